"""The steering knobs of an ITPS session: the sampler, its batch and guide ratio, how much of a plan a step runs.

>>> SteerSettings(sampler="GD", guide_ratio=30).checked().make_sampler().guide_ratio
30.0
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from steer_envs.core.validation import integer, one_of, real_scalar
from steer_envs.steering import MAX_MCMC_STEPS, SAMPLERS, Sampler, make_sampler

__all__ = ["MAX_BATCH", "MAX_GUIDE_RATIO", "SteerSettings"]

#: the most plans one call may sample in the UI (a batch is drawn on the page)
MAX_BATCH = 256
#: guide ratios beyond this only saturate the plans (ITPS uses 20-60)
MAX_GUIDE_RATIO = 10_000.0


@dataclass(frozen=True)
class SteerSettings:
    """The sampler and its knobs (thesis Table 2.1 defaults; ``None``: the sampler's own default).

    Attributes:
        sampler: ``"RS"``, ``"PR"``, ``"OP"``, ``"BI"``, ``"GD"`` or ``"SS"``.
        batch: plans sampled per call (ITPS: 32).
        guide_ratio: ``beta`` of GD / SS (defaults 20 / 60).
        mcmc_steps: SS's iterations per noise level (default 4).
        execute: waypoints of the chosen plan one :meth:`Session.execute` runs (``None``: all).
        use_clipped_model_output: GD's / SS's DDIM step re-derives the noise from the clipped plan
            estimate (:class:`~steer_envs.steering.GuidedDiffusion`); a domain default, not a knob.
    """

    sampler: str = "SS"
    batch: int = 32
    guide_ratio: float | None = None
    mcmc_steps: int | None = None
    execute: int | None = None
    use_clipped_model_output: bool = False

    def checked(self) -> SteerSettings:
        """These settings validated (``TypeError``/``ValueError`` naming the knob)."""
        owner = "SteerSettings"
        sampler = one_of(self.sampler, "sampler", tuple(SAMPLERS), owner=owner)
        batch = integer(self.batch, "`batch`", low=1, high=MAX_BATCH)
        ratio = None
        if self.guide_ratio is not None:
            ratio = real_scalar(self.guide_ratio, "guide_ratio", owner=owner)
            if not 0.0 <= ratio <= MAX_GUIDE_RATIO:
                raise ValueError(f"{owner}: `guide_ratio` must be in [0, {MAX_GUIDE_RATIO:g}], got {ratio!r}")
        mcmc = None if self.mcmc_steps is None else integer(self.mcmc_steps, "`mcmc_steps`", low=1, high=MAX_MCMC_STEPS)
        execute = None if self.execute is None else integer(self.execute, "`execute`", low=1)
        clipped = self.use_clipped_model_output
        if not isinstance(clipped, bool):
            raise TypeError(f"{owner}: `use_clipped_model_output` must be a bool, got {type(clipped).__name__}")
        return SteerSettings(sampler, batch, ratio, mcmc, execute, self.use_clipped_model_output)

    def make_sampler(self) -> Sampler:
        """A fresh sampler of these settings (knobs a sampler does not have are ignored)."""
        kwargs: dict[str, Any] = {}
        if self.sampler in ("GD", "SS") and self.guide_ratio is not None:
            kwargs["guide_ratio"] = self.guide_ratio
        if self.sampler == "SS" and self.mcmc_steps is not None:
            kwargs["mcmc_steps"] = self.mcmc_steps
        if self.sampler in ("GD", "SS") and self.use_clipped_model_output:
            kwargs["use_clipped_model_output"] = True
        return make_sampler(self.sampler, **kwargs)

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready settings."""
        return {
            "sampler": self.sampler,
            "batch": self.batch,
            "guide_ratio": self.guide_ratio,
            "mcmc_steps": self.mcmc_steps,
            "execute": self.execute,
        }
