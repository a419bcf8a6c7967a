"""The Maze2D-Large policies shipped with the package (``baselines/checkpoints``), loaded without pickle.

``scripts/train_maze_checkpoints.sh`` holds the exact commands that produced
them (random-walk data from a fixed seed, then
``python -m steer_envs.baselines.training``); each checkpoint's ``.json``
record beside it has the loss curve and wall time.

>>> policy = load_pretrained("dp")
>>> policy.horizon, policy.action_dim, policy.n_obs_steps
(64, 2, 2)
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path
from typing import Any

import torch

from steer_envs.baselines.common.checkpoint import read_record
from steer_envs.baselines.common.torch_policy import TorchPolicy
from steer_envs.baselines.factory import load_policy
from steer_envs.core.validation import one_of
from steer_envs.io import CheckpointError

__all__ = [
    "BLOCKSTACK_CHECKPOINT",
    "CHECKPOINTS",
    "KITCHEN_CHECKPOINT",
    "CheckpointError",
    "checkpoint_path",
    "checkpoint_record",
    "load_blockstack",
    "load_checkpoint",
    "load_kitchen",
    "load_pretrained",
]

#: kind (a policy name of :mod:`steer_envs.baselines.factory`) -> file in ``steer_envs.baselines/checkpoints``.
CHECKPOINTS: dict[str, str] = {
    "dp": "maze2d_large/dp.safetensors",
    "act": "maze2d_large/act.safetensors",
}


#: the BlockStack pick-or-place Diffusion Policy (ITPS §2.3; ``scripts/train_blockstack_checkpoint.sh``).
BLOCKSTACK_CHECKPOINT = "blockstack/dp.safetensors"
#: the Kitchen door-or-bowl skill Diffusion Policy (ITPS §2.3; ``scripts/train_kitchen_checkpoint.sh``).
KITCHEN_CHECKPOINT = "kitchen/dp.safetensors"


def _shipped(relative: str, script: str) -> Path:
    ref = resources.files("steer_envs.baselines") / "checkpoints" / relative
    path = Path(str(ref))
    if not path.is_file():
        raise FileNotFoundError(
            f"checkpoint {relative} is missing from the installed package; regenerate it with {script}"
        )
    return path


def _check_kind(kind: str) -> None:
    one_of(kind, "kind", tuple(CHECKPOINTS))


def checkpoint_path(kind: str) -> Path:
    """Filesystem path of the shipped checkpoint of ``kind`` (``"dp"`` or ``"act"``).

    >>> checkpoint_path("act").name
    'act.safetensors'
    """
    _check_kind(kind)
    return _shipped(CHECKPOINTS[kind], "scripts/train_maze_checkpoints.sh")


def checkpoint_record(kind: str) -> dict[str, Any]:
    """The training record (config, settings, losses, wall time) written beside the checkpoint.

    >>> checkpoint_record("dp")["training"]["settings"]["steps"]
    40000

    :class:`~steer_envs.io.CheckpointError` when the record is missing, too large or not a JSON object.
    """
    return read_record(checkpoint_path(kind).with_suffix(".json"))


def load_pretrained(kind: str, device: str | torch.device = "cpu") -> TorchPolicy:
    """The shipped Maze2D-Large policy: ``"dp"`` (a ``DiffusionPolicy``) or ``"act"`` (an ``ACTPolicy``)."""
    return load_checkpoint(kind, checkpoint_path(kind), device)


def load_checkpoint(kind: str, path: str | os.PathLike[str], device: str | torch.device = "cpu") -> TorchPolicy:
    """A policy of ``kind`` (``"dp"`` or ``"act"``) from a checkpoint file, e.g. a GPU training run.

    :class:`~steer_envs.io.CheckpointError` (a ``ValueError`` naming the file)
    when the file is missing, damaged, inconsistent or holds another kind of policy.
    """
    _check_kind(kind)
    return load_policy(path, name=kind, device=device)


def load_blockstack(
    device: str | torch.device = "cpu", checkpoint: str | os.PathLike[str] | None = None
) -> TorchPolicy:
    """The shipped BlockStack Diffusion Policy (or a ``checkpoint`` file of the same layout).

    One skill per plan, ``(32, 4)`` waypoints ``[x, y, z, gripper]``; its
    ``interaction_dims`` are ``(0, 1, 2)``: a 3D sketch or point steers the
    waypoints' positions (:mod:`steer_envs.data.blockstack_plans`).
    """
    path = checkpoint or _shipped(BLOCKSTACK_CHECKPOINT, "scripts/train_blockstack_checkpoint.sh")
    policy = load_policy(path, name="dp", device=device)
    policy.interaction_dims = (0, 1, 2)
    return policy


def load_kitchen(device: str | torch.device = "cpu", checkpoint: str | os.PathLike[str] | None = None) -> TorchPolicy:
    """The shipped Kitchen Diffusion Policy (or a ``checkpoint`` file of the same layout).

    One door or bowl skill per plan, ``(32, 5)`` waypoints ``[x, y, z, yaw,
    gripper]``; its ``interaction_dims`` are ``(0, 1, 2)``: a clicked point
    steers the waypoints' positions (:mod:`steer_envs.data.kitchen_plans`).
    """
    path = checkpoint or _shipped(KITCHEN_CHECKPOINT, "scripts/train_kitchen_checkpoint.sh")
    policy = load_policy(path, name="dp", device=device)
    policy.interaction_dims = (0, 1, 2)
    return policy
