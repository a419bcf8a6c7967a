"""The Maze2D policies shipped with the package (``baselines/checkpoints``), loaded without pickle.

``scripts/train_maze_checkpoints.sh`` holds the exact commands that produced
them (random-walk data from a fixed seed, then :mod:`.train_maze`); each
checkpoint's ``.json`` record beside it has the loss curve and wall time.
"""

from __future__ import annotations

import json
import os
from importlib import resources
from pathlib import Path
from typing import Any

import torch

from steer_envs.baselines.act.modeling import ACTPolicy
from steer_envs.baselines.diffusion.modeling import DiffusionPolicy

__all__ = ["CHECKPOINTS", "checkpoint_path", "checkpoint_record", "load_checkpoint", "load_pretrained"]

#: kind -> file name in ``steer_envs.baselines/checkpoints``.
CHECKPOINTS: dict[str, str] = {
    "dp": "maze2d_large/dp.safetensors",
    "act": "maze2d_large/act.safetensors",
}


def checkpoint_path(kind: str) -> Path:
    """Filesystem path of the shipped checkpoint of ``kind`` (``"dp"`` or ``"act"``)."""
    if kind not in CHECKPOINTS:
        raise ValueError(f"kind must be one of {sorted(CHECKPOINTS)}, got {kind!r}")
    ref = resources.files("steer_envs.baselines") / "checkpoints" / CHECKPOINTS[kind]
    path = Path(str(ref))
    if not path.is_file():
        raise FileNotFoundError(
            f"checkpoint {CHECKPOINTS[kind]} is missing from the installed package; "
            "regenerate it with scripts/train_maze_checkpoints.sh"
        )
    return path


def checkpoint_record(kind: str) -> dict[str, Any]:
    """The training record (config, settings, losses, wall time) written beside the checkpoint."""
    return json.loads(checkpoint_path(kind).with_suffix(".json").read_text(encoding="utf-8"))


def load_pretrained(kind: str, device: str | torch.device = "cpu") -> DiffusionPolicy | ACTPolicy:
    """The shipped Maze2D-Large policy: ``"dp"`` (:class:`DiffusionPolicy`) or ``"act"`` (:class:`ACTPolicy`)."""
    return load_checkpoint(kind, checkpoint_path(kind), device)


def load_checkpoint(
    kind: str, path: str | os.PathLike[str], device: str | torch.device = "cpu"
) -> DiffusionPolicy | ACTPolicy:
    """A Maze2D policy of ``kind`` (``"dp"`` or ``"act"``) from a file written by ``train_maze`` (e.g. a GPU run).

    ``ValueError`` when the file is missing or holds the other kind of policy.
    """
    if kind not in CHECKPOINTS:
        raise ValueError(f"kind must be one of {sorted(CHECKPOINTS)}, got {kind!r}")
    return DiffusionPolicy.load(path, device) if kind == "dp" else ACTPolicy.load(path, device)
