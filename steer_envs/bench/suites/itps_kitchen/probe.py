"""The Kitchen skill-policy probe from the command line (:mod:`steer_envs.steering.kitchen_probe`).

python -m steer_envs.bench.suites.itps_kitchen.probe --checkpoint dp.safetensors --scenes 12
"""

from __future__ import annotations

import argparse
from dataclasses import asdict
from typing import Any

from steer_envs.bench.policies import run_probe

__all__ = ["main"]


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenes", type=int, default=12, help="evaluation scenes, cycling 3 start states (default 12)")
    parser.add_argument("--samples", type=int, default=16, help="plans sampled per scene (default 16)")
    parser.add_argument("--seed", type=int, default=0, help="the sampling seed (default 0)")


def _probe(policy: Any, args: argparse.Namespace) -> dict[str, Any]:
    from steer_envs.steering.kitchen_probe import probe_policy

    result = probe_policy(policy, scenes=args.scenes, samples=args.samples, seed=args.seed)
    print(result.summary())
    return asdict(result)


def main(argv: list[str] | None = None) -> int:
    """CLI: probe a checkpoint (or the shipped policy); exit 2 on a usage error."""
    return run_probe(
        argv,
        "kitchen",
        _options,
        _probe,
        prog="python -m steer_envs.bench.suites.itps_kitchen.probe",
        description="Valid and distinct unsteered plans of a Kitchen skill policy on held-out scenes.",
        errors=(TypeError, ValueError, FileNotFoundError),
    )


if __name__ == "__main__":
    raise SystemExit(main())
