"""An offscreen OpenGL backend that works on this machine, chosen before robosuite picks one that may not.

robosuite sets ``MUJOCO_GL=egl`` on Linux when nothing is set, and EGL fails
on machines without a GPU driver (a CPU-only server, a container): the arm
envs then die at their first render, inside a worker thread. When the user
has not chosen (``MUJOCO_GL`` unset), :func:`ensure_gl_backend` tries each
backend of :data:`CANDIDATES` in a short-lived subprocess (a failed GL
context can take its process down) and keeps the first that works the way
the envs are used: a context made in one thread and made current in another
(steer-ui renders from worker threads; an EGL context current in the thread
that made it refuses that), saying which on stderr. A backend the user set is
left alone.

>>> ensure_gl_backend() in CANDIDATES or os.environ["MUJOCO_GL"] != ""
True
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading

__all__ = ["CANDIDATES", "ensure_gl_backend"]

#: offscreen backends tried in order (EGL: GPU rendering; OSMesa: software, works anywhere libOSMesa is)
CANDIDATES: tuple[str, ...] = ("egl", "osmesa")
#: made in this thread, made current in another: how an env's renderer meets steer-ui's worker threads
_PROBE = """
import threading, mujoco
context = mujoco.GLContext(8, 8)
context.make_current()
failed = []
def other_thread():
    try:
        context.make_current()
    except Exception as exc:
        failed.append(exc)
thread = threading.Thread(target=other_thread)
thread.start()
thread.join()
raise SystemExit(1 if failed else 0)
"""
_LOCK = threading.Lock()


def _renders(backend: str) -> bool:
    env = {**os.environ, "MUJOCO_GL": backend, "PYOPENGL_PLATFORM": backend}
    try:
        done = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return done.returncode == 0


def ensure_gl_backend() -> str:
    """``MUJOCO_GL`` as set by the user, or the first of :data:`CANDIDATES` that renders (then set, with
    ``PYOPENGL_PLATFORM``); ``""`` when none does (robosuite's own choice then stands)."""
    with _LOCK:
        chosen = os.environ.get("MUJOCO_GL", "")
        if chosen:
            return chosen
        for backend in CANDIDATES:
            if _renders(backend):
                os.environ["MUJOCO_GL"] = backend
                os.environ.setdefault("PYOPENGL_PLATFORM", backend)
                print(f"steer-envs: MUJOCO_GL was unset; offscreen rendering uses {backend}", file=sys.stderr)
                return backend
        print(f"steer-envs: MUJOCO_GL is unset and none of {CANDIDATES} renders here", file=sys.stderr)
        return ""
