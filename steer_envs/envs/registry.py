"""Gymnasium registration of every steer-envs environment.

Entry points are strings, so ``import steer_envs`` does not import simulators
or geometry libraries; an env's module is imported when it is made.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import gymnasium as gym

NAMESPACE = "steer_envs"


@dataclass(frozen=True)
class EnvEntry:
    """One registered environment id: how Gymnasium makes it and which scripted expert solves it.

    Attributes:
        name: the id without the namespace, e.g. ``"SoupScoop-v0"`` (registered as
            ``"steer_envs/SoupScoop-v0"``).
        entry_point: ``"module:Class"`` of the env.
        max_episode_steps: the registered step limit.
        vector_entry_point: ``"module:function"`` building a batched env, if the domain has one.
        kwargs: constructor arguments of this id (e.g. ``num_modes``).
        kinematic: a 2D numpy domain with a batched vector path.
        expert: ``"module:Class"`` of its scripted expert (:func:`steer_envs.data.experts.make_expert`),
            or None; imported only when an expert is made.
        variant_of: for a variant id (``...Dense-v0``, ``Maze2D-...Goal-v0``), the name of the entry it
            varies (same env class and expert, other ``kwargs``); None for a base id.
        extra: the ``setup.cfg`` extra the env needs (``"arm"``: robosuite), or None when the bare
            ``pip install steer-envs`` makes it; making it without the extra raises an ``ImportError``
            naming ``pip install "steer-envs[<extra>]"``.

    >>> entry("ConvexMode-v0").expert
    'steer_envs.data.experts.convex_mode:ConvexModeExpert'
    >>> entry("Lift-v0").extra, entry("Maze2D-Large-v0").extra
    ('arm', None)
    """

    name: str
    entry_point: str
    max_episode_steps: int
    vector_entry_point: str | None = None
    kwargs: dict[str, Any] = field(default_factory=dict)
    kinematic: bool = False
    expert: str | None = None
    variant_of: str | None = None
    extra: str | None = None

    def __post_init__(self) -> None:
        for label, value in (("entry_point", self.entry_point), ("expert", self.expert)):
            if value is not None and (not isinstance(value, str) or value.count(":") != 1):
                raise ValueError(f"EnvEntry {self.name!r}: `{label}` must be 'module:Name', got {value!r}")

    @property
    def id(self) -> str:
        """The registered id, ``"steer_envs/<name>"``."""
        return f"{NAMESPACE}/{self.name}"


BASE_ENTRIES: tuple[EnvEntry, ...] = (
    EnvEntry(
        "SoupScoop-v0",
        "steer_envs.envs.soup_scoop:SoupScoopEnv",
        max_episode_steps=1000,
        vector_entry_point="steer_envs.envs.soup_scoop:make_vector_env",
        kinematic=True,
        expert="steer_envs.data.experts.soup_scoop:SoupScoopExpert",
    ),
    EnvEntry(
        "ConvexMode-v0",
        "steer_envs.envs.convex_mode:ConvexModeEnv",
        max_episode_steps=1000,
        vector_entry_point="steer_envs.envs.convex_mode:make_vector_env",
        kinematic=True,
        expert="steer_envs.data.experts.convex_mode:ConvexModeExpert",
    ),
    EnvEntry(
        "Cooking-v0",
        "steer_envs.envs.cooking:CookingEnv",
        max_episode_steps=2000,
        vector_entry_point="steer_envs.envs.cooking:make_vector_env",
        kinematic=True,
        expert="steer_envs.data.experts.cooking:CookingExpert",
    ),
    EnvEntry(
        "InspectionLine-v0",
        "steer_envs.envs.inspection_line:InspectionLineEnv",
        max_episode_steps=1000,
        vector_entry_point="steer_envs.envs.inspection_line:make_vector_env",
        kinematic=True,
        expert="steer_envs.data.experts.inspection_line:InspectionLineExpert",
    ),
    EnvEntry(
        "ColorTracing-v0",
        "steer_envs.envs.color_tracing:ColorTracingEnv",
        max_episode_steps=1000,
        vector_entry_point="steer_envs.envs.color_tracing:make_vector_env",
        kinematic=True,
        expert="steer_envs.data.experts.color_tracing:ColorTracingExpert",
    ),
    *(
        EnvEntry(
            f"PolygonNav-{k}Mode-v0",
            "steer_envs.envs.polygon_nav:PolygonNavEnv",
            max_episode_steps=500,
            vector_entry_point="steer_envs.envs.polygon_nav:make_vector_env",
            kwargs={"num_modes": k},
            kinematic=True,
            expert="steer_envs.data.experts.polygon_nav:PolygonNavExpert",
        )
        for k in (3, 4, 5)
    ),
    *(
        EnvEntry(
            f"Maze2D-{maze}-v0",
            "steer_envs.envs.maze2d:Maze2DEnv",
            max_episode_steps=steps,
            kwargs={"maze": maze.lower()},
            expert="steer_envs.data.experts.maze2d:Maze2DExpert",
        )
        for maze, steps in (("Umaze", 300), ("Medium", 600), ("Large", 800))
    ),
    *(
        EnvEntry(
            name,
            "steer_envs.envs.robosuite.adapter:RobosuiteEnv",
            max_episode_steps=steps,
            kwargs={"task": task},
            expert=f"steer_envs.data.experts.robosuite:{expert}",
            extra="arm",
        )
        for name, task, steps, expert in (
            ("Lift-v0", "lift", 200, "LiftExpert"),
            ("Can-v0", "can", 400, "CanExpert"),
            ("Square-v0", "square", 500, "SquareExpert"),
        )
    ),
    EnvEntry(
        "BlockStack-v0",
        "steer_envs.envs.robosuite.blockstack:BlockStackEnv",
        max_episode_steps=2000,
        expert="steer_envs.data.experts.blockstack:BlockStackExpert",
        extra="arm",
    ),
    EnvEntry(
        "ArmScoop-v0",
        "steer_envs.envs.robosuite.arm_scoop:ArmScoopEnv",
        max_episode_steps=600,
        expert="steer_envs.data.experts.arm_scoop:ArmScoopExpert",
        extra="arm",
    ),
    EnvEntry(
        "Kitchen-v0",
        "steer_envs.envs.robosuite.kitchen:KitchenEnv",
        max_episode_steps=1500,
        expert="steer_envs.data.experts.kitchen:KitchenExpert",
        extra="arm",
    ),
)


def _variant(base: EnvEntry, suffix: str, **kwargs: Any) -> EnvEntry:
    """``base`` under the name ``<name><suffix>-v0`` (Gymnasium-Robotics style: ``PointMaze_UMazeDense-v3``)."""
    stem, version = base.name.rsplit("-", 1)
    return replace(base, name=f"{stem}{suffix}-{version}", kwargs={**base.kwargs, **kwargs}, variant_of=base.name)


#: physics steps per env step of the dense Maze2D RL variants (0.08 s; the ITPS and the sparse goal ids keep the
#: data rate, 4 = 0.04 s): half as many decisions per episode, the same time limit in seconds (the step limit halves).
MAZE_DENSE_FRAME_SKIP = 8
_MAZE_ITPS_FRAME_SKIP = 4


#: what a kinematic ``...Dense-v0`` id sets: the shaped reward, the sensor bits observed (task memory such as
#: "soup on the spoon" is then in the state) and a ``[-1, 1]^2`` action box (what RL policies output)
KINEMATIC_DENSE_KWARGS: dict[str, Any] = {"reward_type": "dense", "observe_sensors": True, "normalize_actions": True}
#: what the Maze2D ``...Dense-v0`` / ``...GoalDense-v0`` ids set besides the shaped reward: the velocity observed
#: (as PointMaze: without it the state is not Markov), a ``[-1, 1]^2`` action box mapped onto the maze, and
#: :data:`MAZE_DENSE_FRAME_SKIP`; the plain ``...Dense-v0`` ids also observe the goal (``observe_goal``)
MAZE_DENSE_KWARGS: dict[str, Any] = {
    "reward_type": "dense",
    "observe_velocity": True,
    "normalize_actions": True,
    "frame_skip": MAZE_DENSE_FRAME_SKIP,
}


def _variants() -> tuple[EnvEntry, ...]:
    out: list[EnvEntry] = []
    for e in BASE_ENTRIES:
        if e.kinematic:
            out.append(_variant(e, "Dense", **KINEMATIC_DENSE_KWARGS))
        elif e.entry_point.startswith("steer_envs.envs.maze2d:"):
            # the dense ids act at half the ITPS rate, at which SAC learns Maze2D-Large within 100k steps; the
            # sparse goal ids keep it, at which HER learns Umaze fastest (docs/results.md, sb3), and the waypoint
            # action box of the plain ids
            assert e.max_episode_steps is not None
            limit = e.max_episode_steps * _MAZE_ITPS_FRAME_SKIP // MAZE_DENSE_FRAME_SKIP
            dense = replace(e, max_episode_steps=limit)
            out.append(_variant(dense, "Dense", observe_goal=True, **MAZE_DENSE_KWARGS))
            goal = replace(e, entry_point="steer_envs.envs.maze2d:Maze2DGoalEnv")
            out.append(_variant(goal, "Goal", observe_velocity=True))
            goal_dense = replace(dense, entry_point="steer_envs.envs.maze2d:Maze2DGoalEnv")
            out.append(_variant(goal_dense, "GoalDense", **MAZE_DENSE_KWARGS))
    return tuple(out)


#: the variant ids, made for RL as registered: the dense ids of every 2D env (``SoupScoopDense-v0``:
#: :data:`KINEMATIC_DENSE_KWARGS`; ``Maze2D-UmazeDense-v0``: :data:`MAZE_DENSE_KWARGS`) and the goal-conditioned
#: Maze2D (``Maze2D-UmazeGoal-v0``: sparse, the velocity observed; ``Maze2D-UmazeGoalDense-v0``). The base ids keep
#: the thesis's interface (xy observation, raw velocity or waypoint actions, sparse reward).
VARIANT_ENTRIES: tuple[EnvEntry, ...] = _variants()
#: every registered entry, base ids first.
ENTRIES: tuple[EnvEntry, ...] = BASE_ENTRIES + VARIANT_ENTRIES


def env_ids(kinematic_only: bool = False, variants: bool = False) -> list[str]:
    """The registered steer-envs ids (optionally only the 2D kinematic ones).

    The base ids by default; ``variants=True`` adds the variant ids
    (:data:`VARIANT_ENTRIES`: the ``...Dense-v0`` and Maze2D ``...Goal-v0`` ids).

    >>> env_ids(kinematic_only=True)[:2]
    ['steer_envs/SoupScoop-v0', 'steer_envs/ConvexMode-v0']
    >>> [i for i in env_ids(variants=True) if "Umaze" in i]  # doctest: +NORMALIZE_WHITESPACE
    ['steer_envs/Maze2D-Umaze-v0', 'steer_envs/Maze2D-UmazeDense-v0', 'steer_envs/Maze2D-UmazeGoal-v0',
     'steer_envs/Maze2D-UmazeGoalDense-v0']
    """
    for name, value in (("kinematic_only", kinematic_only), ("variants", variants)):
        if not isinstance(value, bool):
            raise TypeError(f"env_ids: {name} must be a bool, got {type(value).__name__} {value!r}")
    chosen = ENTRIES if variants else BASE_ENTRIES
    return [e.id for e in chosen if e.kinematic or not kinematic_only]


def entry(env_id: str) -> EnvEntry:
    """The registry entry of ``env_id`` (with or without the namespace); ``ValueError`` for an unknown id.

    >>> entry("steer_envs/Maze2D-Large-v0").kwargs
    {'maze': 'large'}
    >>> entry("PolygonNav-3ModeDense-v0").kwargs  # the RL options, as registered
    {'num_modes': 3, 'reward_type': 'dense', 'observe_sensors': True, 'normalize_actions': True}
    """
    for e in ENTRIES:
        if env_id in (e.id, e.name):
            return e
    raise ValueError(f"unknown steer-envs id {env_id!r}; registered: {env_ids(variants=True)}")


def register_all() -> None:
    """Register every entry with Gymnasium (idempotent; ``import steer_envs`` calls it).

    It also makes the wrappers of ``gymnasium.make`` leave a refused ``reset``
    without effect (:func:`steer_envs.envs.refused_reset.install`), as the envs do.

    >>> import gymnasium as gym
    >>> register_all()
    >>> "steer_envs/Cooking-v0" in gym.registry
    True
    """
    from steer_envs.envs.refused_reset import install

    install()
    for e in ENTRIES:
        if e.id in gym.registry:
            continue
        gym.register(
            id=e.id,
            entry_point=e.entry_point,
            vector_entry_point=e.vector_entry_point,
            max_episode_steps=e.max_episode_steps,
            kwargs=dict(e.kwargs),
        )
