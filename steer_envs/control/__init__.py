"""Robot controllers: what turns a plan or a goal into low-level actions on an env.

* :mod:`.blockstack` -- BlockStack skill plans run on the arm
  (:func:`execute_plan`), the skill a plan performs (:func:`classify_plan`,
  :func:`plan_target`) and the skill vocabulary and P-control the scripted
  expert, the tracker and the simulated user share (:class:`Skill`,
  :func:`towers`, :func:`free_table_spot`, :func:`goal_tower_skill`,
  :func:`move_action`);
* :mod:`.kitchen` -- Kitchen skill plans run by a waypoint tracker
  (:func:`execute_kitchen_plan`) and read off geometrically
  (:func:`classify_kitchen_plan`);
* :mod:`.plans` -- what both plan trackers share (:func:`check_plan`, :func:`first_index`,
  the executions ``"open_loop"`` and ``"closed_loop"``: :data:`EXECUTIONS`, :func:`check_execution`);
* :mod:`.waypoint` -- D4RL's Maze2D waypoint controller
  (:class:`WaypointController`, Q-iteration over grid cells).

The layer sits above the envs (it drives them) and below data, users and
policies (experts, plan datasets and simulated users are built on it).
Names are imported lazily.

>>> from steer_envs.control import WaypointController
>>> WaypointController.__name__
'WaypointController'
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from steer_envs.core.lazy import lazy_exports

if TYPE_CHECKING:
    from steer_envs.control.blockstack import (
        Skill,
        classify_plan,
        execute_plan,
        free_table_spot,
        goal_tower_skill,
        move_action,
        plan_target,
        quarter_turn,
        towers,
        wrap_quarter,
        yaw_of,
    )
    from steer_envs.control.kitchen import (
        KitchenPlanOutcome,
        KitchenScene,
        classify_kitchen_plan,
        eef_yaw,
        execute_kitchen_plan,
        kitchen_scene,
    )
    from steer_envs.control.plans import EXECUTIONS, PlanOutcome, check_execution, check_plan, first_index
    from steer_envs.control.waypoint import (
        WaypointController,
        cell_path,
        q_iteration,
    )

_EXPORTS: dict[str, str] = {
    "Skill": "blockstack",
    "classify_plan": "blockstack",
    "execute_plan": "blockstack",
    "free_table_spot": "blockstack",
    "goal_tower_skill": "blockstack",
    "move_action": "blockstack",
    "plan_target": "blockstack",
    "quarter_turn": "blockstack",
    "towers": "blockstack",
    "wrap_quarter": "blockstack",
    "yaw_of": "blockstack",
    "KitchenPlanOutcome": "kitchen",
    "KitchenScene": "kitchen",
    "classify_kitchen_plan": "kitchen",
    "eef_yaw": "kitchen",
    "execute_kitchen_plan": "kitchen",
    "kitchen_scene": "kitchen",
    "EXECUTIONS": "plans",
    "PlanOutcome": "plans",
    "check_execution": "plans",
    "check_plan": "plans",
    "first_index": "plans",
    "WaypointController": "waypoint",
    "cell_path": "waypoint",
    "q_iteration": "waypoint",
}

__all__ = [
    "EXECUTIONS",
    "KitchenPlanOutcome",
    "KitchenScene",
    "PlanOutcome",
    "Skill",
    "WaypointController",
    "cell_path",
    "check_execution",
    "check_plan",
    "classify_kitchen_plan",
    "classify_plan",
    "eef_yaw",
    "execute_kitchen_plan",
    "execute_plan",
    "first_index",
    "free_table_spot",
    "goal_tower_skill",
    "kitchen_scene",
    "move_action",
    "plan_target",
    "q_iteration",
    "quarter_turn",
    "towers",
    "wrap_quarter",
    "yaw_of",
]


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
