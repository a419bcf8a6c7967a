"""User interactions ``z`` that steer a frozen policy (thesis §2.2).

Three validated, immutable value objects:

* :class:`Point` - a target state ``z`` of shape ``(d,)`` the trajectory should reach
  (e.g. a clicked pixel lifted to 3D through the depth buffer);
* :class:`Sketch` - a path ``(T, d)``, ``T >= 2``, the trajectory should follow;
* :class:`Nudge` - a physical correction: ``(k, d)`` states, ``k >= 1``, that overwrite
  the first ``k`` states of a plan.

Each stores its data as a read-only ``float64`` numpy array (one that cannot
be made writable again, so the object's hash is stable), validates on
construction (finite numbers, right rank, minimum length, optional expected
dimension ``dim``) and raises ``TypeError``/``ValueError`` naming the argument.
The classes import no torch; :meth:`as_tensor` imports it on demand.

>>> Point([1.0, 2.0]).target
array([1., 2.])
>>> Sketch([[0, 0], [1, 0], [1, 1]]).resample(5).points.shape
(5, 2)
>>> Nudge([[0.5, 0.5]], dim=2).k
1
>>> Sketch([[0.0, 0.0]])
Traceback (most recent call last):
...
ValueError: Sketch: `points` needs at least 2 entries along axis 0, got shape (1, 2)
"""

from __future__ import annotations

from typing import Any, ClassVar, Literal, Self, TypeAlias

import numpy as np

from steer_envs.core.validation import _from_tensor, _holds_bools, frozen_array, integer

InteractionKind = Literal["point", "sketch", "nudge"]


def as_finite_array(
    value: Any, *, name: str, ndim: int, min_len: int = 1, dim: int | None = None, owner: str | None = None
) -> np.ndarray:
    """Validate ``value`` as a finite real array of rank ``ndim``; return a read-only float64 copy.

    The copy cannot be made writable again (``setflags(write=True)`` raises), so
    value objects built on it keep their hash.

    Args:
        value: array-like of real numbers (lists, numpy arrays, torch tensors; a
            tensor that requires grad is read detached).
        name: argument name used in error messages.
        ndim: required rank (1 for a state, 2 for a sequence of states).
        min_len: minimum size of the first axis.
        dim: expected size of the last axis (the state dimension), if known.
        owner: optional prefix for error messages (e.g. the class being built).

    Raises:
        TypeError: non-numeric (also numeric strings such as ``"1"``), boolean, complex or object input.
        ValueError: ragged input, wrong rank, too short, wrong dimension, NaN/inf.
    """
    where = f"{owner}: " if owner else ""
    value = _from_tensor(value, f"{where}`{name}`")  # a torch tensor (also one that requires grad), read detached
    if isinstance(value, (str, bytes)):
        raise TypeError(f"{where}`{name}` must be an array of real numbers, got {type(value).__name__}")
    try:
        raw = np.asarray(value)
    except ValueError as exc:  # ragged nested sequences
        raise ValueError(f"{where}`{name}` must be a rectangular array of real numbers: {exc}") from None
    except (TypeError, RuntimeError):  # odd objects; a sequence of torch tensors that require grad
        raise TypeError(
            f"{where}`{name}` must be one array or tensor of real numbers, got {type(value).__name__}"
        ) from None
    if raw.dtype.kind not in "iuf" or (isinstance(value, (list, tuple)) and _holds_bools(value)):
        kind = raw.dtype if raw.dtype.kind not in "iuf" else "bool"  # numpy reads [1.0, True] as floats
        raise TypeError(f"{where}`{name}` must hold real numbers (int or float), got dtype {kind}")
    if raw.ndim != ndim:
        expected = "(d,)" if ndim == 1 else "(T, d)"
        raise ValueError(f"{where}`{name}` must have shape {expected} ({ndim}-D), got shape {raw.shape}")
    if raw.shape[0] < min_len:
        raise ValueError(f"{where}`{name}` needs at least {min_len} entries along axis 0, got shape {raw.shape}")
    if raw.shape[-1] < 1:
        raise ValueError(f"{where}`{name}` must have a state dimension >= 1, got shape {raw.shape}")
    if dim is not None and raw.shape[-1] != dim:
        raise ValueError(f"{where}`{name}` must have state dimension {dim}, got shape {raw.shape}")
    arr = np.array(raw, dtype=np.float64, copy=True)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{where}`{name}` must be finite (no NaN or inf)")
    return frozen_array(arr)


def resample_path(path: Any, n: int) -> np.ndarray:
    """Resample a ``(G, d)`` path to ``n`` points uniformly in *index* (as ITPS does).

    The new points sit at fractional indices ``linspace(0, G - 1, n)`` and are
    linearly interpolated between neighbouring path points, so the endpoints are
    kept and arc length is *not* equalised (a slowly drawn part of a sketch keeps
    more points). ``n == 1`` returns the first point.

    >>> resample_path([[0.0, 0.0], [2.0, 0.0]], 3)
    array([[0., 0.],
           [1., 0.],
           [2., 0.]])
    """
    pts = as_finite_array(path, name="path", ndim=2, min_len=1)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"`n` must be a positive integer, got {n!r}")
    g = pts.shape[0]
    idx = np.linspace(0.0, g - 1.0, int(n))
    lo = np.clip(np.floor(idx).astype(np.int64), 0, g - 1)
    hi = np.minimum(lo + 1, g - 1)
    frac = (idx - lo)[:, None]
    return (1.0 - frac) * pts[lo] + frac * pts[hi]


class _Interaction:
    """Shared behaviour: read-only array storage, immutability, equality, hashing, pickling."""

    __slots__ = ("_data",)
    _data: np.ndarray  # the slot: a read-only float64 array
    kind: ClassVar[InteractionKind]
    _name: ClassVar[str]  # constructor argument name, used in error messages
    _ndim: ClassVar[int]
    _min_len: ClassVar[int] = 1

    def __init__(self, data: Any, *, dim: int | None = None) -> None:
        if dim is not None and (isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim < 1):
            raise ValueError(f"{type(self).__name__}: `dim` must be a positive integer or None, got {dim!r}")
        arr = as_finite_array(
            data, name=self._name, ndim=self._ndim, min_len=self._min_len, dim=dim, owner=type(self).__name__
        )
        object.__setattr__(self, "_data", arr)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    def __delattr__(self, name: str) -> None:
        raise AttributeError(f"{type(self).__name__} is immutable")

    @property
    def array(self) -> np.ndarray:
        """The interaction's data as a read-only float64 array."""
        return self._data

    @property
    def dim(self) -> int:
        """State dimension ``d``."""
        return int(self._data.shape[-1])

    def validate(self, dim: int) -> Self:
        """Check the state dimension against an environment's (a positive int); return ``self``."""
        dim = integer(dim, "dim", low=1, owner=type(self).__name__)
        if self.dim != dim:
            raise ValueError(f"{type(self).__name__}: expected state dimension {dim}, got {self.dim}")
        return self

    def as_tensor(self, dtype: Any = None, device: Any = None) -> Any:
        """The data as a ``torch.Tensor`` (default dtype float64); imports torch lazily."""
        import torch

        return torch.as_tensor(np.array(self._data), dtype=dtype or torch.float64, device=device)

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self) or not isinstance(other, _Interaction):
            return NotImplemented
        return bool(np.array_equal(self._data, other._data))

    def __hash__(self) -> int:
        return hash((type(self).__name__, self._data.shape, self._data.tobytes()))

    def __reduce__(self) -> tuple[type[Self], tuple[np.ndarray]]:
        # Rebuild through the constructor so the copy is validated and read-only again.
        return type(self), (np.array(self._data),)

    def __repr__(self) -> str:
        if self._data.size <= 24:
            return f"{type(self).__name__}({self._name}={self._data.tolist()})"
        return f"{type(self).__name__}({self._name}=<array shape={self._data.shape}>)"


class Point(_Interaction):
    """A target state ``z`` of shape ``(d,)`` (thesis: point input).

    >>> Point([1.0, 2.0], dim=2)  # `dim` also checks the state dimension
    Point(target=[1.0, 2.0])
    """

    __slots__ = ()
    kind: ClassVar[InteractionKind] = "point"
    _name: ClassVar[str] = "target"
    _ndim: ClassVar[int] = 1

    def __init__(self, target: Any, *, dim: int | None = None) -> None:
        super().__init__(target, dim=dim)

    @property
    def target(self) -> np.ndarray:
        """The target state, shape ``(d,)``."""
        return self._data


class Sketch(_Interaction):
    """A path ``(T, d)`` with ``T >= 2`` the trajectory should follow (thesis: sketch input).

    >>> sketch = Sketch([[0.0, 0.0], [3.0, 4.0]])
    >>> len(sketch), sketch.arc_length()
    (2, 5.0)
    """

    __slots__ = ()
    kind: ClassVar[InteractionKind] = "sketch"
    _name: ClassVar[str] = "points"
    _ndim: ClassVar[int] = 2
    _min_len: ClassVar[int] = 2

    def __init__(self, points: Any, *, dim: int | None = None) -> None:
        super().__init__(points, dim=dim)

    @property
    def points(self) -> np.ndarray:
        """The path, shape ``(T, d)``."""
        return self._data

    def __len__(self) -> int:
        return int(self._data.shape[0])

    def resample(self, n: int) -> Sketch:
        """A new sketch of ``n >= 2`` points, uniform in index (see :func:`resample_path`)."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
            raise ValueError(f"`n` must be an integer >= 2 for a Sketch, got {n!r}")
        return Sketch(resample_path(self._data, int(n)))

    def arc_length(self) -> float:
        """Total polyline length of the sketch."""
        return float(np.linalg.norm(np.diff(self._data, axis=0), axis=1).sum())


class Nudge(_Interaction):
    """A physical correction: ``(k, d)`` states, ``k >= 1``, overwriting a plan's first ``k`` states.

    >>> Nudge([[0.0, 1.0], [0.0, 2.0]]).states[-1]
    array([0., 2.])
    """

    __slots__ = ()
    kind: ClassVar[InteractionKind] = "nudge"
    _name: ClassVar[str] = "states"
    _ndim: ClassVar[int] = 2

    def __init__(self, states: Any, *, dim: int | None = None) -> None:
        super().__init__(states, dim=dim)

    @property
    def states(self) -> np.ndarray:
        """The overwriting states, shape ``(k, d)``."""
        return self._data

    def __len__(self) -> int:
        return int(self._data.shape[0])

    @property
    def k(self) -> int:
        """Number of overwritten plan states."""
        return len(self)


Interaction: TypeAlias = Point | Sketch | Nudge

_KINDS: dict[str, type[Point] | type[Sketch] | type[Nudge]] = {"point": Point, "sketch": Sketch, "nudge": Nudge}


def make_interaction(kind: str, data: Any, *, dim: int | None = None) -> Interaction:
    """Build the interaction named ``kind`` ("point", "sketch", "nudge") from raw data.

    >>> make_interaction("sketch", [[0, 0], [1, 1]], dim=2)
    Sketch(points=[[0.0, 0.0], [1.0, 1.0]])
    """
    try:
        cls = _KINDS[kind]
    except (KeyError, TypeError):
        raise ValueError(f"`kind` must be one of {sorted(_KINDS)}, got {kind!r}") from None
    return cls(data, dim=dim)
