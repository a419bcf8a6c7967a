"""Thesis Fig. 2.10 from the command line: the share of a batch doing the intended skill against the guide ratio.

    python -m steer_envs.bench.suites.itps_kitchen.sweep --ratios 1,5,20,100,300 --seeds 3 --out runs/kitchen-sweep

Runs :func:`~steer_envs.steering.kitchen.guide_ratio_sweep`
(GD and SS, the same beta at every DDIM step) with the Kitchen policy
(``--checkpoint`` or the shipped one) and writes ``sweep.json`` and
``sweep.png`` (:func:`~steer_envs.bench.suites.itps_kitchen.plots.plot_sweep`)
under ``--out``. Exit 2 on a usage error or a missing policy.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from steer_envs.io import atomic_write_text

__all__ = ["main", "parse_args"]


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (argparse exits 2 on a usage error)."""
    from steer_envs.baselines.diffusion.acceleration import ACCELERATIONS
    from steer_envs.steering.kitchen import SWEEP_STARTS

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", default="1,5,20,100,300", help="comma-separated guide ratios >= 0")
    parser.add_argument("--seeds", type=int, default=3, help="scenes (default 3)")
    parser.add_argument(
        "--starts",
        default="0,1,2",
        help="start states to cycle, indices into SWEEP_STARTS (0: the task's start; 1, 2: reset into an open door)",
    )
    parser.add_argument("--batch", type=int, default=16, help="plans per sampling call (default 16)")
    parser.add_argument("--checkpoint", default="", help="a Kitchen DP checkpoint (default: the shipped one)")
    parser.add_argument(
        "--accelerate",
        choices=ACCELERATIONS,
        default="auto",
        help="the denoiser's inference mode (default auto: ONNX Runtime where installed, else trace)",
    )
    parser.add_argument("--out", type=Path, default=Path("runs/kitchen-sweep"), help="output directory")
    args = parser.parse_args(argv)
    try:
        args.ratios = [float(r) for r in args.ratios.split(",")]
    except ValueError:
        parser.error(f"--ratios must be comma-separated numbers, got {args.ratios!r}")
    try:
        args.starts = [int(i) for i in args.starts.split(",")]
    except ValueError:
        parser.error(f"--starts must be comma-separated integers, got {args.starts!r}")
    last = len(SWEEP_STARTS) - 1
    if any(not 0 <= i <= last for i in args.starts):
        parser.error(f"--starts must be indices in [0, {last}], got {args.starts}")
    if any(not r >= 0 for r in args.ratios):
        parser.error(f"--ratios must be >= 0, got {args.ratios}")
    for name in ("seeds", "batch"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be >= 1, got {getattr(args, name)}")
    return args


def main(argv: list[str] | None = None) -> int:
    """Run the sweep and write its JSON and figure; 0 on success, 2 without a policy."""
    args = parse_args(argv)
    from steer_envs.baselines.pretrained import POLICY_UNAVAILABLE, shared_policy
    from steer_envs.bench.suites.itps_kitchen.plots import plot_sweep
    from steer_envs.steering.kitchen import guide_ratio_sweep

    try:
        policy = shared_policy("kitchen", args.checkpoint, args.accelerate, owner="--accelerate")
    except (ValueError, *POLICY_UNAVAILABLE) as exc:
        print(f"the Kitchen policy is not available ({type(exc).__name__}: {exc})", file=sys.stderr)
        return 2
    result = guide_ratio_sweep(policy, args.ratios, seeds=args.seeds, batch=args.batch, starts=args.starts)
    args.out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(args.out / "sweep.json", json.dumps(result, indent=1))
    path = plot_sweep(result, args.out / "sweep.png")
    for method, shares in result["share"].items():
        print(method, " ".join(f"beta {r:g}: {s:.2f}" for r, s in zip(result["ratios"], shares, strict=True)))
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
