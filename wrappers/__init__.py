"""Composable wrappers of steer-envs (installed as ``steer_envs.wrappers``).

* :class:`SteeringWrapper` - the action becomes a user interaction; a frozen
  policy plans and an ITPS sampler (:mod:`steer_envs.steering`) steers it.
* :class:`LTLReplanWrapper` - adds the LTL-planned next mode to the observation.
* :class:`DSModulationWrapper` - modulates velocity actions by cuts learned on
  invariance failures (an adapter over :mod:`steer_envs.baselines.lpv_ds.cuts`
  and :mod:`~steer_envs.baselines.lpv_ds.modulation`).

Every wrapper records its constructor arguments, so ``env.spec`` shows the
stack. Names are imported lazily, so ``from steer_envs.wrappers import
LTLReplanWrapper`` does not pay for torch (the ITPS samplers) or the LPV-DS stack (the DS cuts).

>>> import gymnasium as gym
>>> import steer_envs
>>> from steer_envs.wrappers import DSModulationWrapper, LTLReplanWrapper
>>> env = DSModulationWrapper(LTLReplanWrapper(gym.make("steer_envs/SoupScoop-v0")), attractor=[4.75, 5.99])
>>> [w.name for w in env.spec.additional_wrappers]
['LTLReplanWrapper', 'DSModulationWrapper']
"""

from __future__ import annotations

from steer_envs.core.lazy import lazy_exports

_EXPORTS: dict[str, str] = {
    # ITPS steering
    "SteeringWrapper": "steering",
    # LTL replanning
    "LTLReplanWrapper": "ltl_replan",
    # DS modulation (the cuts and the modulation themselves: steer_envs.baselines.lpv_ds)
    "DSModulationWrapper": "ds_modulation",
    "ArmPerturbationWrapper": "arm_perturbation",
}

__all__ = sorted(_EXPORTS)


__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS, globals())
