"""How multimodal is a Kitchen skill policy before anyone steers it: valid and distinct unsteered plans.

Steering can only select among skills the policy samples (ITPS's premise):
the thesis's merged microwave + sink policy samples either task's next skill
from the same state, which is why RS alone reaches TA 0.38 in Table 2.3. A
policy that memorised its 120 training scenes samples one skill per scene
instead, and the study has little to steer. :func:`probe_policy` measures
that on the evaluation scenes of ``itps-kitchen`` (reset seeds
``SCENE_SEED_OFFSET + s``, never training scenes), each reset into one of
:data:`~steer_envs.steering.kitchen.SWEEP_STARTS` (cycled):
it samples ``samples`` plans per scene and reads each one's skill off the plan
(:func:`~steer_envs.control.kitchen.classify_kitchen_plan`).
Reported: the share of valid plans, the distinct valid skills per scene, the
skills the scene's mode allows, and per mode how often each skill was
sampled. From the command line (the shipped policy or a checkpoint)::

    python -m steer_envs.bench.suites.itps_kitchen.probe --checkpoint dp.safetensors --scenes 12
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from steer_envs.core.validation import integer
from steer_envs.steering.study import SCENE_SEED_OFFSET

__all__ = ["ProbeResult", "probe_policy"]


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
    :func:`~steer_envs.steering.kitchen.make_env`); None builds one and closes it.
    """
    from steer_envs.control.kitchen import classify_kitchen_plan
    from steer_envs.envs.robosuite.kitchen import legal_skills
    from steer_envs.steering.kitchen import SWEEP_STARTS, make_env

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
