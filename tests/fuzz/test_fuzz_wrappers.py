"""Fuzz pass over the wrappers' boundaries (and the replays, demos, planners and protocols they drive).

Random bad values go to every public argument of the area: each call must end, within
a per-case timeout, either in a documented error (``TypeError``, ``ValueError``,
``KeyError`` for a missing ``info["sensors"]``, ``BoundExceeded``) or in a result; a value
that is no real number (a string, a complex number, NaN/inf, an object) in a numeric
slot must never be accepted. Run with ``pytest -m slow tests/fuzz/test_fuzz_wrappers.py -s``;
it prints the counts.
"""

from __future__ import annotations

import math
import signal
from collections import Counter
from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from stub_policies import StraightLine
from wrapper_bad_values import SAMPLER_KNOBS

import steer_envs  # noqa: F401
from steer_envs.core.interaction import Nudge, Point, Sketch
from steer_envs.core.validation import BoundExceeded

pytestmark = pytest.mark.slow

CASES = 1200
PER_CASE_S = 10.0
DOCUMENTED = (TypeError, ValueError, KeyError, BoundExceeded)


class _Hang(BaseException):
    """Raised by SIGALRM: the case ran past its timeout."""


def _alarm(*_: object) -> None:
    raise _Hang


# ------------------------------------------------------------------------------ bad values
def _bad_value(rng: np.random.Generator, dim: int = 2) -> tuple[Any, bool]:
    """A random value and whether it must be refused in any numeric slot (not a real number at all)."""
    choice = int(rng.integers(24))
    good = rng.uniform(-5, 5, dim)
    table: list[tuple[Any, bool]] = [
        (str(float(good[0])), True),
        ([str(v) for v in good], True),
        (complex(good[0], 1.0), True),
        (good + 1j, True),
        (math.nan, True),
        (math.inf, True),
        (-math.inf, True),
        (np.float32("nan"), True),
        ([*good[:-1], math.nan], True),
        (object(), True),
        (b"\x00\x01", True),
        ({"x": 1}, True),
        ([[1.0, 2.0], [3.0]], True),  # ragged
        (None, False),  # allowed where None means "default"
        (bool(rng.integers(2)), False),
        (int(rng.integers(-(10**12), 10**12)), False),
        (int(rng.integers(-3, 4)), False),
        (float(rng.uniform(-1e9, 1e9)), False),
        (0, False),
        (-1, False),
        (list(good), False),
        (rng.uniform(-5, 5, int(rng.integers(0, 5))), False),  # a wrong length, mostly
        (np.array([list(good), list(good)]), False),  # wrong rank
        ([bool(v > 0) for v in good], False),
    ]
    return table[choice]


# ------------------------------------------------------------------------------- fixtures
def _boundaries() -> dict[str, Callable[[Any, np.random.Generator], Any]]:
    from steer_envs.baselines.glide.planners import LearnedModeMap, PlannerConfig, rrt
    from steer_envs.baselines.lpv_ds.cuts import Cut, CutSet, solve_cut
    from steer_envs.baselines.lpv_ds.modulation import ModulatedPolicy, modulate
    from steer_envs.baselines.lpv_ds.single_mode import rollout, sample_starts
    from steer_envs.data.counterfactual import CounterfactualReplayer
    from steer_envs.data.demos import collect_demonstrations, rollout_expert
    from steer_envs.data.perturbations import PerturbedReference
    from steer_envs.data.pushes import perturbation_schedule
    from steer_envs.steering import PostHocRanking, RandomSampling, make_sampler
    from steer_envs.wrappers import DSModulationWrapper, LTLReplanWrapper, SteeringWrapper

    def convex(**kw: Any) -> gym.Env:
        return gym.make("steer_envs/ConvexMode-v0", layout_seed=0, **kw)

    poly = gym.make("steer_envs/PolygonNav-3Mode-v0", layout_seed=0, terminate_on_violation=False)
    jump = CounterfactualReplayer(poly, "segment", execution="jump")
    tracking = CounterfactualReplayer(poly, "segment")
    steer = SteeringWrapper(convex(), StraightLine(), PostHocRanking(), batch=2)
    steer.reset(seed=0)
    flat = SteeringWrapper(convex(), StraightLine(), PostHocRanking(), batch=2, sketch_points=3)
    flat.reset(seed=0)
    ds = DSModulationWrapper(convex(), attractor=[0.0, 0.0])
    ds.reset(seed=0)
    ltl = LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"))
    ltl.reset(seed=0)
    cuts = CutSet(np.zeros(2), [Cut(np.array([2.0, 0.0]), np.array([1.0, 0.0]))])
    convex_model = convex().unwrapped.model
    demo = np.stack([np.linspace(-5, 5, 20), np.zeros(20)], axis=1)

    class Disc:
        def predict(self, s: np.ndarray) -> np.ndarray:
            return (np.linalg.norm(np.asarray(s), axis=1) < 1).astype(int)

    def waypoints(v: Any, rng: np.random.Generator) -> Any:
        wps = v if rng.random() < 0.5 else [[0.0, 0.0], v]
        return (jump if rng.random() < 0.5 else tracking).replay(
            PerturbedReference(wps, "segment", 0, (0, 1), np.zeros(2))
        )

    def far_waypoint(v: Any, rng: np.random.Generator) -> Any:
        z = rng.uniform(-100, 100, 2)  # mostly outside the [-8, 8]^2 workspace
        return (jump if rng.random() < 0.5 else tracking).replay(
            PerturbedReference(np.array([[0.0, 0.0], z, [1.0, 1.0]]), "segment", 0, (0, 1), z)
        )

    def sensors(v: Any, rng: np.random.Generator) -> Any:
        reading = {"r": False, "s": False, "t": False}
        reading[["r", "s", "t"][int(rng.integers(3))]] = v
        return ltl.sync({"sensors": reading})

    def steer_kwarg(v: Any, rng: np.random.Generator) -> Any:
        name = ["batch", "execute", "sketch_points"][int(rng.integers(3))]
        return SteeringWrapper(convex(), StraightLine(), PostHocRanking(), **{name: v})

    def sampler_kwarg(v: Any, rng: np.random.Generator) -> Any:
        name, cls = list(SAMPLER_KNOBS.items())[int(rng.integers(len(SAMPLER_KNOBS)))]
        return cls(**{name: v})

    def ds_kwarg(v: Any, rng: np.random.Generator) -> Any:
        name = ["attractor", "home_mode", "margin", "learn", "cuts", "plan"][int(rng.integers(6))]
        kwargs: dict[str, Any] = {"attractor": [0.0, 0.0], name: v}
        if name == "attractor" and rng.random() < 0.3:
            kwargs["attractor"] = {int(rng.integers(-2, 4)): v}
        return DSModulationWrapper(convex(), **kwargs)

    def cut_call(v: Any, rng: np.random.Generator) -> Any:
        which = int(rng.integers(6))
        if which == 0:
            return solve_cut(v, [3.1, 0.0], [-3.0, 0.0], [0.0, 0.0])
        if which == 1:
            return Cut(v, np.array([1.0, 0.0]))
        if which == 2:
            return modulate(np.zeros((1, 2)), [v] if rng.random() < 0.5 else v, cuts)
        if which == 3:
            return modulate(np.zeros((1, 2)), np.ones((1, 2)), cuts, max_speed=v)
        if which == 4:
            return ModulatedPolicy(lambda x: -x, cuts, max_speed=v)(np.zeros((1, 2)))
        return CutSet(v)

    def replayer_kwarg(v: Any, rng: np.random.Generator) -> Any:
        name = ["max_steps", "gripper", "kernel_sharpness", "kernel_min_window", "execution", "kind"][
            int(rng.integers(6))
        ]
        return CounterfactualReplayer(poly, **{name: v})

    def rollouts(v: Any, rng: np.random.Generator) -> Any:
        name = ["n", "batch_size"][int(rng.integers(2))]
        kwargs: dict[str, Any] = {"n": 2, "batch_size": 2, name: v}
        if isinstance(v, int) and not isinstance(v, bool) and v > 50:
            kwargs[name] = 50  # a valid size: keep the case short
        return jump.rollouts([demo], kwargs.pop("n"), seed=0, **kwargs)

    def demos(v: Any, rng: np.random.Generator) -> Any:
        name = ["seed", "max_steps", "steps_after_success"][int(rng.integers(3))]
        if isinstance(v, int) and not isinstance(v, bool) and name != "seed":
            v = max(-1, min(v, 50))  # keep valid runs short
        return rollout_expert(convex(), **{"seed": 0, name: v})

    def collect(v: Any, rng: np.random.Generator) -> Any:
        if isinstance(v, int) and not isinstance(v, bool) and v > 2:
            v = 2
        return collect_demonstrations("steer_envs/ConvexMode-v0", v, max_episode_steps=50)

    def planner(v: Any, rng: np.random.Generator) -> Any:
        name = ["grid_resolution", "rrt_iterations", "rrt_step", "k_rep", "clearance", "rrt_goal_bias"][
            int(rng.integers(6))
        ]
        cfg = PlannerConfig(**{name: v})
        if name == "grid_resolution":
            return LearnedModeMap(Disc(), np.full(2, -2.0), np.full(2, 2.0), cfg.grid_resolution)
        return cfg

    def rrt_call(v: Any, rng: np.random.Generator) -> Any:
        name = ["iterations", "step", "goal_bias", "tolerance"][int(rng.integers(4))]
        if isinstance(v, int) and not isinstance(v, bool) and name == "iterations":
            v = max(-1, min(v, 300))
        return rrt(np.zeros(2), np.ones(2), lambda p: True, lambda a, b: False, -np.ones(2), np.ones(2),
                   np.random.default_rng(0), **{name: v})  # fmt: skip

    def tli(v: Any, rng: np.random.Generator) -> Any:
        which = int(rng.integers(3))
        if which == 0:
            return perturbation_schedule(np.random.default_rng(0), 2, 10, v)
        if which == 1:
            n = v if not (isinstance(v, int) and not isinstance(v, bool)) else max(-1, min(v, 30))
            return rollout(lambda x: -x, convex_model, np.zeros((2, 2)) + convex_model.attractor, n_steps=n)
        real = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
        sigma = min(abs(v), 50.0) if real else v  # keep valid runs short
        return sample_starts(convex_model, demo[:3] * 0 + convex_model.attractor, sigma, 3, np.random.default_rng(0))

    return {
        "SteeringWrapper.interaction(plain)": lambda v, rng: steer.interaction(v),
        "SteeringWrapper.interaction(flat)": lambda v, rng: flat.interaction(v if rng.random() < 0.5 else [v] * 6),
        "SteeringWrapper(kwargs)": steer_kwarg,
        "sampler(kwargs)": sampler_kwarg,
        "sampler(n)": lambda v, rng: RandomSampling()(StraightLine(), np.zeros(2), None, v),
        "make_sampler": lambda v, rng: make_sampler(v),
        "DSModulationWrapper(kwargs)": ds_kwarg,
        "DSModulationWrapper.step": lambda v, rng: ds.step(v),
        "cuts": cut_call,
        "LTLReplanWrapper.sync(sensor)": sensors,
        "LTLReplanWrapper.sync(reading)": lambda v, rng: ltl.sync({"sensors": v}),
        "LTLReplanWrapper(spec)": lambda v, rng: LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0"), v),
        "PerturbedReference+replay": waypoints,
        "replay(far waypoint)": far_waypoint,
        "CounterfactualReplayer(kwargs)": replayer_kwarg,
        "CounterfactualReplayer.rollouts": rollouts,
        "rollout_expert": demos,
        "collect_demonstrations(n)": collect,
        "PlannerConfig/LearnedModeMap": planner,
        "rrt": rrt_call,
        "tli protocol": tli,
        "interactions passed as steering actions": lambda v, rng: steer.interaction(
            [Point, Sketch, Nudge][int(rng.integers(3))](v)
        ),
    }


#: boundaries whose argument may legitimately be a string (names), where "a string was accepted" is no coercion
_STRING_SLOTS = {"make_sampler", "LTLReplanWrapper(spec)", "CounterfactualReplayer(kwargs)"}


def test_fuzz_wrappers() -> None:
    rng = np.random.default_rng(20251201)
    boundaries = _boundaries()
    names = sorted(boundaries)
    outcomes: Counter[str] = Counter()
    per_boundary: Counter[str] = Counter()
    problems: list[str] = []
    old = signal.signal(signal.SIGALRM, _alarm)
    try:
        for case in range(CASES):
            name = names[case % len(names)]
            value, must_refuse = _bad_value(rng)
            per_boundary[name] += 1
            signal.setitimer(signal.ITIMER_REAL, PER_CASE_S)
            try:
                boundaries[name](value, rng)
            except _Hang:
                outcomes["hang"] += 1
                problems.append(f"hang: {name}({value!r})")
                continue
            except DOCUMENTED as exc:
                outcomes[type(exc).__name__] += 1
                continue
            except Exception as exc:  # what the fuzz pass counts
                outcomes["traceback"] += 1
                problems.append(f"{type(exc).__name__} from {name}({value!r}): {exc}")
                continue
            finally:
                signal.setitimer(signal.ITIMER_REAL, 0)
            outcomes["accepted"] += 1
            if must_refuse and name not in _STRING_SLOTS:
                outcomes["coerced"] += 1
                problems.append(f"accepted a non-number: {name}({value!r})")
    finally:
        signal.signal(signal.SIGALRM, old)
    print(f"\nfuzz wrappers: {CASES} cases over {len(names)} boundaries; outcomes {dict(sorted(outcomes.items()))}")
    assert not problems, "\n".join(problems[:30])
    assert sum(per_boundary.values()) >= 500
