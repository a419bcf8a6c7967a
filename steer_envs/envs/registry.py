"""Gymnasium registration of every steer-envs environment.

Entry points are strings, so ``import steer_envs`` does not import simulators
or geometry libraries; an env's module is imported when it is made.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym

NAMESPACE = "steer_envs"


@dataclass(frozen=True)
class EnvEntry:
    """One registered environment id."""

    name: str  # e.g. "SoupScoop-v0" (registered as "steer_envs/SoupScoop-v0")
    entry_point: str
    max_episode_steps: int
    vector_entry_point: str | None = None
    kwargs: dict[str, Any] = field(default_factory=dict)
    kinematic: bool = False  # 2D numpy domain with a batched vector path

    @property
    def id(self) -> str:
        return f"{NAMESPACE}/{self.name}"


ENTRIES: tuple[EnvEntry, ...] = (
    EnvEntry(
        "SoupScoop-v0",
        "steer_envs.envs.soup_scoop:SoupScoopEnv",
        max_episode_steps=1000,
        vector_entry_point="steer_envs.envs.soup_scoop:make_vector_env",
        kinematic=True,
    ),
    EnvEntry(
        "ConvexMode-v0",
        "steer_envs.envs.convex_mode:ConvexModeEnv",
        max_episode_steps=1000,
        vector_entry_point="steer_envs.envs.convex_mode:make_vector_env",
        kinematic=True,
    ),
    EnvEntry(
        "Cooking-v0",
        "steer_envs.envs.cooking:CookingEnv",
        max_episode_steps=2000,
        vector_entry_point="steer_envs.envs.cooking:make_vector_env",
        kinematic=True,
    ),
    *(
        EnvEntry(
            f"PolygonNav-{k}Mode-v0",
            "steer_envs.envs.polygon_nav:PolygonNavEnv",
            max_episode_steps=500,
            vector_entry_point="steer_envs.envs.polygon_nav:make_vector_env",
            kwargs={"num_modes": k},
            kinematic=True,
        )
        for k in (3, 4, 5)
    ),
    *(
        EnvEntry(
            f"Maze2D-{maze}-v0",
            "steer_envs.envs.maze2d:Maze2DEnv",
            max_episode_steps=steps,
            kwargs={"maze": maze.lower()},
        )
        for maze, steps in (("Umaze", 300), ("Medium", 600), ("Large", 800))
    ),
)


def env_ids(kinematic_only: bool = False) -> list[str]:
    """Every registered steer-envs id (optionally only the 2D kinematic ones)."""
    return [e.id for e in ENTRIES if e.kinematic or not kinematic_only]


def entry(env_id: str) -> EnvEntry:
    """The registry entry of ``env_id`` (with or without the namespace)."""
    for e in ENTRIES:
        if env_id in (e.id, e.name):
            return e
    raise ValueError(f"unknown steer-envs id {env_id!r}; registered: {env_ids()}")


def register_all() -> None:
    """Register every entry with Gymnasium (idempotent)."""
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
