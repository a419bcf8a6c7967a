"""How good is a BlockStack skill policy before anyone steers it: valid and distinct unsteered plans.

Steering selects among the modes a policy already samples (ITPS's premise), so
the block-stacking study needs a policy whose *unsteered* batch holds several
executable skills in scenes it has not seen. :func:`probe_policy` measures
that on the evaluation scenes of ``itps-blockstack`` (reset seeds
``SCENE_SEED_OFFSET + s``, never training scenes): at each of ``states``
states of a scene (the start, then after each skill of the random planner's
expert) it samples ``samples`` plans and reads each one's skill off the plan
(:func:`~steer_envs.envs.robosuite.plan_execution.classify_plan`). Reported:
the share of valid plans (a plan that performs some skill), the distinct
valid skills per state, and how many skills the state allows. Run as a
module::

    python -m steer_envs.bench.suites.itps_blockstack.probe --checkpoint dp.safetensors --scenes 10
"""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from steer_envs.core.validation import integer

__all__ = ["ProbeResult", "legal_skills", "probe_policy"]


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
    from steer_envs.bench.suites.itps_blockstack.protocol import SCENE_SEED_OFFSET
    from steer_envs.data.blockstack_skills import _run_skill, make_env
    from steer_envs.data.experts.blockstack import BlockStackSkills, RandomTowerPlanner
    from steer_envs.envs.robosuite.plan_execution import classify_plan

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
    env = make_env()
    try:
        for s in range(scenes):
            scene_seed = SCENE_SEED_OFFSET + s
            obs, info = env.reset(seed=scene_seed)
            planner, skills = RandomTowerPlanner(scene_seed), BlockStackSkills(env)
            for k in range(states):
                plans = np.asarray(policy.sample(obs, samples, generator=np.random.default_rng([seed, s, k])))
                kinds = [classify_plan(env, p) for p in plans]
                ok = [kind for kind in kinds if kind is not None]
                valid.append(len(ok) / samples)
                (picks if env.held_cube is None else places).append(len(ok) / samples)
                distinct.append(len(set(ok)))
                legal.append(legal_skills(env))
                _, obs, info = _run_skill(env, skills, planner.next_skill(env), obs, info, scene_seed, k)
    finally:
        env.close()

    def mean(values: list[float]) -> float:
        return float(np.mean(values)) if values else float("nan")

    return ProbeResult(len(valid), samples, mean(valid), mean(distinct), mean(legal), mean(picks), mean(places))


def main(argv: list[str] | None = None) -> int:
    """CLI: probe a checkpoint (or the shipped policy); exit 2 on a usage error."""
    from steer_envs.utils.threads import add_threads_argument, set_process_threads

    parser = argparse.ArgumentParser(
        prog="python -m steer_envs.bench.suites.itps_blockstack.probe",
        description="Valid and distinct unsteered plans of a BlockStack skill policy on held-out scenes.",
    )
    parser.add_argument("--checkpoint", default="", help="a .safetensors checkpoint (default: the shipped one)")
    parser.add_argument("--scenes", type=int, default=10, help="evaluation scenes (default 10)")
    parser.add_argument("--states", type=int, default=4, help="states a scene: start + after each skill (default 4)")
    parser.add_argument("--samples", type=int, default=16, help="plans sampled at each state (default 16)")
    parser.add_argument("--seed", type=int, default=0, help="the sampling seed (default 0)")
    add_threads_argument(parser)
    parser.add_argument("--json", default="", help="also write the result as JSON to this file")
    args = parser.parse_args(argv)
    set_process_threads(args.threads)
    from steer_envs.baselines.pretrained import load_blockstack

    try:
        policy = load_blockstack(checkpoint=args.checkpoint or None)
        result = probe_policy(policy, scenes=args.scenes, states=args.states, samples=args.samples, seed=args.seed)
    except (TypeError, ValueError) as err:
        parser.error(str(err))
    print(result.summary())
    if args.json:
        from steer_envs.io import atomic_write_text

        atomic_write_text(args.json, json.dumps(asdict(result), indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
