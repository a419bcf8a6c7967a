"""The denoiser's inference mode the UI runs a policy in, ``"auto"`` included (light: no torch import)."""

from __future__ import annotations

import importlib.util

from steer_envs.core.validation import one_of

__all__ = ["UI_ACCELERATIONS", "resolve_acceleration"]

#: the modes of :meth:`DiffusionPolicy.accelerate` and ``"auto"``.
UI_ACCELERATIONS: tuple[str, ...] = ("auto", "none", "trace", "compile", "onnx")


def resolve_acceleration(accelerate: str) -> str:
    """``"auto"``: ``"onnx"`` where ONNX Runtime is installed (the fastest on CPU), else ``"trace"``.

    Any other mode of :data:`UI_ACCELERATIONS` is returned as is; ``ValueError`` otherwise.
    """
    accelerate = one_of(accelerate, "accelerate", UI_ACCELERATIONS, owner="steer-ui")
    if accelerate != "auto":
        return accelerate
    found = all(importlib.util.find_spec(name) is not None for name in ("onnx", "onnxruntime"))
    return "onnx" if found else "trace"
