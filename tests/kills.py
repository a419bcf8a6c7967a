"""Killing a writer mid-write: what the tests of the atomic writers share."""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Callable
from typing import Any

#: child processes are forked (they inherit the test's objects and monkeypatches)
FORK = multiprocessing.get_context("fork")


def kill_mid_write(write: Callable[[Callable[[], None]], Any], *, at_fsync: bool = True) -> None:
    """Run ``write(pause)`` in a forked child and SIGKILL it where it calls ``pause()``.

    With ``at_fsync`` the child's first ``os.fsync`` pauses too: all data written, not yet renamed.
    """
    started = FORK.Event()

    def pause(*_: Any) -> None:
        started.set()
        time.sleep(60)

    def child() -> None:
        if at_fsync:
            os.fsync = pause  # type: ignore[assignment]
        write(pause)
        os._exit(3)  # not reached when the kill comes first

    proc = FORK.Process(target=child)
    proc.start()
    try:
        assert started.wait(60), "the child never reached the write"
    finally:
        proc.kill()
        proc.join()
    assert proc.exitcode == -9
