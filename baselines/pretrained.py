"""Every checkpoint shipped with the package (``baselines/checkpoints``), loaded by name without pickle.

One loader, :func:`load_pretrained`, for all of them: the Maze2D-Large
Diffusion Policy and ACT (``"dp"``, ``"act"``, and ``"dp-w16"``, the
previous, narrower Maze2D DP), the BlockStack and Kitchen skill Diffusion
Policies (``"blockstack"``, ``"kitchen"``), the flow-matching policy of the
BlockStack DP's preset and data (``"blockstack-flow"``), a checkpoint file of the same
layout as a shipped one (``checkpoint=``), or any checkpoint file (a policy
of a registered kind, or a GLiDE :class:`~steer_envs.baselines.glide.classifier.ModeClassifier`).

``scripts/train_maze_checkpoints.sh``,
``scripts/train_blockstack_checkpoint.sh`` (``POLICY=flow`` for the flow)
and ``scripts/train_kitchen_checkpoint.sh`` hold the exact commands that produced
them (``python -m steer_envs.baselines.training``); each checkpoint's ``.json``
record beside it has the loss curve and wall time, which those scripts'
``--check`` replays.

Suites and steer-ui name their policy by a ``"module:function"`` loader and
an optional checkpoint file; :func:`resolve_policy` turns that pair into a
policy and :func:`shared_policy` keeps one per process.

>>> policy = load_pretrained("dp")
>>> policy.horizon, policy.action_dim, policy.n_obs_steps
(64, 2, 2)
>>> load_pretrained("blockstack").interaction_dims  # a 3D sketch steers the waypoints' positions
(0, 1, 2)
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import threading
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import torch

from steer_envs.baselines.common.checkpoint import read_record
from steer_envs.baselines.factory import load_policy
from steer_envs.core.validation import describe, integer, one_of
from steer_envs.io import CheckpointError
from steer_envs.utils.imports import resolve_function

__all__ = [
    "CHECKPOINTS",
    "POLICY_UNAVAILABLE",
    "PRETRAINED_LOADER",
    "CheckpointError",
    "ShippedCheckpoint",
    "add_policy_arguments",
    "checkpoint_path",
    "checkpoint_record",
    "load_pretrained",
    "resolve_policy",
    "shared_policy",
]


@dataclass(frozen=True)
class ShippedCheckpoint:
    """One shipped checkpoint: its file under ``baselines/checkpoints``, the policy kind it holds, its recipe.

    ``interaction_dims``: the plan entries an interaction steers (``None``: all;
    the skill policies' ``(0, 1, 2)``: the waypoints' xyz, not yaw or gripper).
    """

    file: str
    kind: str
    script: str
    interaction_dims: tuple[int, ...] | None = None


#: name -> the shipped checkpoint :func:`load_pretrained` loads for it.
CHECKPOINTS: dict[str, ShippedCheckpoint] = {
    "dp": ShippedCheckpoint("maze2d_large/dp.safetensors", "dp", "scripts/train_maze_checkpoints.sh"),
    "act": ShippedCheckpoint("maze2d_large/act.safetensors", "act", "scripts/train_maze_checkpoints.sh"),
    # the previous Maze2D DP (down dims 16/32/64), kept for comparison (docs/results.md)
    "dp-w16": ShippedCheckpoint("maze2d_large/dp-w16.safetensors", "dp", "docs/results.md (the w16 DP)"),
    # ITPS §2.3: one pick or place skill per plan, (32, 4) waypoints [x, y, z, gripper]
    "blockstack": ShippedCheckpoint(
        "blockstack/dp.safetensors", "dp", "scripts/train_blockstack_checkpoint.sh", (0, 1, 2)
    ),
    # ITPS §2.3: one door or bowl skill per plan, (32, 5) waypoints [x, y, z, yaw, gripper]
    "kitchen": ShippedCheckpoint("kitchen/dp.safetensors", "dp", "scripts/train_kitchen_checkpoint.sh", (0, 1, 2)),
    # the flow-matching policy of the same preset, network and data as "blockstack" (itps-blockstack's FLOW-*)
    "blockstack-flow": ShippedCheckpoint(
        "blockstack/flow.safetensors", "flow", "POLICY=flow scripts/train_blockstack_checkpoint.sh", (0, 1, 2)
    ),
}
#: the ``module:function`` of the shipped checkpoints (a suite's default ``loader``)
PRETRAINED_LOADER = "steer_envs.baselines.pretrained:load_pretrained"
#: exceptions that mean "this policy is not available (yet)": its module, function or checkpoint is missing
POLICY_UNAVAILABLE: tuple[type[Exception], ...] = (ImportError, AttributeError, FileNotFoundError)


def _shipped(name: str) -> ShippedCheckpoint:
    one_of(name, "name", tuple(CHECKPOINTS), owner="load_pretrained")
    return CHECKPOINTS[name]


def checkpoint_path(name: str) -> Path:
    """Filesystem path of the shipped checkpoint ``name`` (a key of :data:`CHECKPOINTS`).

    ``FileNotFoundError`` naming the script that makes it when the file is not installed.

    >>> checkpoint_path("act").name
    'act.safetensors'
    """
    shipped = _shipped(name)
    path = Path(str(resources.files("steer_envs.baselines") / "checkpoints" / shipped.file))
    if not path.is_file():
        raise FileNotFoundError(
            f"checkpoint {shipped.file} is missing from the installed package; regenerate it with {shipped.script}"
        )
    return path


def checkpoint_record(name: str) -> dict[str, Any]:
    """The training record (config, settings, losses, wall time) written beside the shipped checkpoint.

    >>> checkpoint_record("dp")["training"]["settings"]["steps"]
    40000

    :class:`~steer_envs.io.CheckpointError` when the record is missing, too large or not a JSON object.
    """
    return read_record(checkpoint_path(name).with_suffix(".json"))


def load_pretrained(
    name: str | os.PathLike[str],
    device: str | torch.device = "cpu",
    *,
    checkpoint: str | os.PathLike[str] | None = None,
) -> Any:
    """The shipped checkpoint ``name``, a file of its layout (``checkpoint``), or the checkpoint file ``name``.

    ``name``: a key of :data:`CHECKPOINTS` (``"dp"``, ``"act"``, ``"dp-w16"``,
    ``"blockstack"``, ``"kitchen"``, the flow policy ``"blockstack-flow"``) or a path. With a key and a ``checkpoint``
    file (e.g. a GPU training run), the file is loaded in the shipped one's
    place: it must hold the same policy kind and gets the same
    ``interaction_dims``. A path loads whatever it holds: a policy of a
    registered kind (:func:`~steer_envs.baselines.factory.load_policy`) or a
    GLiDE mode classifier. :class:`~steer_envs.io.CheckpointError` (a
    ``ValueError`` naming the file) for a missing, damaged or foreign file.
    """
    if not isinstance(name, str) or name not in CHECKPOINTS:
        if checkpoint or (isinstance(name, str) and not _looks_like_path(name)):
            _shipped(str(name))  # a ValueError listing the names
        return _load_file(Path(name), device)
    shipped = _shipped(name)
    path = checkpoint or checkpoint_path(name)
    policy = load_policy(path, name=shipped.kind, device=device)
    if shipped.interaction_dims is not None:
        policy.interaction_dims = shipped.interaction_dims
    return policy


def _looks_like_path(name: str) -> bool:
    return os.sep in name or "/" in name or name.endswith(".safetensors")


def _load_file(path: Path, device: str | torch.device) -> Any:
    """A policy of a registered kind, or a GLiDE classifier, whichever the file's metadata says."""
    if "glide_classifier" in _metadata_keys(path):
        from steer_envs.baselines.glide.classifier import ModeClassifier

        return ModeClassifier.load(path)
    return load_policy(path, device=device)


def _metadata_keys(path: Path) -> set[str]:
    """The keys of a safetensors file's ``__metadata__`` (empty when it is not readable as one)."""
    try:
        with open(path, "rb") as fh:
            size = int.from_bytes(fh.read(8), "little")
            header = json.loads(fh.read(size)) if 0 < size <= 100_000_000 else {}
    except (OSError, ValueError):
        return set()
    metadata = header.get("__metadata__") if isinstance(header, dict) else None
    return set(metadata) if isinstance(metadata, dict) else set()


def add_policy_arguments(parser: argparse.ArgumentParser) -> None:
    """A script's ``--policy`` (``dp`` or ``act``), ``--loader`` and ``--checkpoint``: the frozen Maze2D policy it
    steers, for ``resolve_policy(args.loader or PRETRAINED_LOADER, args.policy, args.checkpoint)``.

    >>> parser = argparse.ArgumentParser()
    >>> add_policy_arguments(parser)
    >>> vars(parser.parse_args(["--policy", "act"]))
    {'policy': 'act', 'loader': None, 'checkpoint': ''}
    """
    parser.add_argument("--policy", choices=("dp", "act"), default="dp", help="frozen policy (default: dp)")
    parser.add_argument(
        "--loader", default=None, help="'module:function' returning the policy (default: the shipped checkpoint)"
    )
    parser.add_argument(
        "--checkpoint",
        default="",
        help="a checkpoint of --policy from python -m steer_envs.baselines.training (default: the shipped one)",
    )


def resolve_policy(loader: str, name: str, checkpoint: str | os.PathLike[str] = "") -> Any:
    """The policy a suite's ``loader`` / ``checkpoint`` parameters name (not cached; see :func:`shared_policy`).

    A non-empty ``checkpoint`` wins: ``load_pretrained(name, checkpoint=checkpoint)``
    (a wrong path is a ``ValueError``, not a missing policy). Else the
    ``"module:function"`` ``loader`` is called as ``loader(name)`` when it takes
    a positional argument, else as ``loader()``, and must return a
    :class:`~steer_envs.core.policy.TrajectoryPolicy`. Raises one of
    :data:`POLICY_UNAVAILABLE` while the policy is not available.

    >>> resolve_policy(PRETRAINED_LOADER, "act").horizon
    64
    >>> resolve_policy("steer_envs.no_such_module:load", "dp")
    Traceback (most recent call last):
    ModuleNotFoundError: No module named 'steer_envs.no_such_module'
    """
    if checkpoint:
        return load_pretrained(name, checkpoint=checkpoint)
    fn = resolve_function(loader)
    policy = fn(name) if _takes_argument(fn) else fn()
    from steer_envs.core.policy import TrajectoryPolicy

    if not isinstance(policy, TrajectoryPolicy):
        raise TypeError(f"{loader}({name!r}) must return a TrajectoryPolicy, got {type(policy).__name__}")
    return policy


def _takes_argument(fn: Any) -> bool:
    try:
        params = inspect.signature(fn).parameters.values()
    except (TypeError, ValueError):
        return True
    positional = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    return any(p.kind in positional or p.kind == inspect.Parameter.VAR_POSITIONAL for p in params)


_SHARED: dict[tuple[str, str, str, str, int], Any] = {}
_SHARED_LOCK = threading.Lock()


def shared_policy(
    name: str,
    checkpoint: str | os.PathLike[str] = "",
    accelerate: str = "none",
    *,
    loader: str = PRETRAINED_LOADER,
    owner: str = "accelerate",
    steps: int = 0,
) -> Any:
    """:func:`resolve_policy`'s policy with its denoiser in ``accelerate`` mode, loaded once per process.

    Every caller in a process (the suites' trials, steer-ui's sessions) with
    the same ``(loader, name, checkpoint, accelerate, steps)`` gets the same object;
    loading is serialized (thread-safe). ``steps`` > 0: the policy's
    ``with_steps(steps)`` (DDIM or Euler steps per plan; sharing the network of
    the policy with its own steps). ``accelerate``: a mode of
    :func:`~steer_envs.baselines.diffusion.acceleration.accelerated` (``"none"``:
    eager; a policy without an ``accelerate`` method takes only ``"none"``,
    ``"auto"`` and ``"fastest"``; a ``TypeError`` naming ``owner`` otherwise).

    >>> shared_policy("dp") is shared_policy("dp")
    True
    """
    from steer_envs.baselines.diffusion.acceleration import accelerated, resolve_acceleration

    mode = resolve_acceleration(accelerate, owner=owner)
    steps = integer(steps, "steps", low=0, high=100_000, owner="shared_policy")
    key = (loader, name, str(checkpoint or ""), mode)
    with _SHARED_LOCK:
        policy = _SHARED.get((*key, 0))
        if policy is None:
            policy = resolve_policy(loader, name, checkpoint)
            if accelerate != "none":
                policy = accelerated(policy, accelerate, owner=owner)
            _SHARED[(*key, 0)] = policy
        if not steps:
            return policy
        stepped = _SHARED.get((*key, steps))
        if stepped is None:
            with_steps = getattr(policy, "with_steps", None)
            if not callable(with_steps):
                raise TypeError(f"shared_policy: steps={steps} needs a policy with with_steps, got {describe(policy)}")
            stepped = _SHARED[(*key, steps)] = with_steps(steps)
        return stepped
