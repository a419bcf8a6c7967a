"""Thread limits for small numeric work: BLAS/OpenMP pools and torch's intra-op threads.

Benchmark trials and small fits run one per core; extra threads inside each
only add contention. :func:`limit_threads` caps both kinds inside a block and
restores them after it.

>>> with single_threaded():
...     pass
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

__all__ = ["limit_threads", "single_threaded"]


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
        if torch_threads is not None:
            try:
                import torch
            except ImportError:  # pragma: no cover - torch is a core dependency
                pass
            else:
                previous = torch.get_num_threads()
                torch.set_num_threads(torch_threads)
                stack.callback(torch.set_num_threads, previous)
        if blas_threads is not None:
            from threadpoolctl import threadpool_limits

            stack.enter_context(threadpool_limits(limits=blas_threads))
        yield


def single_threaded() -> contextlib.AbstractContextManager[None]:
    """One BLAS thread and one torch intra-op thread inside the block (restored after).

    >>> import torch
    >>> with single_threaded():
    ...     torch.get_num_threads()
    1
    """
    return limit_threads(blas_threads=1, torch_threads=1)
