"""Tiny policy settings the baseline tests share (importable: pytest's ``pythonpath``).

Diffusion Policy and the flow policy share the U-Net, so one tiny
architecture serves both; the Maze-like features (the xy of the env
observation in, positions out) serve ACT too.

>>> same_stats({"min": (0.0,), "max": (1.0,)})["action"]
{'min': (0.0,), 'max': (1.0,)}
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, TypeVar

__all__ = ["MAZE_XY", "TINY_UNET", "UNET_ARCH", "same_stats", "tiny_policy"]

T = TypeVar("T")

#: a tiny U-Net (seconds to train on a CPU)
UNET_ARCH: dict[str, Any] = {
    "horizon": 16,
    "down_dims": (8, 16),
    "step_embed_dim": 16,
    "kernel_size": 3,
    "obs_embed_dim": 16,
    "obs_octaves": 2,
}
#: Maze-like features: the xy of the env observation in, positions out
MAZE_XY: dict[str, Any] = {"obs_dim": 2, "action_dim": 2, "obs_indices": (0, 1), "action_obs_indices": (0, 1)}
#: the tiny U-Net as a Maze-like policy planning relative to the agent
TINY_UNET: dict[str, Any] = {**UNET_ARCH, **MAZE_XY, "relative": True}


def same_stats(stats: Mapping[str, Any]) -> dict[str, Any]:
    """Normalization statistics with ``stats`` for both the observation and the action."""
    return {"observation": stats, "action": stats}


def tiny_policy(
    policy: Callable[..., T],
    config: Callable[..., Any],
    fields: Mapping[str, Any],
    stats: Any,
    seed: int,
    **changes: Any,
) -> T:
    """``policy(config(**fields, **changes), stats, seed=seed)``: a tiny policy, ``changes`` over ``fields``."""
    return policy(config(**{**fields, **changes}), stats, seed=seed)
