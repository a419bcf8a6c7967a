"""Thread limits for small numeric work: BLAS/OpenMP pools and torch's intra-op threads.

Benchmark trials and small fits run one per core; extra threads inside each
only add contention. :func:`limit_threads` caps both kinds inside a block and
restores them after it; a script or CLI calls :func:`set_process_threads`
once (its ``--threads`` option comes from :func:`add_threads_argument`,
default 1). See ``docs/threads.md`` for why one thread is the default.

>>> with single_threaded():
...     pass
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from typing import Any

__all__ = ["add_threads_argument", "limit_threads", "set_process_threads", "single_threaded"]

#: the most threads ``--threads`` accepts (more than any machine this runs on has cores)
MAX_THREADS = 1024

# keeps the BLAS limit of set_process_threads alive (threadpoolctl restores it when collected)
_process_limits: list[Any] = []


def _check(name: str, value: int | None) -> None:
    if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 1):
        raise ValueError(f"{name} must be a positive int or None (leave as is), got {value!r}")


@contextlib.contextmanager
def limit_threads(blas_threads: int | None = 1, torch_threads: int | None = 1) -> Iterator[None]:
    """At most ``blas_threads`` BLAS/OpenMP threads and ``torch_threads`` torch threads inside the block.

    ``None`` leaves that kind as it is. The previous settings are restored on exit.

    >>> import torch
    >>> before = torch.get_num_threads()
    >>> with limit_threads(blas_threads=None, torch_threads=1):
    ...     torch.get_num_threads()
    1
    >>> torch.get_num_threads() == before
    True
    """
    _check("blas_threads", blas_threads)
    _check("torch_threads", torch_threads)
    with contextlib.ExitStack() as stack:
        # BLAS first: threadpoolctl's OpenMP limit also sets torch's intra-op threads (torch runs on OpenMP)
        if blas_threads is not None:
            from threadpoolctl import threadpool_limits

            stack.enter_context(threadpool_limits(limits=blas_threads))
        if torch_threads is not None:
            try:
                import torch
            except ImportError:  # pragma: no cover - torch is a core dependency
                pass
            else:
                previous = torch.get_num_threads()
                torch.set_num_threads(torch_threads)
                stack.callback(torch.set_num_threads, previous)
        yield


def single_threaded() -> contextlib.AbstractContextManager[None]:
    """One BLAS thread and one torch intra-op thread inside the block (restored after).

    >>> import torch
    >>> with single_threaded():
    ...     torch.get_num_threads()
    1
    """
    return limit_threads(blas_threads=1, torch_threads=1)


def set_process_threads(threads: int = 1) -> None:
    """At most ``threads`` torch intra-op and BLAS/OpenMP threads for the rest of this process.

    For scripts and CLIs (the library's own calls use :func:`limit_threads`).
    ``threads`` is a positive int (``ValueError`` otherwise).

    >>> import torch
    >>> before = torch.get_num_threads()
    >>> set_process_threads(1); torch.get_num_threads()
    1
    >>> set_process_threads(before)
    """
    _check("threads", threads)
    if threads is None:  # pragma: no cover - _check refuses None only through the type
        raise ValueError("threads must be a positive int")
    import torch
    from threadpoolctl import threadpool_limits

    torch.set_num_threads(threads)
    _process_limits[:] = [threadpool_limits(limits=threads)]


def _positive_threads(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a positive int, got {text!r}") from None
    if not 1 <= value <= MAX_THREADS:
        raise argparse.ArgumentTypeError(f"must be an int in [1, {MAX_THREADS}], got {value}")
    return value


def add_threads_argument(parser: argparse.ArgumentParser, default: int = 1) -> None:
    """Add ``--threads N`` (torch and BLAS threads, default ``default``) to a command-line ``parser``.

    >>> parser = argparse.ArgumentParser()
    >>> add_threads_argument(parser)
    >>> parser.parse_args([]).threads, parser.parse_args(["--threads", "2"]).threads
    (1, 2)
    """
    _check("default", default)
    parser.add_argument(
        "--threads",
        type=_positive_threads,
        default=default,
        help=f"torch and BLAS threads (default {default}: on a busy machine more threads are often slower; "
        "see docs/threads.md)",
    )
