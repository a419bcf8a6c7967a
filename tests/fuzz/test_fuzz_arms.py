"""Property-based runs of the six arm envs: random actions, pushes in and out of the workspace, resets.

Each run is a sequence of operations on one env (made once for the module):
``step`` (a random action, up to 1.5x the action box: the env clips it, held
for 1 to 15 steps), ``push`` (``perturb(delta=...)`` of a random direction and
size, from a few cm to 1e300), ``push_to`` (``perturb(to=...)`` at a random
point of the workspace's bounding box) and ``reset``. After each one:

- the observation is finite and inside the observation box (no NaN);
- no silent reset: the sim time advanced by one control period per step
  (a push: by whole control periods, at most the push's OSC steps), free
  bodies moved less than :data:`MAX_JUMP` per operation, unless ``reset``
  was called;
- the mode is the task's mode of the sensors (``task.mode_of``), its index
  matches, and the sensors agree with the state the env exposes (success,
  the held cube, the bowl's place, the beads...);
- a push inside ``perturb_workspace`` lands on its target (1e-6 m) with the
  joints within their limits and reports no violation; one outside raises a
  ``ValueError`` naming its argument and moves nothing (ArmScoop clips to its
  box instead: the state is the clipped target, or the pose is refused as one
  its joints cannot take).

The default run is short (Hypothesis, derandomized); ``pytest -m slow
tests/fuzz/test_fuzz_arms.py -s`` runs >= 5,000 steps with pushes per env and
prints the counts.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterator
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st
from robosuite_helpers import ROBOSUITE_MARKS, lazy_arms

import steer_envs  # noqa: F401  (registers the ids)
from steer_envs.envs.robosuite.adapter import PERTURB_MAX_STEPS
from steer_envs.envs.robosuite.arm_scoop import PUSH_STEPS
from steer_envs.envs.robosuite.kitchen import DOOR_OPEN_ANGLE

pytestmark = ROBOSUITE_MARKS

ARMS = ("Lift", "Can", "Square", "BlockStack", "Kitchen", "ArmScoop")
CONTROL_DT = 0.05
#: a free body (cube, can, nut, bowl) moving more than this (m) in one operation is a jump, not physics
MAX_JUMP = 0.5
#: push sizes: a push's delta is a random direction in [-1, 1]^3 times one of these
SCALES = (0.02, 0.08, 0.3, 1.5, 1e3, 1e300)
OPS = ("step",) * 12 + ("push",) * 3 + ("push_to",) * 2 + ("reset",)


@pytest.fixture(scope="module")
def arms() -> Iterator[dict[str, gym.Env[Any, Any]]]:
    yield from lazy_arms()


# ---------------------------------------------------------------------- operations
unit = st.floats(-1.0, 1.0, allow_nan=False)
fraction = st.floats(0.0, 1.0, allow_nan=False)
op = st.one_of(
    st.tuples(
        st.just("step"),
        st.tuples(st.lists(st.floats(-1.5, 1.5, allow_nan=False), min_size=7, max_size=7), st.integers(1, 15)),
    ),
    st.tuples(st.just("push"), st.tuples(st.tuples(unit, unit, unit), st.sampled_from(SCALES))),
    st.tuples(st.just("push_to"), st.tuples(fraction, fraction, fraction)),
    st.tuples(st.just("reset"), st.integers(0, 10_000)),
)


def random_op(rng: np.random.Generator) -> tuple[str, Any]:
    """One operation drawn from ``rng`` (the slow run's generator; the same kinds as the Hypothesis strategy)."""
    kind = str(rng.choice(OPS))
    if kind == "step":
        return kind, (list(rng.uniform(-1.5, 1.5, 7)), int(rng.integers(1, 16)))
    if kind == "push":
        scale = SCALES[int(rng.choice(len(SCALES), p=[0.35, 0.35, 0.15, 0.05, 0.05, 0.05]))]
        return kind, (tuple(rng.uniform(-1.0, 1.0, 3)), scale)
    if kind == "push_to":
        return kind, tuple(rng.uniform(0.0, 1.0, 3))
    return kind, int(rng.integers(0, 10_000))


# ---------------------------------------------------------------------- checks
def free_bodies(base: Any) -> np.ndarray:
    """Positions of every free body (the task's objects), from the sim."""
    model, data = base.rs_env.sim.model._model, base.rs_env.sim.data._data
    adr = [model.jnt_qposadr[j] for j in range(model.njnt) if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    return np.array([data.qpos[a : a + 3] for a in adr]).reshape(-1, 3)


def joints_within_limits(base: Any) -> bool:
    model = base.rs_env.sim.model._model
    low, high = model.jnt_range[base._robot._ref_joint_indexes].T
    q = base.rs_env.sim.data.qpos[base._arm_qpos]
    return bool(np.all((q >= low - 1e-9) & (q <= high + 1e-9)))


def sensors_match_state(name: str, base: Any, info: dict[str, Any]) -> bool:
    """The sensors agree with what the env exposes of its state."""
    s = info["sensors"]
    rs = base.rs_env
    if name == "Lift":
        return s["at_height"] == info["success"] == bool(rs._check_success())
    if name == "Square":
        return s["on_peg"] == info["success"] == bool(rs._check_success())
    if name == "Can":
        return s["in_target_bin"] == (not bool(rs.not_in_bin(base.object_pos, rs.object_to_id["can"])))
    if name == "BlockStack":
        held = base.held_cube
        return all(s[f"held_{i}"] == (held == i) for i in range(4)) and info["success"] == (
            bool(rs._check_success()) and held is None
        )
    if name == "Kitchen":
        place = base.place
        return (
            s["door_open"] == (base.door_angle > DOOR_OPEN_ANGLE)
            and s["held"] == (place == "held")
            and s["in_sink"] == (place == "sink")
            and s["in_microwave"] == (place == "microwave")
            and s["on_table"] == (place == "table")
        )
    return (
        s["s"] == base.beads_on_spoon
        and s["t"] == info["success"]
        and s["r"] == (base._in_soup() and not base.beads_on_spoon)
    )


class Run:
    """One env's operations with the invariants checked; problems are counted (and failed on by the callers)."""

    def __init__(self, name: str, env: gym.Env[Any, Any]) -> None:
        self.name, self.env, self.base = name, env, env.unwrapped
        self.counts: Counter[str] = Counter()
        self.problems: list[str] = []
        self.scoop = name == "ArmScoop"
        self.push_steps = PUSH_STEPS if self.scoop else PERTURB_MAX_STEPS
        self.reset(0)

    def fail(self, what: str, detail: str) -> None:
        self.counts[what] += 1
        if len(self.problems) < 20:
            self.problems.append(f"{self.name}: {what}: {detail}")

    # ------------------------------------------------------------------ operations
    def reset(self, seed: int) -> None:
        obs, info = self.env.reset(seed=seed)
        self.counts["resets"] += 1
        self.after(obs, info, "reset", pushed=False)

    def apply(self, kind: str, arg: Any) -> None:
        t0, bodies = float(self.base.rs_env.sim.data.time), free_bodies(self.base)
        if kind == "reset":
            self.reset(int(arg))
            return
        if kind == "step":
            high = self.env.action_space.high
            values, repeat = arg
            action = (np.asarray(values[: high.size]) * high).astype(np.float32)
            for _ in range(repeat):
                obs, _, terminated, truncated, info = self.env.step(action)
                self.counts["steps"] += 1
                self.continuous(t0, bodies, 1, 1, "step")
                self.after(obs, info, "step", pushed=False)
                if terminated or truncated:
                    self.reset(int(self.counts["steps"]))
                    return
                t0, bodies = float(self.base.rs_env.sim.data.time), free_bodies(self.base)
            return
        ws = self.base.perturb_workspace
        if kind == "push":
            direction, scale = arg
            delta = np.asarray(direction, dtype=np.float64) * scale
            target, name, call = self.base.state + delta, "delta", {"delta": delta}
        else:
            target = ws.low + np.asarray(arg) * (ws.high - ws.low)
            name, call = "to", {"to": target}
        self.push(target, name, call, t0, bodies)

    def push(self, target: np.ndarray, name: str, call: dict[str, Any], t0: float, bodies: np.ndarray) -> None:
        base, ws = self.base, self.base.perturb_workspace
        inside = ws.contains(target)
        before = base.state
        try:
            info = base.perturb(**call)
        except ValueError as error:
            message = str(error)
            self.counts["refusals"] += 1
            if f"`{name}`" not in message:
                self.fail("refusal without the argument", message)
            if self.scoop:
                if "cannot take within its joint limits" not in message:
                    self.fail("ArmScoop refused a push it should clip", message)
            elif inside:
                self.fail("in-range push refused", message)
            if not np.array_equal(base.state, before) or float(base.rs_env.sim.data.time) != t0:
                self.fail("a refused push moved the arm", message)
            return
        self.counts["pushes"] += 1
        self.counts["clipped"] += int(self.scoop and not inside)
        expected = ws.clip(target) if self.scoop else target
        if not self.scoop and not inside:
            self.fail("out-of-range push accepted", f"{name}={np.round(target, 4).tolist()}")
        elif not np.allclose(base.state, expected, atol=1e-6):
            self.fail("push missed its target", f"{expected.tolist()} -> {base.state.tolist()}")
        if not joints_within_limits(base):
            self.fail("joints past their limits", str(base.rs_env.sim.data.qpos[base._arm_qpos].tolist()))
        if not info["perturbed"] or info["constraint_violation"]:
            self.fail("push info", f"perturbed={info['perturbed']} violation={info['constraint_violation']}")
        self.continuous(t0, bodies, 0, self.push_steps, "push")
        self.after(base._obs(), info, "push", pushed=True)

    # ------------------------------------------------------------------ invariants
    def continuous(self, t0: float, bodies: np.ndarray, low: int, high: int, where: str) -> None:
        periods = (float(self.base.rs_env.sim.data.time) - t0) / CONTROL_DT
        if not (low - 1e-6 <= periods <= high + 1e-6 and abs(periods - round(periods)) < 1e-6):
            self.fail("silent reset", f"{where}: sim time {t0:.3f} -> {self.base.rs_env.sim.data.time:.3f}")
        near = np.linalg.norm(bodies[:, :2], axis=1) < 2.0  # Can parks its other objects 10 m away, falling
        jump = float(np.max(np.linalg.norm(free_bodies(self.base)[near] - bodies[near], axis=1), initial=0.0))
        if jump > MAX_JUMP:
            self.fail("silent reset", f"{where}: a free body jumped {jump:.3f} m")

    def after(self, obs: np.ndarray, info: dict[str, Any], where: str, *, pushed: bool) -> None:
        if not np.all(np.isfinite(obs)):
            self.fail("NaN", f"{where}: {obs.tolist()}")
        elif not self.env.observation_space.contains(np.asarray(obs, dtype=np.float32)):
            self.fail("observation outside its box", f"{where}: {obs.tolist()}")
        task = self.base.task
        name = task.mode_of(info["sensors"])
        if name != info["mode_name"] or task.mode_index(name) != info["mode"]:
            self.fail("mode", f"{where}: sensors {info['sensors']} -> {name}, info {info['mode_name']}")
        if not sensors_match_state(self.name, self.base, info):
            self.fail("sensors", f"{where}: {info['sensors']}")


def run_ops(name: str, env: gym.Env[Any, Any], ops: list[tuple[str, Any]]) -> Run:
    run = Run(name, env)
    for kind, arg in ops:
        run.apply(kind, arg)
    return run


# ---------------------------------------------------------------------- default: short
@pytest.mark.parametrize("name", ARMS)
def test_random_steps_pushes_and_resets_keep_the_arm_envs_sound(arms: dict[str, gym.Env[Any, Any]], name: str) -> None:
    env = arms[name]
    done: Counter[str] = Counter()

    @settings(
        max_examples=4,
        derandomize=True,
        deadline=None,
        database=None,
        phases=[Phase.explicit, Phase.generate],  # no shrinking: each example costs seconds of simulation
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(st.lists(op, min_size=12, max_size=24))
    def check(ops: list[tuple[str, Any]]) -> None:
        run = run_ops(name, env, ops)
        done.update(run.counts)
        assert not run.problems, run.problems

    check()
    print(f"\n{name}: {dict(done)}")
    out_of_range = done["clipped"] if name == "ArmScoop" else done["refusals"]  # ArmScoop clips to its box
    assert done["steps"] > 0 and done["pushes"] > 0 and out_of_range > 0, dict(done)


# ---------------------------------------------------------------------- slow: long
@pytest.mark.slow
@pytest.mark.parametrize("name", ARMS)
def test_five_thousand_steps_with_pushes_per_arm(arms: dict[str, gym.Env[Any, Any]], name: str) -> None:
    env = arms[name]
    rng = np.random.default_rng([48, ARMS.index(name)])
    run = Run(name, env)
    start = time.perf_counter()
    while run.counts["steps"] < 5000:
        run.apply(*random_op(rng))
    seconds = time.perf_counter() - start
    keys = ("steps", "pushes", "refusals", "resets", "NaN", "silent reset")
    print(f"\n{name}: " + ", ".join(f"{k} {run.counts[k]}" for k in keys) + f", {seconds:.0f} s")
    assert not run.problems, (dict(run.counts), run.problems)
