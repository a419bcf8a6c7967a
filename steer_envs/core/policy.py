"""Policy contracts: what steering samplers and DS modulation need from a policy.

These are structural ``typing.Protocol`` s, so any object with the right members
plugs in (a baseline from this package, a LeRobot policy behind a thin adapter,
a hand-written function). They are ``runtime_checkable``: ``isinstance`` checks
that the members *exist*, not their signatures or return shapes.

* :class:`TrajectoryPolicy` - a generative policy that samples ``n`` plans; enough
  for random sampling (RS), post-hoc ranking (PR) and output perturbation (OP).
* :class:`DiffusionPolicyLike` - additionally exposes its noise predictor,
  scheduler and normalization; needed by biased initialization (BI), guided
  diffusion (GD) and stochastic sampling (SS), which intervene inside denoising.
* :class:`FlowPolicyLike` - a flow-matching policy: instead of a noise
  predictor and a scheduler it exposes its velocity field; BI, GD and SS run
  and steer its integration in the flow's own form (``steer_envs.steering``).
* :class:`VelocityPolicy` - a batched dynamical system ``x -> x_dot`` (LPV-DS, BC),
  the input of DS modulation in the TLI chapter.

``core`` imports no torch; tensor-typed members are annotated ``Any`` and their
expected types are documented.

>>> import numpy as np
>>> class StandStill:  # plans that keep the agent where it is
...     horizon, action_dim = 4, 2
...     def sample(self, obs, n, *, generator=None):
...         return np.repeat(np.asarray(obs, dtype=float)[None, None], self.horizon, axis=1).repeat(n, axis=0)
>>> isinstance(StandStill(), TrajectoryPolicy), isinstance(StandStill(), DiffusionPolicyLike)
(True, False)
>>> StandStill().sample([1.0, 2.0], 3).shape
(3, 4, 2)
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["DiffusionPolicyLike", "FlowPolicyLike", "NoiseSchedulerLike", "TrajectoryPolicy", "VelocityPolicy"]


@runtime_checkable
class TrajectoryPolicy(Protocol):
    """A frozen generative policy that proposes a batch of plans for an observation."""

    @property
    def horizon(self) -> int:
        """Number of states ``H`` in one sampled plan."""
        ...

    @property
    def action_dim(self) -> int:
        """Dimension ``d`` of each plan state (the space interactions live in)."""
        ...

    def sample(self, obs: Any, n: int, *, generator: np.random.Generator | None = None) -> np.ndarray:
        """Draw ``n`` plans for ``obs``: float array ``(n, H, d)`` in env (unnormalized) units.

        ``generator`` makes the draw reproducible: the same generator state gives
        the same plans (ITPS fixes the initial noise per call). ``None`` uses the
        policy's own randomness.
        """
        ...


@runtime_checkable
class NoiseSchedulerLike(Protocol):
    """The part of a diffusers scheduler (e.g. ``DDIMScheduler``) the guided samplers use.

    ``set_timesteps(k)`` fills ``timesteps`` (descending, e.g. 90, 80, ..., 0 for
    10 of 100 training steps); ``step(eps, t, x_t)`` returns an object whose
    ``prev_sample`` is ``x_{t_prev}``; ``alphas_cumprod[t]`` is ``abar_t`` (SS
    re-noises with it); ``config.num_train_timesteps`` is ``N``.
    """

    timesteps: Any
    alphas_cumprod: Any
    config: Any

    def set_timesteps(self, num_inference_steps: int, *args: Any, **kwargs: Any) -> None: ...

    def step(self, model_output: Any, timestep: Any, sample: Any, *args: Any, **kwargs: Any) -> Any: ...


@runtime_checkable
class DiffusionPolicyLike(TrajectoryPolicy, Protocol):
    """A diffusion policy whose denoising loop a sampler can run and steer.

    Sampling happens in the policy's *normalized* trajectory space, on tensors of
    shape ``(n, H, d)`` (torch, on :attr:`device`); samplers normalize the user's
    interaction with :meth:`normalize` and map plans back with :meth:`unnormalize`.
    """

    scheduler: NoiseSchedulerLike
    num_inference_steps: int

    @property
    def device(self) -> Any:
        """Torch device of the network (where samplers create noise)."""
        ...

    def encode_obs(self, obs: Any) -> Any:
        """Conditioning for :meth:`predict_noise` from an env observation (computed once per call)."""
        ...

    def predict_noise(self, x_t: Any, t: Any, cond: Any) -> Any:
        """The network's output at ``(x_t, t | cond)``, same shape as ``x_t``.

        In the scheduler's ``config.prediction_type``: the noise estimate
        (``"epsilon"``, the default), the clean plan (``"sample"``) or
        ``"v_prediction"``; the guided samplers convert
        (:mod:`steer_envs.steering.schedulers`). Differentiable in ``x_t``.
        """
        ...

    def normalize(self, traj: Any) -> Any:
        """Env units -> normalized space, elementwise over ``(..., d)``; numpy in numpy out, torch in torch out."""
        ...

    def unnormalize(self, traj: Any) -> Any:
        """Inverse of :meth:`normalize`."""
        ...


@runtime_checkable
class FlowPolicyLike(TrajectoryPolicy, Protocol):
    """A flow-matching policy whose integration a sampler can run and steer.

    The flow carries noise ``x_0 ~ N(0, I)`` at time ``tau = 0`` to a plan at
    ``tau = 1`` along ``dx/dtau = v(x, tau | cond)`` (rectified flow:
    ``x_tau = tau * x_1 + (1 - tau) * x_0``, so ``v = x_1 - x_0`` and the clean
    plan implied at ``(x, tau)`` is ``x + (1 - tau) * v``). Integration runs
    ``num_inference_steps`` Euler steps of ``1 / num_inference_steps`` in the
    policy's *normalized* space, on torch tensors ``(n, H, d)`` on :attr:`device`.
    """

    num_inference_steps: int

    @property
    def device(self) -> Any:
        """Torch device of the network (where samplers create noise)."""
        ...

    def encode_obs(self, obs: Any) -> Any:
        """Conditioning for :meth:`predict_velocity` from an env observation (computed once per call)."""
        ...

    def predict_velocity(self, x: Any, tau: Any, cond: Any) -> Any:
        """The velocity ``v(x, tau | cond)``, same shape as ``x``; ``tau`` a float in ``[0, 1]``."""
        ...

    def normalize(self, traj: Any) -> Any:
        """Env units -> normalized space, elementwise over ``(..., d)``; numpy in numpy out, torch in torch out."""
        ...

    def unnormalize(self, traj: Any) -> Any:
        """Inverse of :meth:`normalize`."""
        ...


@runtime_checkable
class VelocityPolicy(Protocol):
    """A batched first-order dynamical system: ``x (N, d) -> x_dot (N, d)`` (numpy float arrays).

    Any callable satisfies ``isinstance(f, VelocityPolicy)``; the shape contract
    is checked by the consumer (e.g. DS modulation).
    """

    def __call__(self, x: np.ndarray) -> np.ndarray: ...
