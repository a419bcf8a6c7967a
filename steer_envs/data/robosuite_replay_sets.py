"""GLiDE's replay data on the robosuite arms: demos with their perturbed replays, as one list per task.

:func:`demo_with_replays` records the scripted expert's demo from one reset
seed and, if it succeeds, its perturbed replays
(:func:`~steer_envs.data.robosuite_replays.replay`, perturbations drawn from
``default_rng([index, 7])`` by
:func:`~steer_envs.data.robosuite_replays.sample_perturbation`) with an
early-terminated copy of every successful one; with ``extra_gripper`` (the
public GLiDE robosuite code's "extra gripper perturbation", off by default)
also a replay of every successful replay with the gripper forced open (drawn
from its own stream, ``default_rng([index, 11])``, so the others do not
change). :func:`replay_set` does so for demos ``0 .. n - 1``;
:func:`split_demos` separates the successful demos (what BC and the scores
use) from the replays (what the mode classifier learns from besides them).

>>> split_demos([])
([], [])
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from steer_envs.core.validation import integer
from steer_envs.data import robosuite_replays as rr

__all__ = ["demo_with_replays", "replay_set", "split_demos"]


def demo_with_replays(
    env: rr.RobosuiteEnv,
    index: int,
    replays: int,
    *,
    truncated_copies: bool = True,
    success_hold: int = rr.SUCCESS_HOLD_STEPS,
    extra_gripper: bool = False,
    demos: str = "scripted",
) -> list[rr.ArmTrajectory]:
    """The demo from reset seed ``index`` and (when it succeeds) ``replays`` perturbed replays of it.

    ``demos``: who demonstrates (:data:`~steer_envs.data.robosuite_replays.DEMO_SOURCES`).
    Each successful replay is followed by its early-terminated copy (``truncated_copies``) and,
    with ``extra_gripper``, by a replay of it with the gripper forced open (see the module).
    """
    demo = rr.record_demo(env, index, success_hold=success_hold, demos=demos)
    out = [demo]
    if not (integer(replays, "replays", low=0, owner="demo_with_replays") > 0 and demo.success):
        return out
    rng = np.random.default_rng([index, 7])
    extra_rng = np.random.default_rng([index, 11])  # its own stream: the other replays stay as they were
    for _ in range(replays):
        r = rr.replay(env, demo, rr.sample_perturbation(demo, rng), source=index, success_hold=success_hold)
        out.append(r)
        if truncated_copies and r.success:
            out.append(rr.early_terminated(r, rng))
        if extra_gripper and r.success:
            g = rr.sample_perturbation(r, extra_rng, kernel_fraction=0.0)
            out.append(rr.replay(env, r, g, source=index, success_hold=success_hold))
    return out


def replay_set(
    task: str,
    n_demos: int,
    *,
    replay_demos: int | None = None,
    replays_per_demo: int = 10,
    success_hold: int = rr.SUCCESS_HOLD_STEPS,
    extra_gripper: bool = False,
) -> list[rr.ArmTrajectory]:
    """Demos ``0 .. n_demos - 1`` of ``task`` in order, the first ``replay_demos`` (default: all) with replays.

    One env for all (the simulation takes a few seconds per demo and per replay);
    :func:`~steer_envs.data.robosuite_replays.save_trajectories` writes the result to one file.
    """
    n_demos = integer(n_demos, "n_demos", low=1, owner="replay_set")
    with_replays = n_demos if replay_demos is None else integer(replay_demos, "replay_demos", low=0)
    env = rr.make_arm_env(task)
    try:
        out: list[rr.ArmTrajectory] = []
        for i in range(n_demos):
            replays = replays_per_demo if i < with_replays else 0
            out += demo_with_replays(env, i, replays, success_hold=success_hold, extra_gripper=extra_gripper)
        return out
    finally:
        env.close()


def split_demos(trajectories: Sequence[rr.ArmTrajectory]) -> tuple[list[rr.ArmTrajectory], list[rr.ArmTrajectory]]:
    """(the successful demos, the replays incl. their truncated copies) among ``trajectories``."""
    demos = [t for t in trajectories if t.perturbation.kind == "demo" and t.source < 0 and t.success]
    replays = [t for t in trajectories if t.source >= 0]
    return demos, replays
