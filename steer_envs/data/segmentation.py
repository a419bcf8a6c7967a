"""Segmentation of demonstrations into modes by per-step mode labels, and one attractor per mode.

The one segmentation of the library: consecutive steps of a demonstration
with the same label form a segment (TLI appendix "Sensor-based Motion
Segmentation and Attractor Identification"); all segments of a mode are that
mode's training data, and the mode's attractor is the mean of the *last*
state of each of its segments (the transition states to the next mode; for a
demonstration's final segment, its final state).

Where the labels come from is the caller's choice: the env's sensors or the
recorded modes of a demonstration (TLI, LTL-DS), or a learned classifier
(GLiDE: :func:`~steer_envs.baselines.glide.modes.label_demonstrations`).
Per-step labels may be mode indices or names, boolean sensor rows
``(T, num_aps)``, or ``{ap: bool}`` dicts; with a :class:`TaskSpec` sensor
readings are mapped to the task's mode names (``task.mode_of``), otherwise
every distinct sensor state is its own mode (as in the appendix table).

>>> import numpy as np
>>> x = np.arange(10.0).reshape(5, 2)
>>> seg = segment_demonstrations([(x, [0, 0, 1, 1, 1])])
>>> seg.order, seg[1].attractor.tolist(), [len(s) for s in seg[0].segments]
((0, 1), [8.0, 9.0], [2])
"""

from __future__ import annotations

import itertools
from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import boolean, describe, integer, real_array

__all__ = ["ModeData", "ModeSegment", "Segmentation", "segment_demonstration", "segment_demonstrations"]


@dataclass(frozen=True)
class ModeSegment:
    """A maximal run of steps of one demonstration in one mode.

    Attributes:
        mode: the mode label (index, name, or tuple of true APs).
        demo: index of the demonstration.
        start, stop: the run is ``states[start:stop]`` of that demonstration.
        states: ``(T, d)`` the states of the run.
        velocities: ``(T, d)`` the matching velocities, or None.
    """

    mode: Hashable
    demo: int
    start: int
    stop: int
    states: np.ndarray
    velocities: np.ndarray | None = None

    @property
    def entry(self) -> np.ndarray:
        """First state of the run (where the mode was entered)."""
        return self.states[0]

    @property
    def last(self) -> np.ndarray:
        """Last state of the run (the last in-mode state)."""
        return self.states[-1]

    def __len__(self) -> int:
        return self.stop - self.start


@dataclass(frozen=True)
class ModeData:
    """Everything the demonstrations say about one mode."""

    mode: Hashable
    segments: tuple[ModeSegment, ...]
    attractor: np.ndarray  # (d,) mean of the segments' last states

    @property
    def last_states(self) -> np.ndarray:
        """``(n, d)`` last in-mode state of each segment."""
        return np.stack([s.last for s in self.segments])

    @property
    def entry_states(self) -> np.ndarray:
        """``(n, d)`` first state of each segment."""
        return np.stack([s.entry for s in self.segments])

    @property
    def states(self) -> list[np.ndarray]:
        """Each segment's states (a list of demonstrations for :meth:`LPVDS.fit`)."""
        return [s.states for s in self.segments]

    @property
    def velocities(self) -> list[np.ndarray]:
        """Each segment's velocities (raises if the demonstrations had none)."""
        if any(s.velocities is None for s in self.segments):
            raise ValueError(f"mode {self.mode!r}: the demonstrations were segmented without velocities")
        return [s.velocities for s in self.segments]  # type: ignore[misc]


@dataclass(frozen=True)
class Segmentation:
    """The modes found in a set of demonstrations, in order of first appearance."""

    modes: dict[Hashable, ModeData] = field(default_factory=dict)

    @property
    def order(self) -> tuple[Hashable, ...]:
        """The modes in order of first appearance."""
        return tuple(self.modes)

    @property
    def attractors(self) -> dict[Hashable, np.ndarray]:
        """``mode -> attractor``."""
        return {m: md.attractor for m, md in self.modes.items()}

    def __getitem__(self, mode: Hashable) -> ModeData:
        return self.modes[mode]

    def __len__(self) -> int:
        return len(self.modes)


def _labels(labels: object, n: int, task: TaskSpec | None) -> list[Hashable]:
    """Per-step hashable mode labels from any supported label format."""
    if isinstance(labels, np.ndarray) and labels.dtype == bool:
        if labels.ndim != 2 or len(labels) != n:
            raise ValueError(f"boolean sensor labels must have shape ({n}, num_aps), got {labels.shape}")
        if task is not None:
            if labels.shape[1] != len(task.sensors):
                raise ValueError(f"sensor rows have {labels.shape[1]} columns, task {task.name} has {task.sensors}")
            return [task.mode_of({ap: bool(v) for ap, v in zip(task.sensors, row, strict=True)}) for row in labels]
        return [tuple(bool(v) for v in row) for row in labels]
    if not isinstance(labels, Sequence | np.ndarray) or len(labels) != n:
        raise ValueError(f"labels must be a sequence of length {n} (one per state)")
    out: list[Hashable] = []
    for item in labels:
        if isinstance(item, Mapping):
            reading = {k: boolean(v, f"sensor reading {k!r}") for k, v in item.items()}
            out.append(task.mode_of(reading) if task is not None else tuple(sorted(k for k, v in reading.items() if v)))
            continue
        if isinstance(item, np.generic):
            item = item.item()
        if isinstance(item, float) and item != item:
            raise ValueError("labels must not be NaN")
        if isinstance(item, Hashable) and not isinstance(item, (bytes, complex)):
            out.append(item)
        else:
            raise TypeError(f"labels must be ints, strings, bool rows or dicts, got {describe(item)}")
    if task is not None:  # normalise indices and names to names
        out = [task.modes[task.mode_index(m)] if isinstance(m, int | str) else m for m in out]
    return out


def segment_demonstration(
    states: ArrayLike,
    labels: object,
    velocities: ArrayLike | None = None,
    *,
    demo: int = 0,
    task: TaskSpec | None = None,
    min_length: int = 1,
) -> list[ModeSegment]:
    """Split one demonstration ``(T, d)`` into runs of equal mode label.

    Args:
        states: ``(T, d)`` states.
        labels: per-step modes (ints/names), bool sensor rows ``(T, num_aps)`` or ``{ap: bool}`` dicts.
        velocities: optional ``(T, d)`` velocities carried into the segments.
        demo: index stored in the segments.
        task: map sensor readings to the task's modes (and indices to names).
        min_length: runs shorter than this (sensor chatter) are merged into the preceding run.

    >>> import numpy as np
    >>> [(s.mode, s.start, s.stop) for s in segment_demonstration(np.zeros((5, 2)), ["a", "a", "b", "a", "a"])]
    [('a', 0, 2), ('b', 2, 3), ('a', 3, 5)]
    >>> [(s.mode, s.start, s.stop) for s in segment_demonstration(np.zeros((5, 2)), [0, 0, 1, 0, 0], min_length=2)]
    [(0, 0, 5)]
    """
    x = real_array(states, "states")
    if x.ndim != 2 or len(x) == 0:
        raise ValueError(f"states must have shape (T>=1, d), got {x.shape}")
    v = None
    if velocities is not None:
        v = real_array(velocities, "velocities")
        if v.shape != x.shape:
            raise ValueError(f"velocities must be finite with the shape of states {x.shape}, got {v.shape}")
    min_length = integer(min_length, "min_length", low=1)
    lab = _labels(labels, len(x), task)
    bounds = [0] + [t for t in range(1, len(lab)) if lab[t] != lab[t - 1]] + [len(lab)]
    merged: list[tuple[Hashable, int, int]] = []
    for a, b in itertools.pairwise(bounds):
        if merged and (b - a < min_length or merged[-1][0] == lab[a]):
            merged[-1] = (merged[-1][0], merged[-1][1], b)  # chatter (or a run equal to the previous) extends it
        else:
            merged.append((lab[a], a, b))
    return [
        ModeSegment(mode=m, demo=demo, start=a, stop=b, states=x[a:b], velocities=None if v is None else v[a:b])
        for m, a, b in merged
    ]


def segment_demonstrations(
    demos: Sequence[tuple[ArrayLike, object] | tuple[ArrayLike, object, ArrayLike | None]],
    *,
    task: TaskSpec | None = None,
    min_length: int = 1,
) -> Segmentation:
    """Segment demonstrations ``[(states, labels[, velocities]), ...]`` and find each mode's attractor.

    ``labels`` as in :func:`segment_demonstration`; the modes are kept in order of first appearance.
    See the module docstring for an example.
    """
    if not isinstance(demos, Sequence) or len(demos) == 0:
        raise ValueError("demos must be a non-empty sequence of (states, labels[, velocities]) tuples")
    per_mode: dict[Hashable, list[ModeSegment]] = {}
    dims = set()
    for i, demo in enumerate(demos):
        if not isinstance(demo, tuple | list) or len(demo) not in (2, 3):
            raise TypeError(f"demos[{i}] must be a (states, labels[, velocities]) tuple")
        states, labels = demo[0], demo[1]
        vel = demo[2] if len(demo) == 3 else None
        for seg in segment_demonstration(states, labels, vel, demo=i, task=task, min_length=min_length):
            dims.add(seg.states.shape[1])
            per_mode.setdefault(seg.mode, []).append(seg)
    if len(dims) != 1:
        raise ValueError(f"all demonstrations must have the same state dimension, got {sorted(dims)}")
    modes = {
        m: ModeData(mode=m, segments=tuple(segs), attractor=np.mean([s.last for s in segs], axis=0))
        for m, segs in per_mode.items()
    }
    return Segmentation(modes=modes)
