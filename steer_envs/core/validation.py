"""Argument validation shared by every public boundary (envs, wrappers, value objects, policies, loaders).

Each helper checks one kind of argument and raises ``TypeError`` (wrong kind:
a string where a number belongs, a complex number, a bool where an int
belongs) or ``ValueError`` (right kind, wrong value: NaN, out of range, wrong
shape), with a message naming the argument, what was expected and what came.
Nothing is coerced silently: strings are never parsed as numbers, complex
numbers never lose their imaginary part, ``"no"`` is not a boolean.

>>> real_scalar(0.5, "guide_ratio", low=0.0, high=1.0)
0.5
>>> real_scalar("0.5", "guide_ratio")
Traceback (most recent call last):
TypeError: guide_ratio must be a real number, got str '0.5'
>>> real_array([[0, 1], [2, 3]], "sketch", shape=(-1, 2)).shape
(2, 2)
>>> boolean("no", "render")
Traceback (most recent call last):
TypeError: render must be a bool, got str 'no'
"""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Collection, Mapping, Sequence
from typing import Any, TypeVar

import numpy as np

__all__ = [
    "BoundExceeded",
    "bool_array",
    "boolean",
    "describe",
    "frozen_array",
    "integer",
    "name_tuple",
    "one_of",
    "real_array",
    "real_scalar",
    "sensor_reading",
]

T = TypeVar("T")

_repr = reprlib.Repr()
_repr.maxstring = 60
_repr.maxother = 60
_repr.maxlist = 6
_repr.maxtuple = 6


class BoundExceeded(RuntimeError):
    """A loop that waits on the world (a replay, a rollout, a planner) hit its bound; the message names the bound.

    >>> raise BoundExceeded("replay: waypoint 3 not reached within max_steps=200")
    Traceback (most recent call last):
    steer_envs.core.validation.BoundExceeded: replay: waypoint 3 not reached within max_steps=200
    """


def describe(value: Any) -> str:
    """A short description of ``value`` for error messages: its type and a truncated repr.

    >>> describe("abc")
    "str 'abc'"
    >>> describe(list(range(100)))
    'list [0, 1, 2, 3, 4, 5, ...]'
    """
    return f"{type(value).__name__} {_repr.repr(value)}"


def _where(name: str, owner: str | None) -> str:
    return f"{owner}: {name}" if owner else name


def _is_real_number(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def real_scalar(
    value: Any,
    name: str,
    *,
    low: float | None = None,
    high: float | None = None,
    low_inclusive: bool = True,
    high_inclusive: bool = True,
    finite: bool = True,
    owner: str | None = None,
) -> float:
    """``value`` as a float: a real number (int, float, numpy scalar, not a bool), optionally within bounds.

    >>> real_scalar(3, "dt", low=0.0, low_inclusive=False)
    3.0
    >>> real_scalar(float("nan"), "dt")
    Traceback (most recent call last):
    ValueError: dt must be a finite real number, got float nan
    """
    where = _where(name, owner)
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if not _is_real_number(value):
        raise TypeError(f"{where} must be a real number, got {describe(value)}")
    try:
        out = float(value)  # an int becomes its nearest float
    except OverflowError:
        raise ValueError(f"{where} is too large for a float, got {describe(value)}") from None
    if finite and not math.isfinite(out):
        raise ValueError(f"{where} must be a finite real number, got {describe(value)}")
    if math.isnan(out):
        raise ValueError(f"{where} must not be NaN")
    too_low = low is not None and (out < low if low_inclusive else out <= low)
    too_high = high is not None and (out > high if high_inclusive else out >= high)
    if too_low or too_high:
        left = "[" if low_inclusive else "("
        right = "]" if high_inclusive else ")"
        span = f"{left}{'-inf' if low is None else low}, {'inf' if high is None else high}{right}"
        raise ValueError(f"{where} must be in {span}, got {out!r}")
    return out


def integer(value: Any, name: str, *, low: int | None = None, high: int | None = None, owner: str | None = None) -> int:
    """``value`` as an int: a Python or numpy integer (not a bool, not a float), optionally within ``[low, high]``.

    >>> integer(5, "n_starts", low=1)
    5
    >>> integer(2.0, "n_starts")
    Traceback (most recent call last):
    TypeError: n_starts must be an int, got float 2.0
    """
    where = _where(name, owner)
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if not isinstance(value, numbers.Integral) or isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{where} must be an int, got {describe(value)}")
    out = int(value)
    if (low is not None and out < low) or (high is not None and out > high):
        span = f"[{'-inf' if low is None else low}, {'inf' if high is None else high}]"
        raise ValueError(f"{where} must be an int in {span}, got {out}")
    return out


def boolean(value: Any, name: str, *, owner: str | None = None) -> bool:
    """``value`` as a bool: ``True``/``False`` (or a numpy bool) only; strings and numbers are refused.

    >>> boolean(np.bool_(True), "perturbed")
    True
    """
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{_where(name, owner)} must be a bool, got {describe(value)}")
    return bool(value)


def one_of(value: T, name: str, choices: Collection[T], *, owner: str | None = None) -> T:
    """``value`` if it is one of ``choices``; ``ValueError`` listing them otherwise.

    >>> one_of("SS", "sampler", ("RS", "SS"))
    'SS'
    >>> one_of("XX", "sampler", ("RS", "SS"))
    Traceback (most recent call last):
    ValueError: sampler must be one of ['RS', 'SS'], got str 'XX'
    """
    try:
        ok = value in choices
    except TypeError:  # unhashable value tested against a set
        ok = False
    if not ok:
        raise ValueError(f"{_where(name, owner)} must be one of {sorted(map(str, choices))}, got {describe(value)}")
    return value


def name_tuple(
    value: Any, name: str, *, owner: str | None = None, what: str = "names", ordered: bool = True, empty: bool = False
) -> tuple[str, ...]:
    """``value`` as a tuple of str ``what`` (e.g. mode names); ``TypeError`` naming the argument otherwise.

    A single str is refused (it is not a tuple of its characters), and with
    ``ordered`` so are mappings and sets (their order is not the caller's);
    ``empty`` lets ``""`` through.

    >>> name_tuple(["a", "b"], "modes", owner="TaskSpec")
    ('a', 'b')
    >>> name_tuple("ab", "modes", owner="TaskSpec")
    Traceback (most recent call last):
    TypeError: TaskSpec: modes must be a tuple of names, got str 'ab'
    """
    where = _where(name, owner)
    refused = (str, bytes, Mapping, set, frozenset) if ordered else (str, bytes)
    try:
        if isinstance(value, refused):
            raise TypeError
        items = tuple(value)
    except TypeError:
        raise TypeError(f"{where} must be a tuple of {what}, got {describe(value)}") from None
    for item in items:
        if not isinstance(item, str) or not (item or empty):
            kind = "str" if empty else "non-empty str"
            raise TypeError(f"{where} must hold {kind} {what}, got {describe(item)}")
    return items


def _raw_array(value: Any, where: str, what: str) -> tuple[Any, np.ndarray]:
    """``value`` (a tensor read as numpy) and ``np.asarray`` of it, refusing what cannot be an array of ``what``."""
    original = value
    value = _from_tensor(value, where)
    if value is None or isinstance(value, (str, bytes, dict, set)):
        raise TypeError(f"{where} must be an array of {what}, got {describe(original)}")
    try:
        return value, np.asarray(value)
    except (ValueError, TypeError) as exc:  # ragged nested sequences, odd objects
        raise ValueError(f"{where} must be a rectangular array of {what} ({exc}), got {describe(original)}") from None
    except RuntimeError:  # a sequence of torch tensors that require grad
        raise TypeError(f"{where} must be one array or tensor of {what}, got {describe(original)}") from None


def real_array(
    value: Any,
    name: str,
    *,
    shape: Sequence[int] | None = None,
    ndim: int | None = None,
    finite: bool = True,
    max_size: int | None = None,
    owner: str | None = None,
    readonly: bool = False,
) -> np.ndarray:
    """``value`` as a new float64 array of real numbers, checked before anything is converted.

    Accepts nested sequences, numpy arrays and torch tensors (detached, moved
    to the CPU, so a tensor that requires grad is read, never differentiated
    through). Refuses strings (also inside a sequence), complex numbers,
    booleans, objects, ragged input, NaN/inf (unless ``finite=False``) and
    arrays larger than ``max_size``. ``shape`` may use ``-1`` for "any
    length" on an axis. ``readonly=True`` returns an array that cannot be
    written, nor made writable again (see :func:`frozen_array`; for value
    objects that are hashed).

    >>> real_array((1, 2), "delta", shape=(2,))
    array([1., 2.])
    >>> real_array(["1", "2"], "action", shape=(2,))
    Traceback (most recent call last):
    TypeError: action must hold real numbers, got dtype <U1 (list ['1', '2'])
    >>> real_array([1 + 2j, 0], "action")
    Traceback (most recent call last):
    TypeError: action must hold real numbers, got dtype complex128 (list [(1+2j), 0])
    """
    where = _where(name, owner)
    original = value
    value, raw = _raw_array(value, where, "real numbers")
    if raw.dtype.kind not in "iuf" or (isinstance(value, (list, tuple)) and _holds_bools(value)):
        kind = raw.dtype if raw.dtype.kind not in "iuf" else "bool"  # numpy reads [1.0, True] as floats
        raise TypeError(f"{where} must hold real numbers, got dtype {kind} ({describe(original)})")
    if max_size is not None and raw.size > max_size:
        raise ValueError(f"{where} may hold at most {max_size} numbers, got shape {raw.shape}")
    if ndim is not None and raw.ndim != ndim:
        raise ValueError(f"{where} must be {ndim}-D, got shape {raw.shape}")
    if shape is not None:
        _check_shape(raw, tuple(shape), where)
    arr = np.array(raw, dtype=np.float64, copy=True)
    if finite and not np.all(np.isfinite(arr)):
        raise ValueError(f"{where} must be finite (no NaN or inf)")
    return frozen_array(arr) if readonly else arr


def bool_array(value: Any, name: str, *, shape: Sequence[int] | None = None, owner: str | None = None) -> np.ndarray:
    """``value`` as a new bool array: ``True``/``False`` entries only (Python or numpy bools).

    Numbers (``0``/``1``), strings (``"no"``) and objects are refused, so a
    mask can never be read from something that merely looks true. ``shape``
    may use ``-1`` for "any length" on an axis.

    >>> bool_array([True, False], "mask", shape=(2,))
    array([ True, False])
    >>> bool_array([1, 0], "mask")
    Traceback (most recent call last):
    TypeError: mask must hold bools (True/False), got dtype int64 (list [1, 0])
    """
    where = _where(name, owner)
    original = value
    _, raw = _raw_array(value, where, "bools")
    if raw.dtype.kind != "b":
        raise TypeError(f"{where} must hold bools (True/False), got dtype {raw.dtype} ({describe(original)})")
    if shape is not None:
        _check_shape(raw, tuple(shape), where)
    return np.array(raw, dtype=bool, copy=True)


def sensor_reading(info: Any, sensors: Sequence[str], *, owner: str) -> dict[str, bool]:
    """``info["sensors"]`` checked as a reading of exactly the APs ``sensors``, each a real bool.

    Sensor values must be ``True``/``False`` (Python or numpy bools): the string
    ``"False"``, a NaN or a number is a ``TypeError``, not a silent ``True``; a
    missing or extra AP is a ``ValueError``; no ``info["sensors"]`` is a ``KeyError``.

    >>> sensor_reading({"sensors": {"r": False, "s": np.bool_(True)}}, ("r", "s"), owner="demo")
    {'r': False, 's': True}
    >>> sensor_reading({"sensors": {"r": "False", "s": True}}, ("r", "s"), owner="demo")
    Traceback (most recent call last):
    TypeError: demo: info['sensors']['r'] must be a bool, got str 'False'
    """
    if not isinstance(info, Mapping) or "sensors" not in info:
        raise KeyError(f"{owner} needs info['sensors'] (AP -> bool) from the wrapped env")
    raw = info["sensors"]
    if not isinstance(raw, Mapping):
        raise TypeError(f"{owner}: info['sensors'] must be a mapping AP -> bool, got {describe(raw)}")
    missing = [ap for ap in sensors if ap not in raw]
    extra = sorted(str(k) for k in raw if k not in sensors)
    if missing or extra:
        raise ValueError(
            f"{owner}: info['sensors'] must hold exactly the APs {list(sensors)}; missing {missing}, unknown {extra}"
        )
    return {ap: boolean(raw[ap], f"info['sensors'][{ap!r}]", owner=owner) for ap in sensors}


def frozen_array(arr: np.ndarray) -> np.ndarray:
    """A read-only copy of ``arr`` that cannot be made writable again (``setflags(write=True)`` fails).

    The copy's memory is an immutable ``bytes`` object, so value objects that
    hash their array keep a stable hash.

    >>> a = frozen_array(np.arange(3.0))
    >>> a.flags.writeable
    False
    >>> a.setflags(write=True)
    Traceback (most recent call last):
    ValueError: cannot set WRITEABLE flag to True of this array
    """
    src = np.ascontiguousarray(arr)
    return np.frombuffer(src.tobytes(), dtype=src.dtype).reshape(src.shape)


def _from_tensor(value: Any, where: str) -> Any:
    """A torch tensor as a numpy array (detached, on the CPU; ``requires_grad`` is fine); other values unchanged."""
    if not (hasattr(value, "detach") and callable(value.detach) and hasattr(value, "cpu")):
        return value
    tensor = value.detach().cpu()
    if callable(getattr(tensor, "is_complex", None)) and tensor.is_complex():
        raise TypeError(f"{where} must hold real numbers, got a complex tensor ({tensor.dtype})")
    try:
        return tensor.numpy()
    except TypeError:  # float dtypes numpy lacks (bfloat16): widen, the values are exact in float64
        return tensor.double().numpy()


def _holds_bools(value: list[Any] | tuple[Any, ...]) -> bool:
    """Whether a nested list/tuple holds a bool anywhere (``np.asarray`` would silently read it as 0/1)."""
    stack: list[Any] = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, (bool, np.bool_)):
            return True
        if isinstance(item, (list, tuple)):
            stack.extend(item)
        elif isinstance(item, np.ndarray) and item.dtype.kind == "b":
            return True
    return False


def _check_shape(raw: np.ndarray, shape: tuple[int, ...], where: str) -> None:
    if raw.ndim != len(shape) or any(want not in (-1, got) for want, got in zip(shape, raw.shape, strict=True)):
        wanted = "(" + ", ".join("N" if s == -1 else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ValueError(f"{where} must have shape {wanted}, got {raw.shape}")
