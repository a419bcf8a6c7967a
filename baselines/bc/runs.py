"""Resumable BC training: minibatch steps with one Adam optimiser throughout, the run's state in checked files.

:class:`BCRun` trains a :class:`~steer_envs.baselines.bc.modeling.BCPolicy`
configured with ``steps`` for as many minibatch steps as asked, in as many
calls as needed: one Adam optimiser and the policy's batch generator carry
over, so training to step 100 and then on to step 300 gives the weights of one
300-step :meth:`~steer_envs.baselines.bc.modeling.BCPolicy.fit`, bit for bit.
The run's whole state (weights, Adam's moments, the batch generator, the step,
the loss log) is one safetensors file (:meth:`BCRun.save`, :meth:`BCRun.load`),
written atomically with the sha256 of its tensors and loaded only after that
checksum, the run's key and every tensor's name, shape and dtype have been
checked (:mod:`~steer_envs.baselines.common.checkpoint`).

:func:`train_run` keeps a run in a folder: the state at every step it is asked
to keep (``step-00050000.safetensors``) and, every ``save_every`` seconds, the
latest one (``latest.safetensors``). A killed training continues from its last
saved state, and a larger budget continues a smaller one's run: the learning
rate is constant, so a run's weights at step ``k`` do not depend on its
budget. The folder is named by :attr:`BCRun.key`, a digest of everything the
weights depend on but the budget: the config without ``steps``, the seed, the
loss log's interval and the training tensors.

Why not the trainer of :mod:`steer_envs.baselines.training`: it trains the
chunked trajectory policies (windows of a dataset, AdamW with a warm-up and a
cosine decay tied to the budget, gradient clipping); a BC MLP trains by
constant-rate Adam on i.i.d. pairs, the loop :meth:`BCPolicy.fit` runs, which
:class:`BCRun` reuses step for step.

>>> import numpy as np, tempfile
>>> from steer_envs.baselines.bc import BCConfig, BCPolicy
>>> x = np.random.default_rng(0).normal(size=(32, 2))
>>> config = BCConfig(hidden=(8,), epochs=None, steps=30, output="clip")
>>> whole = BCPolicy(config, seed=1)
>>> _ = whole.fit(x, -x)
>>> with tempfile.TemporaryDirectory() as folder:
...     first = BCRun(BCPolicy(config, seed=1), x, -x)
...     _ = train_run(first, 10, folder=folder)  # stopped at step 10, its state kept
...     again = BCRun(BCPolicy(config, seed=1), x, -x)
...     _ = train_run(again, 30, folder=folder)  # continues from step 10
>>> again.trained_from, bool(np.array_equal(again.policy(x), whole(x)))
(10, True)
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import torch
from numpy.typing import ArrayLike

from steer_envs.baselines.bc.modeling import BCPolicy
from steer_envs.baselines.common.checkpoint import check_state, read_safetensors, write_safetensors
from steer_envs.core.validation import describe, integer, real_scalar
from steer_envs.io import CheckpointError

__all__ = ["LATEST_FILE", "RUN_FORMAT", "BCRun", "step_file", "train_run"]

#: the format tag of a run's state file (also part of :attr:`BCRun.key`)
RUN_FORMAT = "steer_envs.bc_run/1"
#: the safetensors metadata entry of a run's state
_META_KEY = "bc_run"
#: the periodically replaced state of a run folder
LATEST_FILE = "latest.safetensors"
_DAMAGED = "delete it: the run then continues from its previous saved state (or trains again from step 0)"


def step_file(step: int) -> str:
    """The name of the state kept at ``step`` in a run folder.

    >>> step_file(50_000)
    'step-00050000.safetensors'
    """
    return f"step-{integer(step, 'step', low=1):08d}.safetensors"


def _checked_losses(value: Any) -> list[list[float]]:
    """``value`` as ``[[step, loss], ...]``, steps increasing ints >= 1, losses finite; else an error."""
    if not isinstance(value, list):
        raise TypeError(f"'losses' must be a list of [step, loss] pairs, got {describe(value)}")
    out: list[list[float]] = []
    for item in value:
        if not (isinstance(item, list) and len(item) == 2):
            raise TypeError(f"'losses' entries must be [step, loss] pairs, got {item!r}")
        step = integer(item[0], "losses step", low=1 if not out else int(out[-1][0]) + 1)
        out.append([step, real_scalar(item[1], "losses value")])
    return out


def _digest(*tensors: torch.Tensor) -> str:
    h = hashlib.sha256()
    for t in tensors:
        arr = t.detach().cpu().contiguous().numpy()
        h.update(json.dumps([str(arr.dtype), list(arr.shape)]).encode())
        h.update(arr.tobytes())
    return h.hexdigest()


class BCRun:
    """One BC training run: a fresh :class:`BCPolicy` (configured with ``steps``), its data and its Adam optimiser.

    Args:
        policy: the untrained policy (its config's ``steps`` is the budget
            :func:`train_run` is usually asked for; the run itself stops where it is told).
        states, actions: the training pairs, as :meth:`BCPolicy.fit` takes them.
        log_every: the loss log holds the mean loss of every ``log_every`` steps.

    Attributes:
        step: the steps trained so far; losses: ``[[step, mean loss], ...]``;
        trained_from: the step of the last state loaded (0: none); steps_trained: the steps this object trained;
        key: the hex digest that names the run's folder (see the module).
    """

    def __init__(self, policy: BCPolicy, states: ArrayLike, actions: ArrayLike, *, log_every: int = 100) -> None:
        owner = "BCRun"
        if not isinstance(policy, BCPolicy):
            raise TypeError(f"{owner}: `policy` must be a BCPolicy, got {describe(policy)}")
        if policy.config.steps is None:
            raise ValueError(f"{owner}: the policy's config must train by `steps` (minibatches), not by epochs")
        if policy.trained_for:
            raise ValueError(f"{owner}: the policy must be untrained, it has trained for {policy.trained_for} steps")
        self.policy = policy
        self.log_every = integer(log_every, "log_every", low=1, owner=owner)
        self.x, self.y = policy.training_tensors(states, actions)
        self.optimizer = policy.new_optimizer()
        self.step = 0
        self.trained_from = 0
        self.steps_trained = 0
        self.losses: list[list[float]] = []
        self._running = 0.0
        config = {k: v for k, v in asdict(policy.config).items() if k != "steps"}
        identity = {
            "format": RUN_FORMAT,
            "config": config,
            "seed": policy.seed,
            "log_every": self.log_every,
            "data": _digest(self.x, self.y),
        }
        self.key = hashlib.sha256(json.dumps(identity, sort_keys=True).encode()).hexdigest()[:20]

    # ------------------------------------------------------------------ training
    def advance(self, until: int, *, save: Callable[[], object] | None = None, save_every: float = math.inf) -> None:
        """Train on from :attr:`step` through step ``until``; call ``save`` every ``save_every`` seconds on the way."""
        until = integer(until, "until", low=self.step, owner="BCRun.advance")
        save_every = real_scalar(save_every, "save_every", low=0.0, owner="BCRun.advance")
        policy, last = self.policy, time.monotonic()
        with policy.training():
            for step in range(self.step + 1, until + 1):
                self._running += policy.minibatch_step(self.optimizer, self.x, self.y)
                self.step = policy.trained_for = step
                self.steps_trained += 1
                if step % self.log_every == 0:
                    self.losses.append([step, self._running / self.log_every])
                    self._running = 0.0
                if save is not None and step < until and time.monotonic() - last >= save_every:
                    save()
                    last = time.monotonic()

    # --------------------------------------------------------------- persistence
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the run's state after :attr:`step` (>= 1) atomically, with its checksum; returns the path."""
        if self.step < 1:
            raise ValueError("BCRun.save: nothing to save before the first step")
        tensors = {f"net.{k}": v for k, v in self.policy.net.state_dict().items()}
        for index, entry in self.optimizer.state_dict()["state"].items():
            for name, value in entry.items():
                tensors[f"optim.{index}.{name}"] = value
        tensors["batch_generator"] = self.policy.batch_generator.get_state()
        if self.policy.input_mean is not None and self.policy.input_scale is not None:
            tensors["input_mean"] = torch.from_numpy(self.policy.input_mean)
            tensors["input_scale"] = torch.from_numpy(self.policy.input_scale)
        meta = {
            "format": RUN_FORMAT,
            "key": self.key,
            "config": asdict(self.policy.config),
            "seed": self.policy.seed,
            "step": self.step,
            "losses": self.losses,
            "running": self._running,
        }
        return write_safetensors(path, tensors, _META_KEY, meta)

    def _expected(self) -> dict[str, torch.Tensor]:
        """The tensors a state of this run holds (names, shapes, dtypes)."""
        expected = {f"net.{k}": v for k, v in self.policy.net.state_dict().items()}
        for i, p in enumerate(self.policy.net.parameters()):
            expected[f"optim.{i}.step"] = torch.empty((), dtype=torch.float32)
            expected[f"optim.{i}.exp_avg"] = torch.empty_like(p)
            expected[f"optim.{i}.exp_avg_sq"] = torch.empty_like(p)
        expected["batch_generator"] = self.policy.batch_generator.get_state()
        if self.policy.input_mean is not None:
            expected["input_mean"] = expected["input_scale"] = torch.empty(self.policy.config.state_dim)
        return expected

    def load(self, path: str | os.PathLike[str]) -> None:
        """Continue from the state in ``path`` (written by :meth:`save` for this run, at any step).

        :class:`~steer_envs.io.CheckpointError` naming the file when it is
        damaged, foreign, or the state of another run (another key), or its
        tensors do not fit; the run is unchanged then.
        """
        src = Path(path)
        tensors, meta = read_safetensors(src, _META_KEY, remedy=_DAMAGED)
        try:
            if meta.get("format") != RUN_FORMAT:
                raise ValueError(f"format {meta.get('format')!r}, expected {RUN_FORMAT!r}")
            if meta.get("key") != self.key:
                raise ValueError(f"it is the state of run {meta.get('key')!r}, not of this one ({self.key!r})")
            step = integer(meta["step"], "step", low=1)
            losses = _checked_losses(meta["losses"])
            running = real_scalar(meta["running"], "running")
            if losses and losses[-1][0] > step:
                raise ValueError(f"losses logged up to step {losses[-1][0]}, after the state's {step}")
        except (KeyError, TypeError, ValueError) as err:
            what = f"missing {err}" if isinstance(err, KeyError) else str(err)
            raise CheckpointError(f"{src}: not a state of this BC run ({what})") from None
        check_state(self._expected(), tensors, str(src))
        try:
            net = {k[len("net.") :]: v for k, v in tensors.items() if k.startswith("net.")}
            n = len(list(self.policy.net.parameters()))
            names = ("step", "exp_avg", "exp_avg_sq")
            state = {i: {name: tensors[f"optim.{i}.{name}"] for name in names} for i in range(n)}
            groups = self.optimizer.state_dict()["param_groups"]
            self.policy.net.load_state_dict(net)
            self.optimizer.load_state_dict({"state": state, "param_groups": groups})
            self.policy.batch_generator.set_state(tensors["batch_generator"])
        except (RuntimeError, ValueError) as err:
            raise CheckpointError(f"{src}: the state does not fit this run ({err})") from None
        if "input_mean" in tensors:
            self.policy.input_mean = tensors["input_mean"].numpy()
            self.policy.input_scale = tensors["input_scale"].numpy()
        self.step = self.trained_from = self.policy.trained_for = step
        self.losses, self._running = [[int(s), v] for s, v in losses], running

    @staticmethod
    def saved_step(path: str | os.PathLike[str]) -> int | None:
        """The step of the run state in ``path`` (``None`` when it cannot be read as one)."""
        try:
            _, meta = read_safetensors(path, _META_KEY, remedy=_DAMAGED)
            return integer(meta["step"], "step", low=1)
        except (CheckpointError, KeyError, TypeError, ValueError):
            return None


def train_run(
    run: BCRun,
    until: int,
    *,
    folder: str | os.PathLike[str] | None = None,
    keep: Sequence[int] = (),
    save_every: float = 120.0,
) -> dict[int, dict[str, torch.Tensor]]:
    """Bring ``run`` to step ``until`` (from the latest usable saved state in ``folder``); the weights at ``keep``.

    Returns step -> a copy of the network's weights (its ``state_dict``) at
    each step of ``keep`` and at ``until``. With ``folder`` (usually
    ``<cache>/<run.key>``), each of those steps' states is kept there
    (:func:`step_file`) and read instead of trained where it already is, the
    run starts from the largest saved step not beyond the next step it needs,
    and :data:`LATEST_FILE` is replaced every ``save_every`` seconds. A saved
    state that cannot be read (damaged, foreign) is skipped with the others
    still tried; the run then trains that stretch again.
    """
    until = integer(until, "until", low=1, owner="train_run")
    if not isinstance(keep, Sequence) or isinstance(keep, str):
        raise TypeError(f"train_run: `keep` must be a sequence of steps, got {describe(keep)}")
    targets = sorted({integer(k, "keep", low=1, high=until, owner="train_run") for k in keep} | {until})
    save_every = real_scalar(save_every, "save_every", low=0.0, owner="train_run")
    if run.step > targets[0]:
        raise ValueError(f"train_run: the run is at step {run.step}, past the first step asked for ({targets[0]})")
    out: dict[int, dict[str, torch.Tensor]] = {}
    root = None if folder is None else Path(folder)
    save = None if root is None else functools.partial(run.save, root / LATEST_FILE)
    for target in targets:
        if root is not None:
            _catch_up(run, root, target)
        if run.step < target:
            run.advance(target, save=save, save_every=save_every)
            if root is not None:
                run.save(root / step_file(target))
        out[target] = {k: v.detach().clone() for k, v in run.policy.net.state_dict().items()}
    return out


def _catch_up(run: BCRun, root: Path, target: int) -> None:
    """Load into ``run`` the saved state of the largest step in ``(run.step, target]`` that can be read."""
    candidates: list[tuple[int, Path]] = []
    if (root / step_file(target)).is_file():
        candidates.append((target, root / step_file(target)))
    else:
        for path in root.glob("step-*.safetensors"):
            digits = path.name[len("step-") : -len(".safetensors")]
            if digits.isdigit() and run.step < int(digits) <= target:
                candidates.append((int(digits), path))
        latest = root / LATEST_FILE
        step = BCRun.saved_step(latest) if latest.is_file() else None
        if step is not None and run.step < step <= target:
            candidates.append((step, latest))
    for _, path in sorted(candidates, reverse=True):
        try:
            run.load(path)
            return
        except CheckpointError:
            continue
