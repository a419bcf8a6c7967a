"""Which CPU this is: its model name and the instruction sets that decide how fast a network runs on it.

Inference speed on a CPU depends less on the clock than on the matrix
instructions: AMX (Intel Sapphire Rapids and later: bfloat16 and int8 tiles),
AVX-512 BF16 (bfloat16 dot products; AMD Zen 4 has it without AMX), VNNI
(int8 dot products, AVX-512 or AVX) and AVX2. Every timing the library reports
names the CPU with :func:`cpu_summary`, and the acceleration code picks a
precision from :func:`isa_features`.

>>> sorted(isa_features())
['amx', 'avx2', 'avx512_bf16', 'vnni']
>>> isinstance(cpu_summary(), str)
True
"""

from __future__ import annotations

import functools
import platform
from pathlib import Path

__all__ = ["cpu_name", "cpu_summary", "isa_features"]

#: feature -> the /proc/cpuinfo flags that mean it (any one of them)
_FLAGS: dict[str, tuple[str, ...]] = {
    "amx": ("amx_bf16", "amx_tile"),
    "avx512_bf16": ("avx512_bf16",),
    "vnni": ("avx512_vnni", "avx_vnni"),
    "avx2": ("avx2",),
}


def _cpuinfo() -> list[str]:
    try:
        return Path("/proc/cpuinfo").read_text().splitlines()
    except OSError:
        return []


@functools.cache
def cpu_name() -> str:
    """The CPU's model name (Linux ``/proc/cpuinfo``; else :func:`platform.processor`; ``"unknown"``)."""
    for line in _cpuinfo():
        if line.lower().startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor() or "unknown"


@functools.cache
def isa_features() -> dict[str, bool]:
    """``{"amx", "avx512_bf16", "vnni", "avx2"}`` -> whether the CPU has it (Linux; all ``False`` elsewhere)."""
    flags: set[str] = set()
    for line in _cpuinfo():
        if line.lower().startswith("flags"):
            flags = set(line.split(":", 1)[1].split())
            break
    return {feature: any(f in flags for f in names) for feature, names in _FLAGS.items()}


def cpu_summary() -> str:
    """``"<model name> (AMX no, AVX-512 BF16 yes, VNNI yes, AVX2 yes)"``: the line a timing is reported with."""
    labels = {"amx": "AMX", "avx512_bf16": "AVX-512 BF16", "vnni": "VNNI", "avx2": "AVX2"}
    features = ", ".join(f"{labels[k]} {'yes' if v else 'no'}" for k, v in isa_features().items())
    return f"{cpu_name()} ({features})"
