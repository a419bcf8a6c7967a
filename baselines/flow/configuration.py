"""The flow-matching policy's config and its training presets.

:class:`FlowConfig` is :class:`~steer_envs.baselines.diffusion.configuration.PlanNetConfig`
as it is: the same plan layout and U-Net as Diffusion Policy, so a flow and a
DP of one preset have the same parameters and train on the same samples;
only the target (a velocity) and the sampler (Euler steps) differ.
``num_inference_steps`` is the number of Euler steps.

>>> cfg = FlowConfig(obs_dim=2, action_dim=2)
>>> from steer_envs.baselines.diffusion import DiffusionConfig
>>> cfg.parameter_count() == DiffusionConfig(obs_dim=2, action_dim=2).parameter_count()
True
>>> sorted(PRESETS)
['blockstack', 'cpu', 'itps', 'kitchen']
"""

from __future__ import annotations

from dataclasses import dataclass

from steer_envs.baselines.common.configuration import Preset
from steer_envs.baselines.diffusion.configuration import PRESETS as DP_PRESETS
from steer_envs.baselines.diffusion.configuration import PlanNetConfig

__all__ = ["PRESETS", "FlowConfig"]


@dataclass(frozen=True, kw_only=True)
class FlowConfig(PlanNetConfig):
    """Features, plan layout, U-Net and Euler steps of a :class:`~steer_envs.baselines.flow.FlowPolicy`."""


def _like_dp(name: str) -> Preset[FlowConfig]:
    """DP's preset ``name`` with the same network, plan layout and training settings."""
    dp = DP_PRESETS[name]
    fields = {k: v for k, v in dp.model.to_dict().items() if k in FlowConfig.field_names()}
    return Preset(FlowConfig.from_dict(fields), dp.train, f"DP's {name!r} preset as a flow ({dp.description})")


#: named (config, training) presets, each DP's preset of that name field for field: ``cpu`` (the shipped
#: Maze2D DP's recipe), ``blockstack`` and ``kitchen`` (the skill-plan policies) and ``itps`` (ITPS's
#: full-size network, a GPU job)
PRESETS: dict[str, Preset[FlowConfig]] = {name: _like_dp(name) for name in ("blockstack", "cpu", "itps", "kitchen")}
