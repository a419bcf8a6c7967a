"""GLiDE training data: demonstrations plus perturbed replays labelled by task success.

Layout (one ``.npz`` file, written atomically). The unit of this data set is a
*labelled trajectory* (thesis: ``<tau_i, succ_i>``), of variable length, with a
few per-trajectory fields; there are no actions or rewards to learn from. So it
is stored ragged, as flat arrays plus offsets:

========================  ==============  ==================================================
key                       shape / dtype   meaning
========================  ==============  ==================================================
``states``                (S, d) float32  every trajectory's states, concatenated
``modes``                 (S,) int16      the env's ground-truth mode of each state
                                          (evaluation only; never used for training)
``offsets``               (n + 1,) int64  trajectory ``i`` is ``states[offsets[i]:offsets[i+1]]``
``success``               (n,) bool       the env's success check (the training label)
``kind``                  (n,) int8       index into ``KINDS``: demo, segment, kernel, gripper
``source``                (n,) int32      index of the demonstration it perturbs
``window``                (n, 2) int32    X, Y (segment) / s, e (kernel) indices in the demo
``target``                (n, d) float32  the random target Z (NaN for demos)
``violation_step``        (n,) int32      first invalid transition (-1 if none)
``meta``                  () str          JSON: env id, layout seed, seed, kinds, counts, version
========================  ==============  ==================================================

Why not Minari: Minari stores RL *episodes* (observations, actions, rewards,
terminations) of an env it can re-create from its spec, as HDF5 files that it
appends to in place under a data-set root. GLiDE's records are trajectories
with a single success label and perturbation metadata, a few MB in all; one
``np.load``-able file is simpler to ship, to cache per (env, layout, seed) and
to write atomically (temp file + ``os.replace``), so a killed benchmark never
leaves a half-written data set behind.
"""

from __future__ import annotations

import json
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import gymnasium as gym
import numpy as np

from steer_envs.core.progress import check_progress, progress_bar
from steer_envs.core.validation import integer, one_of
from steer_envs.data.counterfactual import EXECUTIONS, CounterfactualReplayer, Execution, Replay
from steer_envs.io import DatasetError, atomic_write_npz, npz_json, read_npz, require_arrays

KINDS: tuple[str, ...] = ("demo", "segment", "kernel", "gripper")
FORMAT_VERSION = 1


@dataclass(frozen=True)
class CounterfactualDataset:
    """Ragged labelled trajectories (see the module docstring for the layout)."""

    states: np.ndarray
    modes: np.ndarray
    offsets: np.ndarray
    success: np.ndarray
    kind: np.ndarray
    source: np.ndarray
    window: np.ndarray
    target: np.ndarray
    violation_step: np.ndarray
    meta: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = len(self.success)
        if self.states.ndim != 2:
            raise ValueError(f"states must be (S, d), got {self.states.shape}")
        if self.offsets.shape != (n + 1,) or self.offsets[0] != 0 or self.offsets[-1] != len(self.states):
            raise ValueError("offsets must have n + 1 entries from 0 to len(states)")
        if np.any(np.diff(self.offsets) < 1):
            raise ValueError("every trajectory must have at least one state")
        if self.modes.shape != (len(self.states),):
            raise ValueError(f"modes must have shape ({len(self.states)},), got {self.modes.shape}")
        for name in ("kind", "source", "violation_step"):
            if getattr(self, name).shape != (n,):
                raise ValueError(f"{name} must have shape ({n},), got {getattr(self, name).shape}")
        if self.window.shape != (n, 2) or self.target.shape != (n, self.states.shape[1]):
            raise ValueError("window must be (n, 2) and target (n, d)")

    # ------------------------------------------------------------- access
    def __len__(self) -> int:
        return len(self.success)

    @property
    def state_dim(self) -> int:
        return int(self.states.shape[1])

    def trajectory(self, i: int) -> np.ndarray:
        """States ``(T_i, d)`` of trajectory ``i``."""
        if not -len(self) <= i < len(self):
            raise IndexError(f"trajectory index {i} out of range for {len(self)} trajectories")
        i %= len(self)
        return self.states[self.offsets[i] : self.offsets[i + 1]]

    def trajectory_modes(self, i: int) -> np.ndarray:
        """Ground-truth modes ``(T_i,)`` of trajectory ``i`` (evaluation only)."""
        i %= len(self)
        return self.modes[self.offsets[i] : self.offsets[i + 1]]

    def trajectories(self) -> list[np.ndarray]:
        """All trajectories as a list of ``(T_i, d)`` arrays."""
        return [self.trajectory(i) for i in range(len(self))]

    @property
    def is_demo(self) -> np.ndarray:
        return self.kind == KINDS.index("demo")

    def subset(self, mask: np.ndarray) -> CounterfactualDataset:
        """The trajectories selected by a boolean mask or index array."""
        idx = np.arange(len(self))[np.asarray(mask)]
        parts = [np.arange(self.offsets[i], self.offsets[i + 1]) for i in idx]
        rows = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
        lengths = np.diff(self.offsets)[idx]
        return CounterfactualDataset(
            states=self.states[rows],
            modes=self.modes[rows],
            offsets=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
            success=self.success[idx],
            kind=self.kind[idx],
            source=self.source[idx],
            window=self.window[idx],
            target=self.target[idx],
            violation_step=self.violation_step[idx],
            meta=dict(self.meta),
        )

    # ---------------------------------------------------------- building
    @classmethod
    def from_replays(cls, replays: Sequence[Replay], meta: Mapping[str, Any] | None = None) -> CounterfactualDataset:
        """Pack replays (demos and perturbations) into the flat layout."""
        if len(replays) == 0:
            raise ValueError("replays must not be empty")
        states = np.concatenate([r.states for r in replays]).astype(np.float32)
        lengths = np.array([len(r.states) for r in replays])
        return cls(
            states=states,
            modes=np.concatenate([r.modes for r in replays]).astype(np.int16),
            offsets=np.concatenate([[0], np.cumsum(lengths)]).astype(np.int64),
            success=np.array([r.success for r in replays], dtype=bool),
            kind=np.array([KINDS.index(r.reference.kind) for r in replays], dtype=np.int8),
            source=np.array([r.reference.source for r in replays], dtype=np.int32),
            window=np.array([r.reference.window for r in replays], dtype=np.int32).reshape(-1, 2),
            target=np.array([r.reference.target for r in replays], dtype=np.float32).reshape(len(replays), -1),
            violation_step=np.array([r.violation_step for r in replays], dtype=np.int32),
            meta=dict(meta or {}),
        )

    # -------------------------------------------------------------- files
    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the data set to ``path`` (``.npz``) atomically (temp file + ``os.replace``)."""
        path = Path(path)
        if path.suffix != ".npz":
            raise ValueError(f"path must end in .npz, got {str(path)!r}")
        meta = {**dict(self.meta), "format_version": FORMAT_VERSION, "kinds": list(KINDS)}
        arrays = {name: getattr(self, name) for name in _SPECS}
        return atomic_write_npz(path, {**arrays, "meta": np.array(json.dumps(meta, sort_keys=True))})

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> CounterfactualDataset:
        """Read a data set written by :meth:`save` (no pickle).

        :class:`~steer_envs.io.DatasetError` (a ``ValueError``) naming the file
        when it is missing, not an ``.npz`` of plain arrays, of another format
        version, or holds arrays of the wrong dtype or shape, non-finite states,
        unknown kinds or inconsistent offsets.
        """
        src = Path(path)
        arrays = read_npz(src)
        missing = sorted((set(_SPECS) | {"meta"}) - set(arrays))
        if missing:
            raise DatasetError(f"{src} is not a GLiDE counterfactual dataset (missing {missing})")
        meta = npz_json(src, arrays, "meta")
        arrays.pop("meta")
        if meta.get("format_version") != FORMAT_VERSION:
            raise DatasetError(f"{src}: unsupported format_version {meta.get('format_version')!r}")
        unknown = sorted(set(arrays) - set(_SPECS))
        if unknown:
            raise DatasetError(f"{src}: unexpected arrays {unknown}")
        require_arrays(src, arrays, _SPECS)
        if not np.all(np.isfinite(arrays["states"])):
            raise DatasetError(f"{src}: 'states' holds NaN or infinite values")
        kind = arrays["kind"]
        if np.any((kind < 0) | (kind >= len(KINDS))):
            raise DatasetError(f"{src}: 'kind' holds values outside [0, {len(KINDS)})")
        try:
            return cls(**arrays, meta=meta)
        except (TypeError, ValueError, IndexError) as err:
            raise DatasetError(f"{src}: {err}") from None


#: array -> (dtype kinds, number of axes) of a saved data set
_SPECS: dict[str, tuple[str, int]] = {
    "states": ("f", 2),
    "modes": ("iu", 1),
    "offsets": ("iu", 1),
    "success": ("b", 1),
    "kind": ("iu", 1),
    "source": ("iu", 1),
    "window": ("iu", 2),
    "target": ("f", 2),
    "violation_step": ("iu", 1),
}


def build_counterfactual_dataset(
    env_id: str,
    demos: Sequence[np.ndarray],
    *,
    n_success: int = 500,
    n_failure: int = 500,
    kind: str | Sequence[str] | Mapping[str, float] = "segment",
    execution: str = "jump",
    seed: int = 0,
    batch_size: int = 512,
    max_replays: int = 50_000,
    max_episode_steps: int = 5000,
    progress: bool | None = False,
    **make_kwargs: Any,
) -> CounterfactualDataset:
    """Demos plus a balanced set of perturbed replays (``n_success`` + ``n_failure``).

    The env is made with ``terminate_on_violation=False`` so failed replays run
    to the end of the perturbed demo, like the thesis's trajectories (whose
    first and last states are the demo's), and with a step limit long enough
    for every detour. Replays are drawn in seeded batches until both quotas are
    filled (surplus of the more frequent outcome is dropped in draw order).
    The demos are replayed too (kind ``"demo"``) and must all succeed.
    ``make_kwargs`` go to ``gymnasium.make``. ``progress``: ``True`` a bar,
    ``None`` a bar only when stderr is a terminal, ``False`` (default) none.

    >>> from steer_envs.data.demos import collect_demonstrations
    >>> env_id = "steer_envs/PolygonNav-3Mode-v0"
    >>> demos = [d.states for d in collect_demonstrations(env_id, n=2, seed=0, layout_seed=0)]
    >>> data = build_counterfactual_dataset(env_id, demos, n_success=3, n_failure=3, batch_size=64, layout_seed=0)
    >>> len(data), int(data.is_demo.sum()), int(data.success[~data.is_demo].sum())
    (8, 2, 3)
    """
    owner = "build_counterfactual_dataset"
    if not isinstance(env_id, str):
        raise TypeError(f"{owner}: env_id must be a str, got {type(env_id).__name__}")
    n_success = integer(n_success, "n_success", low=0, owner=owner)
    n_failure = integer(n_failure, "n_failure", low=0, owner=owner)
    max_replays = integer(max_replays, "max_replays", low=1, owner=owner)
    batch_size = integer(batch_size, "batch_size", low=1, owner=owner)
    max_episode_steps = integer(max_episode_steps, "max_episode_steps", low=1, owner=owner)
    seed = integer(seed, "seed", low=0, owner=owner)
    progress = check_progress(progress, owner=owner)
    if isinstance(demos, (str, bytes)) or len(demos) == 0:
        raise ValueError(f"{owner}: demos must hold at least one demonstration")
    one_of(execution, "execution", EXECUTIONS, owner=owner)
    env = gym.make(env_id, terminate_on_violation=False, max_episode_steps=max_episode_steps, **make_kwargs)
    replayer = CounterfactualReplayer(env, kind, execution=cast(Execution, execution))
    try:
        demo_replays = _replay_demos(replayer, demos, env_id)
        draws = _Draws(n_success, n_failure, batch_size, max_replays)
        draws.fill(replayer, [r.states for r in demo_replays], np.random.default_rng(seed), progress, env_id)
    finally:
        env.close()
    meta = {
        "env_id": env_id,
        "make_kwargs": {k: v for k, v in make_kwargs.items() if isinstance(v, (int, float, str, bool))},
        **draws.meta(int(seed), replayer.kind_weights, execution, len(demo_replays)),
    }
    return CounterfactualDataset.from_replays([*demo_replays, *draws.succ, *draws.fail], meta)


def _replay_demos(replayer: CounterfactualReplayer, demos: Sequence[np.ndarray], env_id: str) -> list[Replay]:
    """The unperturbed replays of ``demos``; ``ValueError`` naming those that do not succeed."""
    demo_replays = replayer.replay_batch([replayer.unperturbed(d, source=i) for i, d in enumerate(demos)])
    failed = [i for i, r in enumerate(demo_replays) if not r.success]
    if failed:
        raise ValueError(f"demos {failed} do not succeed when replayed in {env_id}")
    return demo_replays


@dataclass
class _Draws:
    """Perturbed replays drawn until ``n_success`` successes and ``n_failure`` failures are kept."""

    n_success: int
    n_failure: int
    batch_size: int
    max_replays: int
    succ: list[Replay] = field(default_factory=list)
    fail: list[Replay] = field(default_factory=list)
    drawn: int = 0
    raw_success: int = 0
    raw_total: int = 0

    def fill(
        self,
        replayer: CounterfactualReplayer,
        paths: list[np.ndarray],
        rng: np.random.Generator,
        progress: bool | None,
        env_id: str,
    ) -> None:
        """Replay seeded batches of perturbed ``paths`` until both quotas are filled (``RuntimeError`` after
        ``max_replays``); the surplus of the more frequent outcome is dropped in draw order."""
        total = self.n_success + self.n_failure
        with progress_bar(total=total, enabled=progress, desc=f"counterfactuals {env_id}") as bar:
            while len(self.succ) < self.n_success or len(self.fail) < self.n_failure:
                if self.drawn >= self.max_replays:
                    raise RuntimeError(
                        f"only {len(self.succ)} successes / {len(self.fail)} failures after {self.drawn} replays "
                        f"(wanted {self.n_success} / {self.n_failure})"
                    )
                sources = rng.integers(0, len(paths), size=self.batch_size)
                refs = [replayer.sample(paths[s], rng, source=int(s)) for s in sources]
                self.drawn += len(refs)
                before = len(self.succ) + len(self.fail)
                for r in replayer.replay_batch(refs):
                    self.keep(r)
                bar.update(len(self.succ) + len(self.fail) - before)

    def meta(self, seed: int, kind: Any, execution: str, n_demos: int) -> dict[str, Any]:
        """The rest of a data set's metadata: the seed, perturbation kinds and execution, the counts of demos,
        kept outcomes and replays drawn, and the raw success rate."""
        return {
            "seed": seed,
            "kind": kind,
            "execution": execution,
            "n_demos": n_demos,
            "n_success": len(self.succ),
            "n_failure": len(self.fail),
            "replays_drawn": self.drawn,
            "raw_success_rate": self.raw_success / max(self.raw_total, 1),
        }

    def keep(self, r: Replay) -> None:
        """Count a finished replay and keep it while its outcome's quota is open (truncated ones are dropped)."""
        if r.truncated:
            return
        self.raw_total += 1
        self.raw_success += int(r.success)
        if r.success and len(self.succ) < self.n_success:
            self.succ.append(r)
        elif not r.success and len(self.fail) < self.n_failure:
            self.fail.append(r)


def cached_counterfactual_dataset(
    path: str | os.PathLike[str] | None, env_id: str, demos: Sequence[np.ndarray], **build_kwargs: Any
) -> CounterfactualDataset:
    """:func:`build_counterfactual_dataset`, kept in ``path`` (``.npz``; None: no file).

    An existing file is read instead of building; an unreadable one (a torn
    copy, a disk error) is a miss: rebuilt and overwritten, with a
    ``RuntimeWarning``. The caller chooses ``path`` so that it changes with
    every setting that changes the data.
    """
    file = None if path is None else Path(path)
    if file is not None and file.exists():
        try:
            return CounterfactualDataset.load(file)
        except DatasetError as err:  # a corrupt cache entry is a miss: rebuild and overwrite it
            warnings.warn(f"rebuilding the cached counterfactual data: {err}", RuntimeWarning, stacklevel=2)
    data = build_counterfactual_dataset(env_id, demos, **build_kwargs)
    if file is not None:
        data.save(file)
    return data


__all__ = ["KINDS", "CounterfactualDataset", "build_counterfactual_dataset", "cached_counterfactual_dataset"]
