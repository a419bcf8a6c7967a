"""Composable wrappers of steer-envs (installed as ``steer_envs.wrappers``).

Names are imported lazily, so ``from steer_envs.wrappers import LTLReplanWrapper``
does not pay for torch (the ITPS samplers) or cvxpy (the DS cuts).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS: dict[str, str] = {
    # ITPS steering
    "SteeringWrapper": "steering",
    "Sampler": "samplers",
    "SteeringResult": "samplers",
    "RandomSampling": "samplers",
    "PostHocRanking": "samplers",
    "OutputPerturbation": "samplers",
    "BiasedInitialization": "samplers",
    "GuidedDiffusion": "samplers",
    "StochasticSampling": "samplers",
    "make_sampler": "samplers",
    "benchmark_latency": "samplers",
    # LTL replanning
    "LTLReplanWrapper": "ltl_replan",
    # DS modulation
    "DSModulationWrapper": "ds_modulation",
    "ModulatedPolicy": "ds_modulation",
    "Cut": "ds_modulation",
    "CutSet": "ds_modulation",
    "solve_cut": "ds_modulation",
    "modulate": "ds_modulation",
    # GLiDE counterfactual perturbations
    "CounterfactualPerturbationWrapper": "counterfactual",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
