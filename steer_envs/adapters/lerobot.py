"""A LeRobot ``DiffusionPolicy`` as a :class:`~steer_envs.core.policy.DiffusionPolicyLike`: all six samplers steer it.

:class:`LeRobotDiffusion` wraps a trained LeRobot (0.4) Diffusion Policy and
the processors it was trained with; it duck-types both (steer-envs imports no
LeRobot module, except in :meth:`LeRobotDiffusion.from_pretrained`). What it maps:

* **features**: each vector input feature of the policy (``observation.state``,
  ``observation.environment_state``) takes entries of the env observation
  (``observation_features``; default: the feature's first entries); an
  observation history ``(n_obs_steps, obs_dim)`` (what
  :func:`~steer_envs.steering.observations.policy_observation` gives) fills
  LeRobot's ``n_obs_steps`` window. Image features are refused.
* **normalisation**: observations go through the policy's preprocessor (its
  ``NormalizerProcessorStep``); actions are mapped with the postprocessor
  (its ``UnnormalizerProcessorStep``), whose affine map is read off by
  probing it at 0 and 1, so any of LeRobot's modes (mean/std, min/max,
  quantiles) works and the inverse is exact.
* **horizon**: a plan is LeRobot's whole ``horizon``-step action chunk;
  ``exec_start = n_obs_steps - 1`` is the chunk's first action for the current
  step (what :class:`~steer_envs.wrappers.SteeringWrapper` executes from).
* **denoiser**: ``predict_noise`` is ``policy.diffusion.unet(x, t,
  global_cond=...)``, the condition from
  ``policy.diffusion._prepare_global_conditioning``; its output is in the
  scheduler's ``prediction_type`` (``epsilon`` or x0-prediction ``sample``; the
  samplers convert, :mod:`~steer_envs.steering.schedulers`).
* **randomness**: ``sample`` is :func:`~steer_envs.steering.diffusion.denoise_plans`:
  the initial noise from the numpy generator, DDPM's per-step noise from a
  ``torch.Generator`` seeded by it (never torch's global generator), so the
  same seed gives the same plans under every sampler. ``scheduler="ddim"``
  swaps DDPM for a DDIM scheduler built from the same config (deterministic
  steps, fewer of them: ``num_inference_steps``).

>>> LeRobotDiffusion.__name__
'LeRobotDiffusion'
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch

from steer_envs.core.validation import describe, integer
from steer_envs.steering.base import check_generator
from steer_envs.steering.diffusion import denoise_plans
from steer_envs.steering.schedulers import check_scheduler

__all__ = ["LeRobotDiffusion"]

#: LeRobot's feature-type names of vector observations (``FeatureType.STATE`` / ``FeatureType.ENV``)
_VECTOR_TYPES = ("STATE", "ENV")


def _type_name(feature: Any) -> str:
    kind = getattr(feature, "type", None)
    return str(getattr(kind, "name", kind))


class LeRobotDiffusion:
    """A trained LeRobot ``DiffusionPolicy`` (and its processors) as a steerable ``DiffusionPolicyLike``.

    Args:
        policy: a ``lerobot.policies.diffusion.modeling_diffusion.DiffusionPolicy``.
        preprocessor: the policy's input pipeline (``make_pre_post_processors(...)[0]``
            or ``policy_preprocessor.json`` of a checkpoint): normalises observations.
        postprocessor: its output pipeline: unnormalises actions.
        observation_features: LeRobot input feature -> entries of the env observation
            (default: each feature's first ``shape[0]`` entries).
        scheduler: ``None`` (the policy's own noise scheduler), ``"ddim"`` (a DDIM
            scheduler from the same config), or a diffusers scheduler object.
        num_inference_steps: denoising steps (default: the policy's).
        interaction_dims: action entries a sketch or point constrains (default: all).
    """

    def __init__(
        self,
        policy: Any,
        preprocessor: Any,
        postprocessor: Any,
        *,
        observation_features: Mapping[str, Sequence[int]] | None = None,
        scheduler: Any = None,
        num_inference_steps: int | None = None,
        interaction_dims: Sequence[int] | None = None,
    ) -> None:
        model = getattr(policy, "diffusion", None)
        if model is None or not hasattr(model, "unet") or not hasattr(model, "noise_scheduler"):
            raise TypeError(
                f"LeRobotDiffusion: `policy` must be a LeRobot DiffusionPolicy (with .diffusion.unet and "
                f".diffusion.noise_scheduler), got {describe(policy)}"
            )
        for name, value in (("preprocessor", preprocessor), ("postprocessor", postprocessor)):
            if not callable(value):
                raise TypeError(
                    f"LeRobotDiffusion: `{name}` must be the policy's processor pipeline, got {describe(value)}"
                )
        self.lerobot_policy, self._model, self.config = policy, model, policy.config
        self.preprocessor, self.postprocessor = preprocessor, postprocessor
        self.scheduler = self._scheduler(scheduler)
        check_scheduler(self.scheduler, "LeRobotDiffusion")
        steps = model.num_inference_steps if num_inference_steps is None else num_inference_steps
        self.num_inference_steps = integer(steps, "num_inference_steps", low=1, owner="LeRobotDiffusion")
        self.horizon = int(self.config.horizon)
        self.n_obs_steps = int(self.config.n_obs_steps)
        self.exec_start = self.n_obs_steps - 1
        self.action_dim = int(self.config.action_feature.shape[0])
        self.interaction_dims = None if interaction_dims is None else tuple(int(i) for i in interaction_dims)
        self.features = self._observation_features(observation_features)
        self._scale, self._offset = self._affine_action_map()

    @classmethod
    def from_pretrained(cls, path: str | os.PathLike[str], **kwargs: Any) -> LeRobotDiffusion:
        """The policy and processors a LeRobot checkpoint folder holds (``lerobot-train``'s ``pretrained_model``).

        ``kwargs`` go to the constructor. Needs LeRobot (``pip install "steer-envs[lerobot]"``).
        """
        from steer_envs.core.extras import require

        modeling = require("lerobot.policies.diffusion.modeling_diffusion", "lerobot", "LeRobotDiffusion")
        pipeline = require("lerobot.processor", "lerobot", "LeRobotDiffusion").PolicyProcessorPipeline
        converters = require("lerobot.processor.converters", "lerobot", "LeRobotDiffusion")
        policy = modeling.DiffusionPolicy.from_pretrained(str(path))
        policy.eval()
        pre = pipeline.from_pretrained(str(path), config_filename="policy_preprocessor.json")
        post = pipeline.from_pretrained(
            str(path),
            config_filename="policy_postprocessor.json",
            to_transition=converters.policy_action_to_transition,
            to_output=converters.transition_to_policy_action,
        )
        return cls(policy, pre, post, **kwargs)

    # ------------------------------------------------------------ set-up
    def _scheduler(self, scheduler: Any) -> Any:
        own = self._model.noise_scheduler
        if scheduler is None:
            return own
        if isinstance(scheduler, str):
            if scheduler.lower() != "ddim":
                raise ValueError(
                    f"LeRobotDiffusion: `scheduler` must be None, 'ddim' or a scheduler, got {scheduler!r}"
                )
            from diffusers import DDIMScheduler

            return DDIMScheduler.from_config(own.config)
        return scheduler

    def _observation_features(self, given: Mapping[str, Sequence[int]] | None) -> dict[str, tuple[int, ...]]:
        inputs = dict(self.config.input_features)
        images = [k for k, f in inputs.items() if _type_name(f) not in _VECTOR_TYPES]
        if images:
            raise ValueError(f"LeRobotDiffusion maps vector observations only; the policy also takes {images}")
        given = dict(given or {})
        unknown = set(given) - set(inputs)
        if unknown:
            raise ValueError(
                f"LeRobotDiffusion: observation_features names {sorted(unknown)}, "
                f"not inputs of the policy ({sorted(inputs)})"
            )
        out: dict[str, tuple[int, ...]] = {}
        for key, feature in inputs.items():
            width = int(feature.shape[0])
            picks = tuple(int(i) for i in given.get(key, range(width)))
            if len(picks) != width:
                raise ValueError(
                    f"LeRobotDiffusion: observation_features[{key!r}] must name {width} entries, got {len(picks)}"
                )
            out[key] = picks
        return out

    def _affine_action_map(self) -> tuple[torch.Tensor, torch.Tensor]:
        """``unnormalize(a) = scale * a + offset``, read off the postprocessor (checked at a third point)."""
        probe = torch.tensor([0.0, 1.0, -0.5])[:, None].repeat(1, self.action_dim)
        out = torch.as_tensor(self.postprocessor(probe.clone())).to(torch.float64).reshape(3, self.action_dim)
        offset, scale = out[0], out[1] - out[0]
        if not torch.allclose(out[2], offset - 0.5 * scale, atol=1e-5) or bool((scale == 0).any()):
            raise ValueError("LeRobotDiffusion: the postprocessor's action map is not an invertible affine map")
        return scale.float(), offset.float()

    # ------------------------------------------------------------ DiffusionPolicyLike
    @property
    def device(self) -> torch.device:
        """Where the U-Net's parameters live."""
        return next(self._model.unet.parameters()).device

    @property
    def dtype(self) -> torch.dtype:
        """The U-Net's parameter dtype (the samplers draw noise in it)."""
        return next(self._model.unet.parameters()).dtype

    def encode_obs(self, obs: Any) -> torch.Tensor:
        """``(1, global_cond_dim)``: the normalised observation window through LeRobot's conditioning."""
        arr = np.asarray(obs, dtype=np.float32)
        if arr.ndim == 1:
            arr = np.repeat(arr[None], self.n_obs_steps, axis=0)
        if arr.ndim != 2 or arr.shape[0] != self.n_obs_steps:
            raise ValueError(
                f"LeRobotDiffusion.encode_obs: `obs` must be one observation or "
                f"({self.n_obs_steps}, obs_dim), got {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise ValueError("LeRobotDiffusion.encode_obs: `obs` must be finite")
        need = 1 + max(max(p) for p in self.features.values())
        if arr.shape[1] < need:
            raise ValueError(f"LeRobotDiffusion.encode_obs: `obs` has {arr.shape[1]} entries, the features need {need}")
        batch = {key: torch.from_numpy(arr[:, list(picks)].copy()) for key, picks in self.features.items()}
        normalized = self.preprocessor(batch)  # rows are the window: normalised elementwise
        window = {k: torch.as_tensor(normalized[k]).reshape(1, self.n_obs_steps, -1).to(self.device) for k in batch}
        return self._model._prepare_global_conditioning(window)

    def predict_noise(self, x_t: torch.Tensor, t: Any, cond: torch.Tensor) -> torch.Tensor:
        """The U-Net's output at ``(x_t, t)`` in the scheduler's ``prediction_type``; differentiable in ``x_t``."""
        n = x_t.shape[0]
        steps = torch.as_tensor(t, device=x_t.device).long().reshape(-1).expand(n)
        return self._model.unet(x_t, steps, global_cond=cond.to(x_t.dtype).expand(n, -1))

    def normalize(self, traj: Any) -> Any:
        """Actions in env units -> the policy's normalised space (numpy in numpy out, torch in torch out)."""
        if isinstance(traj, torch.Tensor):
            return (traj - self._offset.to(traj)) / self._scale.to(traj)
        return (np.asarray(traj, dtype=np.float64) - self._offset.double().numpy()) / self._scale.double().numpy()

    def unnormalize(self, traj: Any) -> Any:
        """Inverse of :meth:`normalize`."""
        if isinstance(traj, torch.Tensor):
            return traj * self._scale.to(traj) + self._offset.to(traj)
        return np.asarray(traj, dtype=np.float64) * self._scale.double().numpy() + self._offset.double().numpy()

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """``n`` unsteered action chunks ``(n, horizon, action_dim)`` in env units (see the module docstring)."""
        rng = check_generator(generator)
        return denoise_plans(self, obs, integer(n, "n", low=1, owner="LeRobotDiffusion.sample"), rng)
