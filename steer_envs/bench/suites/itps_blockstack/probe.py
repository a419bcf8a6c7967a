"""The BlockStack skill-policy probe from the command line (:mod:`steer_envs.steering.blockstack_probe`).

python -m steer_envs.bench.suites.itps_blockstack.probe --checkpoint dp.safetensors --scenes 10
python -m steer_envs.bench.suites.itps_blockstack.probe --guide 0 5 25 100 --min-guided-t 50
python -m steer_envs.bench.suites.itps_blockstack.probe --guide 0 5 25 100 --no-clipped-output  # ITPS's step
"""

from __future__ import annotations

import argparse
from dataclasses import asdict
from typing import Any

from steer_envs.bench.policies import run_probe

__all__ = ["main"]


def _options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--scenes", type=int, default=10, help="evaluation scenes (default 10)")
    parser.add_argument("--states", type=int, default=4, help="states a scene: start + after each skill (default 4)")
    parser.add_argument("--samples", type=int, default=16, help="plans sampled at each state (default 16)")
    parser.add_argument("--seed", type=int, default=0, help="the sampling seed (default 0)")
    parser.add_argument(
        "--guide",
        type=float,
        nargs="+",
        metavar="BETA",
        help="instead: GD's sweep over these guide ratios on the user's sketches (see guide_sweep)",
    )
    parser.add_argument("--min-guided-t", type=int, default=0, help="GD's guidance stops at this step (default 0)")
    parser.add_argument(
        "--clipped-output",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="GD's DDIM step re-derives the noise from the clipped plan estimate (default on; off: ITPS's step)",
    )


def _probe(policy: Any, args: argparse.Namespace) -> Any:
    from steer_envs.steering.blockstack_probe import guide_sweep, probe_policy

    sizes = {"scenes": args.scenes, "states": args.states, "samples": args.samples, "seed": args.seed}
    if args.guide:
        kwargs = {"min_guided_t": args.min_guided_t, "use_clipped_model_output": args.clipped_output}
        rows = guide_sweep(policy, args.guide, **kwargs, **sizes)
        print("\n".join(r.summary() for r in rows))
        return [asdict(r) for r in rows]
    result = probe_policy(policy, **sizes)
    print(result.summary())
    return asdict(result)


def main(argv: list[str] | None = None) -> int:
    """CLI: probe a checkpoint (or the shipped policy); exit 2 on a usage error."""
    return run_probe(
        argv,
        "blockstack",
        _options,
        _probe,
        prog="python -m steer_envs.bench.suites.itps_blockstack.probe",
        description="Valid and distinct unsteered plans of a BlockStack skill policy on held-out scenes.",
    )


if __name__ == "__main__":
    raise SystemExit(main())
