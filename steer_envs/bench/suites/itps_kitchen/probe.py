"""How multimodal is a Kitchen skill policy before anyone steers it: valid and distinct unsteered plans.

Steering can only select among skills the policy samples (ITPS's premise):
the thesis's merged microwave + sink policy samples either task's next skill
from the same state, which is why RS alone reaches TA 0.38 in Table 2.3. A
policy that memorised its 120 training scenes samples one skill per scene
instead, and the study has little to steer. :func:`probe_policy` measures
that on the evaluation scenes of ``itps-kitchen`` (reset seeds
``SCENE_SEED_OFFSET + s``, never training scenes), each reset into one of
:data:`~steer_envs.bench.suites.itps_kitchen.protocol.SWEEP_STARTS` (cycled):
it samples ``samples`` plans per scene and reads each one's skill off the plan
(:func:`~steer_envs.envs.robosuite.kitchen_plan_execution.classify_kitchen_plan`).
Reported: the share of valid plans, the distinct valid skills per scene, the
skills the scene's mode allows, and per mode how often each skill was
sampled. Run as a module::

    python -m steer_envs.bench.suites.itps_kitchen.probe --checkpoint dp.safetensors --scenes 12
"""

from __future__ import annotations

import argparse
import json
from collections import Counter
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from steer_envs.core.validation import integer

__all__ = ["ProbeResult", "main", "probe_policy"]


@dataclass(frozen=True)
class ProbeResult:
    """Shares over every probed scene; per start mode the sampled skills' counts (``None``: no skill) and
    the mean distinct valid skills a scene."""

    scenes: int
    samples: int
    valid: float
    distinct: float
    legal: float
    skills_by_mode: dict[str, dict[str, int]] = field(default_factory=dict)
    distinct_by_mode: dict[str, float] = field(default_factory=dict)

    def summary(self) -> str:
        lines = [
            f"{self.scenes} scenes x {self.samples} plans: valid {100 * self.valid:.1f} %, "
            f"{self.distinct:.2f} distinct valid skills a scene of {self.legal:.2f} allowed"
        ]
        for mode, counts in self.skills_by_mode.items():
            per_scene = ""
            if mode in self.distinct_by_mode:
                per_scene = f" ({self.distinct_by_mode[mode]:.2f} distinct a scene)"
            lines.append(f"  {mode}: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())) + per_scene)
        return "\n".join(lines)


def probe_policy(policy: Any, *, scenes: int = 12, samples: int = 16, seed: int = 0, env: Any = None) -> ProbeResult:
    """Unsteered plans of ``policy`` on ``scenes`` evaluation scenes (see the module docstring).

    ``env``: a Kitchen env to reuse (made by
    :func:`~steer_envs.bench.suites.itps_kitchen.protocol.make_env`); None builds one and closes it.
    """
    from steer_envs.bench.suites.itps_kitchen.protocol import SCENE_SEED_OFFSET, SWEEP_STARTS, make_env
    from steer_envs.envs.robosuite.kitchen import legal_skills
    from steer_envs.envs.robosuite.kitchen_plan_execution import classify_kitchen_plan

    owner = "probe_policy"
    scenes = integer(scenes, "scenes", low=1, high=10_000, owner=owner)
    samples = integer(samples, "samples", low=1, high=4096, owner=owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    own_env = env is None
    env = make_env("microwave") if own_env else env
    base = env.unwrapped
    valid: list[float] = []
    distinct: list[float] = []
    legal: list[float] = []
    by_mode: dict[str, Counter[str]] = {}
    distinct_in: dict[str, list[int]] = {}
    try:
        for s in range(scenes):
            obs, _ = base.reset(seed=SCENE_SEED_OFFSET + s, options=dict(SWEEP_STARTS[s % len(SWEEP_STARTS)]))
            mode = str(base.task.modes[base._mode])
            plans = np.asarray(policy.sample(obs, samples, generator=np.random.default_rng([seed, s])))
            kinds = [classify_kitchen_plan(base, p) for p in plans]
            ok = [kind for kind in kinds if kind is not None]
            valid.append(len(ok) / samples)
            distinct.append(len(set(ok)))
            distinct_in.setdefault(mode, []).append(len(set(ok)))
            legal.append(len(legal_skills(mode)))
            by_mode.setdefault(mode, Counter()).update(str(kind) for kind in kinds)
    finally:
        if own_env:
            env.close()
    counts = {mode: dict(c) for mode, c in by_mode.items()}
    per_mode = {mode: float(np.mean(n)) for mode, n in distinct_in.items()}
    return ProbeResult(
        len(valid), samples, float(np.mean(valid)), float(np.mean(distinct)), float(np.mean(legal)), counts, per_mode
    )


def main(argv: list[str] | None = None) -> int:
    """CLI: probe a checkpoint (or the shipped policy); exit 2 on a usage error."""
    from steer_envs.utils.threads import add_threads_argument, set_process_threads

    parser = argparse.ArgumentParser(
        prog="python -m steer_envs.bench.suites.itps_kitchen.probe",
        description="Valid and distinct unsteered plans of a Kitchen skill policy on held-out scenes.",
    )
    parser.add_argument("--checkpoint", default="", help="a .safetensors checkpoint (default: the shipped one)")
    parser.add_argument("--scenes", type=int, default=12, help="evaluation scenes, cycling 3 start states (default 12)")
    parser.add_argument("--samples", type=int, default=16, help="plans sampled per scene (default 16)")
    parser.add_argument("--seed", type=int, default=0, help="the sampling seed (default 0)")
    add_threads_argument(parser)
    parser.add_argument("--json", default="", help="also write the result as JSON to this file")
    args = parser.parse_args(argv)
    set_process_threads(args.threads)
    from steer_envs.baselines.pretrained import load_kitchen

    try:
        policy = load_kitchen(checkpoint=args.checkpoint or None)
        result = probe_policy(policy, scenes=args.scenes, samples=args.samples, seed=args.seed)
    except (TypeError, ValueError, FileNotFoundError) as err:
        parser.error(str(err))
    print(result.summary())
    if args.json:
        from steer_envs.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(asdict(result), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
