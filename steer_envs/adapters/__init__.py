"""Policies written elsewhere, made steerable: adapters to :class:`~steer_envs.core.policy.DiffusionPolicyLike`.

* :class:`~steer_envs.adapters.lerobot.LeRobotDiffusion`: a LeRobot
  ``DiffusionPolicy`` (and its processors), steered by all six ITPS samplers.

The adapters duck-type the third-party objects: importing this package
imports none of their libraries.
"""

from __future__ import annotations

from steer_envs.adapters.lerobot import LeRobotDiffusion

__all__ = ["LeRobotDiffusion"]
