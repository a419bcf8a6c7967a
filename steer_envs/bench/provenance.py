"""Where a trial ran: package versions, git commit, host (stored with every record).

Versions are read from package metadata (``importlib.metadata``), so asking
for torch's version does not import torch. Computed once per process.

>>> sorted(host())
['cpus', 'hostname', 'pid']
"""

from __future__ import annotations

import functools
import importlib.metadata
import os
import platform
import socket
import subprocess
from pathlib import Path
from typing import Any

#: distributions whose versions every record carries (absent ones are omitted)
TRACKED_DISTRIBUTIONS: tuple[str, ...] = ("numpy", "gymnasium", "torch", "steer-envs")


def _dist_version(name: str) -> str | None:
    try:
        return importlib.metadata.version(name)
    except importlib.metadata.PackageNotFoundError:
        return None


@functools.cache
def git_commit() -> str | None:
    """Commit of the steer-envs checkout this code runs from (``None`` outside git)."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        out = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5, check=True
        )
    except (OSError, subprocess.SubprocessError):
        return None
    commit = out.stdout.strip()
    return commit or None


@functools.cache
def _versions() -> tuple[tuple[str, str | None], ...]:
    items: list[tuple[str, str | None]] = [("python", platform.python_version())]
    for dist in TRACKED_DISTRIBUTIONS:
        version = _dist_version(dist)
        if version is not None:
            items.append((dist.replace("-", "_"), version))
    items.append(("git_commit", git_commit()))
    return tuple(items)


def versions() -> dict[str, str | None]:
    """``{"python": ..., "numpy": ..., "gymnasium": ..., "torch": ..., "steer_envs": ..., "git_commit": ...}``.

    >>> import platform
    >>> versions()["python"] == platform.python_version()
    True
    """
    return dict(_versions())


def host() -> dict[str, Any]:
    """Host name, process id and CPU count of the process running a trial."""
    return {"hostname": socket.gethostname(), "pid": os.getpid(), "cpus": os.cpu_count()}
