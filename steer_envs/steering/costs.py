"""Steering costs beyond alignment: any differentiable function of a plan, and the safety cost of a task.

A *plan cost* is a callable ``cost(plans) -> (n,)`` on a torch tensor of plans
``(n, H, d)`` in env units (what the policy's ``unnormalize`` gives),
differentiable in ``plans``. The samplers that take costs (``costs=`` of
:func:`~steer_envs.steering.make_sampler`) add them to the user's alignment:
GD and SS follow their gradient during denoising (through the policy's
``unnormalize``), and every sampler ranks its batch by alignment plus
weighted costs, so PR, OP and BI pick the plan they like best too.

:func:`safety_cost` turns a task's :class:`~steer_envs.core.task.TaskSpec`
into a cost: the mean depth of a plan's waypoints inside its unsafe regions
(forbidden regions, and the regions of modes the current mode may not move
to: :meth:`~steer_envs.core.task.TaskSpec.unsafe_regions`), so TLI's
constraints guide any policy's plans. :func:`switch_cost` guards a task's
transitions where a plan carries a discrete command (a gripper): the
command may switch on only inside some regions and off only inside others
(a grasp only at a cube, a release only where the cube can rest).

>>> import torch
>>> from steer_envs.core.regions import Boxes
>>> wall = region_cost([Boxes([[0.0, 0.0]], [[1.0, 1.0]])])
>>> wall(torch.tensor([[[0.5, 0.5], [2.0, 2.0]]])).tolist()  # one waypoint 0.5 deep, one outside
[0.25]
>>> speed = lambda plans: (plans.diff(dim=1) ** 2).sum(dim=(1, 2))  # any differentiable function of the plan
>>> [weight for _, weight in check_costs([speed, (wall, 5.0)])]
[1.0, 5.0]
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import torch

from steer_envs.core.regions import Boxes
from steer_envs.core.task import TaskSpec
from steer_envs.core.validation import describe, real_scalar

__all__ = ["PlanCost", "WeightedCosts", "check_costs", "region_cost", "safety_cost", "switch_cost"]

#: a differentiable plan cost: plans ``(n, H, d)`` in env units -> costs ``(n,)``
PlanCost = Callable[[torch.Tensor], torch.Tensor]


def _against(plans: torch.Tensor, box: Boxes) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The plans' entries ``box.dims`` as ``(n, H, 1, m)`` and the box corners ``(k, m)`` as tensors like them."""
    low = torch.as_tensor(box.low, dtype=plans.dtype, device=plans.device)
    high = torch.as_tensor(box.high, dtype=plans.dtype, device=plans.device)
    return plans[..., list(box.dims)].unsqueeze(-2), low, high


def region_cost(regions: Sequence[Boxes]) -> PlanCost:
    """The mean over waypoints of how deep each waypoint is inside any of ``regions`` (0 outside all).

    Its gradient pushes a waypoint inside a box toward the box's nearest face,
    with the magnitude of the alignment cost's (``1 / H`` per waypoint).
    """
    boxes = list(regions)
    for box in boxes:
        if not isinstance(box, Boxes):
            raise TypeError(f"region_cost: `regions` must hold Boxes, got {describe(box)}")

    def cost(plans: torch.Tensor) -> torch.Tensor:
        total = plans.new_zeros(plans.shape[:-2])
        for box in boxes:
            if len(box) == 0:
                continue
            p, low, high = _against(plans, box)
            inside = torch.minimum(p - low, high - p).amin(dim=-1)  # (n, H, k), negative outside a box
            total = total + inside.clamp_min(0.0).amax(dim=-1).mean(dim=-1)
        return total

    cost.__name__ = "region_cost"
    return cost


def _check_boxes(regions: Sequence[Boxes] | None, what: str) -> list[Boxes]:
    boxes = list(regions or ())
    for box in boxes:
        if not isinstance(box, Boxes):
            raise TypeError(f"switch_cost: `{what}` must hold Boxes, got {describe(box)}")
    return boxes


def _distance_outside(plans: torch.Tensor, regions: list[Boxes]) -> torch.Tensor:
    """``(n, H)``: each waypoint's Euclidean distance to the nearest box of ``regions`` (0 inside one)."""
    nearest: torch.Tensor | None = None
    for box in regions:
        if len(box) == 0:
            continue
        p, low, high = _against(plans, box)
        gap = torch.maximum(low - p, p - high).clamp_min(0.0)
        # the norm's gradient is undefined at 0 (inside a box): a tiny floor keeps it finite there
        dist = (gap.square().sum(dim=-1) + 1e-12).sqrt().amin(dim=-1)
        nearest = dist if nearest is None else torch.minimum(nearest, dist)
    if nearest is None:
        raise ValueError("switch_cost: a guarded switch needs at least one non-empty region it may happen in")
    return nearest


def switch_cost(
    dim: int,
    *,
    on_at: Sequence[Boxes] | None = None,
    off_at: Sequence[Boxes] | None = None,
    sharpness: float = 8.0,
) -> PlanCost:
    """Guards on where a plan's binary command (entry ``dim``, on when > 0) may switch.

    A switch on between waypoints ``k - 1`` and ``k`` (a gripper closing)
    costs waypoint ``k``'s distance to the nearest box of ``on_at``; a switch
    off costs its distance to ``off_at`` (``None``: that switch is not
    guarded). The switch is read softly, ``s_k = sigmoid(sharpness * c_k)``,
    a switch on weighing ``s_k (1 - s_{k-1})``, so the gradient moves both
    where the switch happens and the waypoints around it. The cost of a plan
    is the sum over its switches (a plan that never switches costs 0).

    >>> import torch
    >>> at_cube = Boxes([[0.0, 0.0]], [[0.1, 0.1]])
    >>> grasp = switch_cost(2, on_at=[at_cube])
    >>> plans = torch.tensor([[[0.05, 0.05, -1.0], [0.05, 0.05, 1.0]],   # closes at the cube
    ...                       [[0.50, 0.05, -1.0], [0.50, 0.05, 1.0]]])  # closes 0.4 away from it
    >>> [round(value, 2) for value in grasp(plans).tolist()]
    [0.0, 0.4]
    """
    if isinstance(dim, bool) or not isinstance(dim, int) or dim < 0:
        raise ValueError(f"switch_cost: `dim` must be a plan entry index >= 0, got {dim!r}")
    sharp = real_scalar(sharpness, "`sharpness`", low=0.0)
    guards = [(True, _check_boxes(on_at, "on_at")), (False, _check_boxes(off_at, "off_at"))]
    guards = [(on, boxes) for on, boxes in guards if boxes]
    if not guards:
        raise ValueError("switch_cost: give `on_at` or `off_at` (the regions a switch may happen in)")
    for _, boxes in guards:
        if dim in {d for box in boxes for d in box.dims}:
            raise ValueError(f"switch_cost: the regions must not constrain the command's own entry {dim}")

    def cost(plans: torch.Tensor) -> torch.Tensor:
        if plans.shape[-1] <= dim:
            raise ValueError(f"switch_cost: plans have {plans.shape[-1]} entries, the command is entry {dim}")
        on = torch.sigmoid(sharp * plans[..., dim])  # (n, H)
        total = plans.new_zeros(plans.shape[0])
        for switch_on, boxes in guards:
            now, before = (on, 1 - on) if switch_on else (1 - on, on)
            weight = now[:, 1:] * before[:, :-1]
            total = total + (weight * _distance_outside(plans[:, 1:], boxes)).sum(dim=1)
        return total

    cost.__name__ = "switch_cost"
    return cost


def safety_cost(task: TaskSpec, mode: str | None = None) -> PlanCost:
    """The safety cost of ``task`` (in the current ``mode``, if given): :func:`region_cost` of its unsafe regions.

    ``ValueError`` when the task declares no region a plan must stay out of.
    """
    if not isinstance(task, TaskSpec):
        raise TypeError(f"safety_cost: `task` must be a TaskSpec, got {describe(task)}")
    regions = task.unsafe_regions(mode)
    if not regions:
        raise ValueError(
            f"safety_cost: task {task.name!r} declares no forbidden region (TaskSpec.forbidden / mode_regions)"
        )
    cost = region_cost(regions)
    cost.__name__ = f"safety_cost({task.name})"
    return cost


def check_costs(costs: Any) -> list[tuple[PlanCost, float]]:
    """``costs`` as ``[(cost, weight), ...]``: each item a plan cost (weight 1) or a ``(cost, weight)`` pair."""
    if costs is None:
        return []
    if callable(costs) or isinstance(costs, (str, bytes)) or not hasattr(costs, "__iter__"):
        raise TypeError(f"`costs` must be a sequence of plan costs or (cost, weight) pairs, got {describe(costs)}")
    out = []
    for item in costs:
        pair = (item, 1.0) if callable(item) else tuple(item) if isinstance(item, (tuple, list)) else ()
        if len(pair) != 2 or not callable(pair[0]):
            raise TypeError(f"`costs` items must be plan costs or (cost, weight) pairs, got {describe(item)}")
        out.append((pair[0], real_scalar(pair[1], "a cost's weight", low=0.0)))
    return out


class WeightedCosts:
    """The weighted sum of plan costs a sampler was given: its values (ranking) and its gradient (guidance)."""

    def __init__(self, costs: Any) -> None:
        self.terms = check_costs(costs)

    def __bool__(self) -> bool:
        return bool(self.terms)

    def _total(self, plans: torch.Tensor) -> torch.Tensor:
        total = plans.new_zeros(plans.shape[0])
        for cost, weight in self.terms:
            value = cost(plans)
            if not isinstance(value, torch.Tensor) or value.shape != (plans.shape[0],):
                what = tuple(value.shape) if isinstance(value, torch.Tensor) else describe(value)
                raise ValueError(f"a plan cost must return a tensor of shape ({plans.shape[0]},), got {what}")
            total = total + weight * value
        return total

    def values(self, plans: np.ndarray) -> np.ndarray:
        """``(n,)`` weighted costs of plans ``(n, H, d)`` in env units (0 without costs)."""
        if not self.terms:
            return np.zeros(len(plans))
        with torch.no_grad():
            return self._total(torch.as_tensor(plans, dtype=torch.float64)).numpy()

    def grad(self, policy: Any, x: torch.Tensor) -> torch.Tensor:
        """``grad_x sum_b cost(unnormalize(x_b))`` in the policy's normalized space (zeros without costs)."""
        if not self.terms:
            return torch.zeros_like(x)
        leaf = x.detach().requires_grad_(True)
        with torch.enable_grad():
            total = self._total(policy.unnormalize(leaf)).sum()
            (grad,) = torch.autograd.grad(total, leaf, allow_unused=True)
        return torch.zeros_like(x) if grad is None else grad.to(x.dtype)
