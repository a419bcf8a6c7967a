"""Composable wrappers of steer-envs (installed as ``steer_envs.wrappers``).

* :class:`SteeringWrapper` - the action becomes a user interaction; a frozen
  policy plans and an ITPS sampler steers it (:mod:`~steer_envs.wrappers.samplers`).
* :class:`LTLReplanWrapper` - adds the LTL-planned next mode to the observation.
* :class:`DSModulationWrapper` - modulates velocity actions by cuts learned on
  invariance failures.

Every wrapper records its constructor arguments, so ``env.spec`` shows the
stack. Names are imported lazily, so ``from steer_envs.wrappers import
LTLReplanWrapper`` does not pay for torch (the ITPS samplers) or scipy (the DS cuts).

>>> import gymnasium as gym
>>> import steer_envs
>>> from steer_envs.wrappers import DSModulationWrapper, LTLReplanWrapper
>>> env = DSModulationWrapper(LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0")), attractor=[4.75, 5.99])
>>> [w.name for w in env.spec.additional_wrappers]
['LTLReplanWrapper', 'DSModulationWrapper']
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
    "ArmPerturbationWrapper": "arm_perturbation",
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
