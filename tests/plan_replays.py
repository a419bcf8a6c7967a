"""What the BlockStack and Kitchen plan-execution tests share: replay-fidelity rows and rates, refused plans."""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
import pytest


def fidelity_row(seed: int, index: int, record: Any, label: str | None, outcome: Any) -> dict[str, Any]:
    """One replayed skill: the recorded skill, what the plan was classified as and what its execution did."""
    return {
        "seed": seed,
        "index": index,
        "skill": record.name,
        "classified": label,
        "executed": outcome.executed,
        "violation": outcome.violation,
        "steps": outcome.steps,
    }


def fidelity_rates(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The count and rates of :func:`fidelity_row` rows: ``replay_success`` (executed the recorded skill, no
    violation), ``replay_executed``, ``classified``; and the rows."""
    n = max(len(rows), 1)
    return {
        "skills": len(rows),
        "replay_success": sum(r["executed"] == r["skill"] and not r["violation"] for r in rows) / n,
        "replay_executed": sum(r["executed"] == r["skill"] for r in rows) / n,
        "classified": sum(r["classified"] == r["skill"] for r in rows) / n,
        "rows": rows,
    }


def noisy(plan: np.ndarray, noise: float, rng: np.random.Generator) -> np.ndarray:
    """``plan`` (float64) with Gaussian noise of std ``noise`` (m) on every waypoint's position (none at 0)."""
    plan = plan.astype(np.float64)
    if noise > 0:
        plan[:, :3] += rng.normal(scale=noise, size=plan[:, :3].shape)
    return plan


def refuse_bad_plans(fns: Iterable[Callable[..., Any]], env: Any, good: np.ndarray) -> None:
    """Each ``fn(env, plan)`` refuses a non-env and plans of the wrong width, axes, length or values."""
    width = good.shape[1]
    for fn in fns:
        with pytest.raises(TypeError, match="env"):
            fn(object(), good)
        with pytest.raises(ValueError, match="plan"):
            fn(env, good[:, : width - 1])
        with pytest.raises(ValueError, match="plan"):
            fn(env, good[0])
        with pytest.raises(ValueError, match="plan"):
            fn(env, np.zeros((0, width)))
        with pytest.raises(ValueError, match="plan"):
            fn(env, np.zeros((10_001, width)))
        with pytest.raises(ValueError, match="plan"):
            fn(env, np.where(good == good[0, 0], np.nan, good))
        with pytest.raises(TypeError, match="plan"):
            fn(env, "plan")


def fidelity_parser(domain: str, seeds: int, seeds_help: str) -> argparse.ArgumentParser:
    """The command line of a replay-fidelity script: ``--seeds`` (default ``seeds``), ``--first-seed``, ``--noise``."""
    parser = argparse.ArgumentParser(description=f"{domain} replay fidelity of the expert's skills as plans")
    parser.add_argument("--seeds", type=int, default=seeds, help=seeds_help)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--noise", type=float, default=0.0, help="waypoint noise std (m)")
    return parser


def print_fidelity(result: dict[str, Any]) -> None:
    """Print the rows that missed (executed or classified another skill, or violated), then the rates."""
    for row in result["rows"]:
        if row["executed"] != row["skill"] or row["violation"] or row["classified"] != row["skill"]:
            print("miss:", row)
    print({k: v for k, v in result.items() if k != "rows"})
