"""What the page shows beside Kitchen's camera: the task's modes, the skills legal now, what the chosen plan does."""

from __future__ import annotations

from typing import Any

__all__ = ["kitchen_rows"]


def kitchen_rows(base: Any, plan: Any = None) -> list[tuple[str, str]]:
    """``(label, value)`` rows for a KitchenEnv ``base``: task, mode, legal skills, the plan to the goal.

    With ``plan`` (a chosen skill plan), also the skill it would perform, read off the plan
    (:func:`~steer_envs.control.kitchen.classify_kitchen_plan`).
    """
    from steer_envs.control.kitchen import classify_kitchen_plan
    from steer_envs.envs.robosuite.kitchen import SKILLS, skill_target

    task = base.task
    mode = str(task.modes[base._mode])
    legal = [s for s in SKILLS if skill_target(mode, s) is not None]
    to_goal = task.shortest_plan(mode) if mode != "lost" else []
    rows = [
        ("task", f"{base.kitchen_task} (goal: {' or '.join(task.goal)})"),
        ("mode", mode),
        ("skills legal now", ", ".join(legal) or "none"),
        ("modes to the goal", " → ".join(to_goal) or "–"),
    ]
    if plan is not None:
        rows.append(("the chosen plan does", classify_kitchen_plan(base, plan) or "no skill"))
    return rows
