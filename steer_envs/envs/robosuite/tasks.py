"""The robosuite tasks of steer-envs: Lift, Can, Square, as data (no robosuite import).

One module for the three tasks, not one per task: a task is a small table
(robosuite env name, observation keys, ground-truth modes) read by the one
adapter, :class:`steer_envs.envs.robosuite.adapter.RobosuiteEnv`; the
sim-side predicates (grasp, bin, peg) live in the adapter beside the sim they read.

Ground-truth modes (thesis appendix "Heuristic Rules for Mode Family
Groundtruth in RoboSuite") are labelled from sensor APs, so
``task.mode_of(info["sensors"]) == info["mode_name"]`` always holds:

- ``held``: latched. Set when both finger pads have touched the object
  (robosuite's ``_check_grasp``) for two consecutive control steps
  (``adapter.GRASP_HOLD_STEPS``: a one-step touch of both pads while the
  fingers close on an object on the table is no grasp, and would otherwise
  read as a grasp dropped at once); it stays set while the object is grasped
  *or* still in the air (a momentary slip of the fingers in transport is not a
  new reach); it clears when the object is not grasped and rests again
  (less than 1 cm above its height at reset).
- Lift: ``lifted`` (cube 1 cm above its rest height), ``at_height`` (robosuite's
  success: cube 4 cm above the table). Modes reach -> lift (held, or lifted)
  -> reach_height (at_height).
- Lift, ``variant="public_code"`` (:data:`LIFT_VARIANTS`): the task of the
  public GLiDE robosuite fork. Success needs the cube
  :data:`PUBLIC_CODE_LIFT_HEIGHT` (0.40 m) above the table, ten times
  robosuite's margin; ``falling`` (the cube moves down faster than
  :data:`FALL_SPEED`), ``at_height`` (that success). Modes free -> lifting
  (held and not falling) -> success (at_height), the fork's three.
- Can: ``above_target`` (can xy within ``bin_size / 4`` of its target bin
  placement, per axis). Modes reach -> transport (held) -> hover (above_target,
  held or released into the bin).
- Square: ``above_peg`` (nut-peg xy <= 0.03 m), ``low`` (nut less than
  :data:`SQUARE_LOW_HEIGHT` above its rest height), ``on_peg`` (robosuite's
  success). Modes reach -> transport (held) -> align (held, above_peg, not
  low) -> lower (held, above_peg and low; or on_peg).

Transitions: the forward chain, plus every backward edge that does not go
back to ``reach``. A step whose mode change is not allowed (the object
dropped after being grasped, or a skipped mode) reports
``info["constraint_violation"]``; a change caused by ``perturb`` does not
(a push is not the policy's fault).

>>> TASKS["square"].modes
('reach', 'transport', 'align', 'lower')
>>> sorted(TASK_NAMES)
['can', 'lift', 'square']
>>> task_variant("lift", "public_code").modes
('free', 'lifting', 'success')
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass

from steer_envs.core.task import TaskSpec

__all__ = [
    "FALL_SPEED",
    "LIFT_VARIANTS",
    "PUBLIC_CODE_LIFT_HEIGHT",
    "SQUARE_LOW_HEIGHT",
    "TASKS",
    "TASK_NAMES",
    "VARIANTS",
    "RobosuiteTask",
    "task_spec",
    "task_variant",
]

#: Square: the nut counts as "low" (lowering onto the peg) below this height over its rest height (m).
SQUARE_LOW_HEIGHT = 0.10
#: Lift's variants: the thesis text's task (robosuite's) and the public GLiDE robosuite fork's.
LIFT_VARIANTS: tuple[str, ...] = ("thesis", "public_code")
#: public-code Lift: success once the cube is this high above the table top (m; robosuite's margin is 0.04).
PUBLIC_CODE_LIFT_HEIGHT = 0.40
#: public-code Lift: the cube counts as falling while it moves down faster than this (m/s, 5 mm a control
#: step; the fork compares heights step to step, this leaves out the mm jitter of a cube held still, and
#: a dropped cube reaches 0.49 m/s within one step).
FALL_SPEED = 0.1

Labeller = Callable[[Mapping[str, bool]], str]


@dataclass(frozen=True)
class RobosuiteTask:
    """One robosuite task as the adapter sees it.

    Attributes:
        name: steer-envs task name (``"lift"``...).
        env_name: robosuite environment name (``suite.make``'s first argument).
        object_prefix: prefix of robosuite's object observation keys (``"cube"``, ``"Can"``, ``"SquareNut"``).
        object_keys: robosuite observation keys of the object state, in observation order.
        modes: ordered ground-truth modes.
        sensors: sensor APs (``info["sensors"]`` keys).
        label: sensor reading -> mode name.
        variant: which version of the task (``"thesis"``; Lift also ``"public_code"``).
        success_height: success is the object this high above the table top (m); None: robosuite's own check.
    """

    name: str
    env_name: str
    object_prefix: str
    object_keys: tuple[str, ...]
    modes: tuple[str, ...]
    sensors: tuple[str, ...]
    label: Labeller
    variant: str = "thesis"
    success_height: float | None = None


def _lift(s: Mapping[str, bool]) -> str:
    if s["at_height"]:
        return "reach_height"
    return "lift" if s["held"] or s["lifted"] else "reach"


def _lift_public_code(s: Mapping[str, bool]) -> str:
    if s["at_height"]:
        return "success"
    return "lifting" if s["held"] and not s["falling"] else "free"


def _can(s: Mapping[str, bool]) -> str:
    if s["above_target"] and (s["held"] or s["in_target_bin"]):
        return "hover"
    return "transport" if s["held"] else "reach"


def _square(s: Mapping[str, bool]) -> str:
    if s["on_peg"] or (s["held"] and s["above_peg"] and s["low"]):
        return "lower"
    if s["held"] and s["above_peg"]:
        return "align"
    return "transport" if s["held"] else "reach"


TASKS: Mapping[str, RobosuiteTask] = {
    "lift": RobosuiteTask(
        "lift",
        "Lift",
        "cube",
        ("cube_pos", "cube_quat", "gripper_to_cube_pos"),
        ("reach", "lift", "reach_height"),
        ("held", "lifted", "at_height"),
        _lift,
    ),
    "can": RobosuiteTask(
        "can",
        "PickPlaceCan",
        "Can",
        ("Can_pos", "Can_quat", "Can_to_robot0_eef_pos"),
        ("reach", "transport", "hover"),
        ("held", "above_target", "in_target_bin"),
        _can,
    ),
    "square": RobosuiteTask(
        "square",
        "NutAssemblySquare",
        "SquareNut",
        ("SquareNut_pos", "SquareNut_quat", "SquareNut_to_robot0_eef_pos"),
        ("reach", "transport", "align", "lower"),
        ("held", "above_peg", "low", "on_peg"),
        _square,
    ),
}
TASK_NAMES = tuple(TASKS)
#: every task's variants: task name -> variant name -> task (``"thesis"``: :data:`TASKS`).
VARIANTS: Mapping[str, Mapping[str, RobosuiteTask]] = {
    "lift": {
        "thesis": TASKS["lift"],
        "public_code": RobosuiteTask(
            "lift",
            "Lift",
            "cube",
            TASKS["lift"].object_keys,
            ("free", "lifting", "success"),
            ("held", "falling", "at_height"),
            _lift_public_code,
            variant="public_code",
            success_height=PUBLIC_CODE_LIFT_HEIGHT,
        ),
    },
    "can": {"thesis": TASKS["can"]},
    "square": {"thesis": TASKS["square"]},
}


def task_variant(task: str, variant: str = "thesis") -> RobosuiteTask:
    """The ``variant`` of ``task`` (a ``ValueError`` naming the argument for an unknown one).

    >>> task_variant("lift").success_height is None, task_variant("lift", "public_code").success_height
    (True, 0.4)
    """
    if task not in VARIANTS:
        raise ValueError(f"task_variant: unknown `task` {task!r}; tasks: {list(TASK_NAMES)}")
    if variant not in VARIANTS[task]:
        raise ValueError(f"task_variant: `variant` of {task!r} must be one of {list(VARIANTS[task])}, got {variant!r}")
    return VARIANTS[task][variant]


def task_spec(task: RobosuiteTask) -> TaskSpec:
    """The :class:`TaskSpec` of ``task``: every sensor reading labelled, forward chain + non-reach back edges.

    >>> spec = task_spec(TASKS["lift"])
    >>> spec.mode_of({"held": True, "lifted": False, "at_height": False}), spec.is_allowed("lift", "reach")
    ('lift', False)
    """
    sensor_modes = {}
    for values in itertools.product((False, True), repeat=len(task.sensors)):
        reading = dict(zip(task.sensors, values, strict=True))
        sensor_modes[frozenset(k for k, v in reading.items() if v)] = task.label(reading)
    m = task.modes
    transitions = {(m[i], m[i + 1]) for i in range(len(m) - 1)}
    transitions |= {(m[i + 1], m[i]) for i in range(1, len(m) - 1)}
    suffix = "" if task.variant == "thesis" else f"-{task.variant}"
    return TaskSpec(
        name=f"robosuite-{task.name}{suffix}",
        modes=m,
        sensors=task.sensors,
        sensor_modes=sensor_modes,
        transitions=frozenset(transitions),
    )
