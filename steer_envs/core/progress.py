"""Progress bars: the one place the library builds a tqdm bar, quiet in logs unless asked for.

Every long loop of steer-envs (the ``steer-bench`` runner, the data
generators, GLiDE's classifier training) draws its bar through
:func:`progress_bar`. Its ``enabled`` is three-valued, like the ``progress``
arguments and command-line options that feed it:

* ``None`` (auto): a bar only when stderr is a terminal (tqdm's
  ``disable=None``); a log file, a CI job or a pipe gets none, and a Jupyter
  notebook gets its widget. The default wherever a bar is on by default.
* ``True``: a bar wherever stderr goes, a log included (the user asked for it:
  ``progress=True``, ``--progress``).
* ``False``: no bar (``progress=False``, ``--no-progress``).

A hidden bar is still a tqdm object (``bar.disable`` is True; ``update``,
``set_postfix`` and ``close`` do nothing; ``tqdm.write`` still prints), so
callers need no ``if bar is not None``.

>>> bar = progress_bar(total=3, enabled=False, desc="demo")
>>> bar.disable, [x for x in progress_bar(range(3), enabled=False)]
(True, [0, 1, 2])
>>> progress_bar(total=3, enabled="yes")
Traceback (most recent call last):
TypeError: progress_bar: enabled must be True, False or None (auto: a bar only on a terminal), got str 'yes'
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np

from steer_envs.core.validation import describe

__all__ = ["check_progress", "progress_bar"]


def check_progress(value: Any, name: str = "progress", *, owner: str | None = None) -> bool | None:
    """``value`` as a ``progress`` setting: ``True``, ``False`` or ``None`` (auto); ``TypeError`` otherwise.

    >>> check_progress(None), check_progress(False)
    (None, False)
    >>> check_progress(1, owner="run_suite")
    Traceback (most recent call last):
    TypeError: run_suite: progress must be True, False or None (auto: a bar only on a terminal), got int 1
    """
    if value is None:
        return None
    if not isinstance(value, (bool, np.bool_)):
        where = f"{owner}: {name}" if owner else name
        raise TypeError(f"{where} must be True, False or None (auto: a bar only on a terminal), got {describe(value)}")
    return bool(value)


def progress_bar(iterable: Iterable[Any] | None = None, *, enabled: bool | None = None, **kwargs: Any) -> Any:
    """A ``tqdm.auto`` bar over ``iterable`` (or with ``total=...``), shown as ``enabled`` says (see the module).

    ``kwargs`` go to tqdm (``total``, ``desc``, ``unit``, ``leave``, ...); the
    bar writes to stderr unless ``file`` says otherwise.
    """
    enabled = check_progress(enabled, "enabled", owner="progress_bar")
    from tqdm.auto import tqdm

    return tqdm(iterable, disable=None if enabled is None else not enabled, **kwargs)
