"""How good is a BlockStack skill policy before anyone steers it: valid and distinct unsteered plans.

Steering selects among the modes a policy already samples (ITPS's premise), so
the block-stacking study needs a policy whose *unsteered* batch holds several
executable skills in scenes it has not seen. :func:`probe_policy` measures
that on the evaluation scenes of :func:`~steer_envs.steering.blockstack.tower_trial` (reset seeds
``SCENE_SEED_OFFSET + s``, never training scenes): at each of ``states``
states of a scene (the start, then after each skill of the random planner's
expert) it samples ``samples`` plans and reads each one's skill off the plan
(:func:`~steer_envs.control.blockstack.classify_plan`). Reported:
the share of valid plans (a plan that performs some skill), the distinct
valid skills per state, and how many skills the state allows.

:func:`guide_sweep` asks how strongly GD may push this policy: at the same
states a :class:`~steer_envs.users.block_sketcher.TowerSketchUser` sketches
the skill it wants, and for each guide ratio the batch's share of plans that
do that skill, its share of valid plans and its mean sketch cost are
reported (a ratio that raises the cost overshoots). From the command line
(the shipped policy or a checkpoint)::

    python -m steer_envs.bench.suites.itps_blockstack.probe --checkpoint dp.safetensors --scenes 10
    python -m steer_envs.bench.suites.itps_blockstack.probe --guide 0 5 25 100 --min-guided-t 50
    python -m steer_envs.bench.suites.itps_blockstack.probe --guide 0 5 25 100 --no-clipped-output  # ITPS's step
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from steer_envs.core.validation import integer, real_scalar
from steer_envs.steering.registry import make_sampler
from steer_envs.steering.study import SCENE_SEED_OFFSET

__all__ = ["GuideRow", "ProbeResult", "guide_sweep", "legal_skills", "probe_policy"]


@dataclass(frozen=True)
class ProbeResult:
    """Shares over every probed state: valid plans, distinct valid skills, skills the state allows."""

    states: int
    samples: int
    valid: float
    distinct: float
    legal: float
    picks_valid: float
    places_valid: float

    def summary(self) -> str:
        return (
            f"{self.states} states x {self.samples} plans: valid {100 * self.valid:.1f} % "
            f"(picks {100 * self.picks_valid:.1f} %, places {100 * self.places_valid:.1f} %), "
            f"{self.distinct:.2f} distinct valid skills a state of {self.legal:.2f} allowed"
        )


def legal_skills(env: Any) -> int:
    """How many skills ``env``'s state allows: a pick per tower top, or a place per other top plus the table."""
    supports = env.supports
    covered = {below for below in supports.values() if isinstance(below, int)}
    tops = [c for c in supports if c not in covered and c != env.held_cube]
    return len(tops) if env.held_cube is None else len(tops) + 1


def probe_policy(policy: Any, *, scenes: int = 10, states: int = 4, samples: int = 16, seed: int = 0) -> ProbeResult:
    """Unsteered plans of ``policy`` on ``scenes`` evaluation scenes x ``states`` states (module docstring)."""
    from steer_envs.control.blockstack import classify_plan

    owner = "probe_policy"
    scenes = integer(scenes, "scenes", low=1, high=10_000, owner=owner)
    states = integer(states, "states", low=1, high=100, owner=owner)
    samples = integer(samples, "samples", low=1, high=4096, owner=owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    valid: list[float] = []
    distinct: list[float] = []
    legal: list[float] = []
    picks: list[float] = []
    places: list[float] = []
    for env, obs, s, k in _scene_states(scenes, states):
        plans = np.asarray(policy.sample(obs, samples, generator=np.random.default_rng([seed, s, k])))
        kinds = [classify_plan(env, p) for p in plans]
        ok = [kind for kind in kinds if kind is not None]
        valid.append(len(ok) / samples)
        (picks if env.held_cube is None else places).append(len(ok) / samples)
        distinct.append(len(set(ok)))
        legal.append(legal_skills(env))

    def mean(values: list[float]) -> float:
        return float(np.mean(values)) if values else float("nan")

    return ProbeResult(len(valid), samples, mean(valid), mean(distinct), mean(legal), mean(picks), mean(places))


@dataclass(frozen=True)
class GuideRow:
    """One guide ratio of :func:`guide_sweep`: shares of the batch and its mean sketch cost (m)."""

    guide_ratio: float
    aligned: float
    valid: float
    cost: float

    def summary(self) -> str:
        return (
            f"beta {self.guide_ratio:g}: intended skill {100 * self.aligned:.1f} % of the batch, "
            f"valid {100 * self.valid:.1f} %, sketch cost {self.cost:.3f} m"
        )


def _scene_states(scenes: int, states: int) -> Iterator[tuple[Any, Any, int, int]]:
    """``(env, obs, scene, state)`` at each probed state: evaluation scenes, then the random planner's skills."""
    from steer_envs.data.blockstack_skills import make_env, record_skill
    from steer_envs.data.experts.blockstack import BlockStackSkills, RandomTowerPlanner

    env = make_env()
    try:
        for s in range(scenes):
            scene_seed = SCENE_SEED_OFFSET + s
            obs, info = env.reset(seed=scene_seed)
            planner, skills = RandomTowerPlanner(scene_seed), BlockStackSkills(env)
            for k in range(states):
                yield env, obs, s, k
                _, obs, info = record_skill(env, skills, planner.next_skill(env), obs, info, scene_seed, k)
    finally:
        env.close()


def guide_sweep(
    policy: Any,
    guide_ratios: Sequence[float],
    *,
    scenes: int = 6,
    states: int = 2,
    samples: int = 16,
    min_guided_t: int = 0,
    seed: int = 0,
    use_clipped_model_output: bool = True,
) -> list[GuideRow]:
    """GD at each of ``guide_ratios`` on the user's sketches at the probed states (see the module docstring).

    ``use_clipped_model_output``: GD's DDIM step re-derives the noise from the
    clipped plan estimate (the suite's default; False: ITPS's step).
    """
    from steer_envs.control.blockstack import classify_plan
    from steer_envs.users.block_sketcher import TowerSketchUser

    owner = "guide_sweep"
    scenes = integer(scenes, "scenes", low=1, high=10_000, owner=owner)
    states = integer(states, "states", low=1, high=100, owner=owner)
    samples = integer(samples, "samples", low=1, high=4096, owner=owner)
    min_guided_t = integer(min_guided_t, "min_guided_t", low=0, owner=owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    if isinstance(guide_ratios, (str, bytes)) or not isinstance(guide_ratios, Sequence) or not guide_ratios:
        raise TypeError(f"{owner}: `guide_ratios` must be a non-empty sequence of numbers, got {guide_ratios!r}")
    betas = [real_scalar(b, "guide_ratios", low=0.0, owner=owner) for b in guide_ratios]
    if not isinstance(use_clipped_model_output, bool):
        raise TypeError(f"{owner}: `use_clipped_model_output` must be a bool, got {use_clipped_model_output!r}")
    samplers = [
        make_sampler("GD", guide_ratio=b, min_guided_t=min_guided_t, use_clipped_model_output=use_clipped_model_output)
        for b in betas
    ]
    aligned: list[list[float]] = [[] for _ in betas]
    valid: list[list[float]] = [[] for _ in betas]
    cost: list[list[float]] = [[] for _ in betas]
    for env, obs, s, k in _scene_states(scenes, states):
        order = tuple(int(c) for c in np.random.default_rng([s, 7]).permutation(4))
        user = TowerSketchUser(order, seed=s)
        skill = user.intended_skill(env)
        sketch = user.sketch(env, skill)
        for i, sampler in enumerate(samplers):
            result = sampler(policy, obs, sketch, samples, generator=np.random.default_rng([seed, s, k]))
            kinds = [classify_plan(env, p) for p in result.plans]
            aligned[i].append(float(np.mean([kind == skill.name for kind in kinds])))
            valid[i].append(float(np.mean([kind is not None for kind in kinds])))
            cost[i].append(float(np.mean(result.costs)))
    return [
        GuideRow(b, float(np.mean(a)), float(np.mean(v)), float(np.mean(c)))
        for b, a, v, c in zip(betas, aligned, valid, cost, strict=True)
    ]
