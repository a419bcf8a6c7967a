"""``sb3``: can an RL user train stable-baselines3 agents on the library's envs with SB3's defaults?

Methods, each with every SB3 default: ``sac`` (``SAC("MlpPolicy", env)``) and
``ppo`` (``PPO("MlpPolicy", env)``) on each 2D dense env (the registered ids
ending ``Dense-v0``, not the goal ones), ``sac-her`` (SAC with
``HerReplayBuffer``: SB3's default ``future`` strategy, 4 sampled goals) on
the goal-conditioned ``steer_envs/Maze2D-UmazeGoal-v0`` (sparse reward). Each
id runs as registered (the dense ids carry their RL options: observed
sensors or goal, ``[-1, 1]`` actions). A trial trains one agent for
``timesteps`` steps (default 100k for ``sac`` and ``ppo``, 50k for
``sac-her``, the RL-readiness budgets) from its seed (5 seeds by default),
evaluates it deterministically on ``eval_episodes`` episodes every
``eval_every`` steps (episode ``i`` from ``reset(seed=1_000_000 + i)`` for
every seed and method, never a training env's reset seed; success =
``info["is_success"]`` at the episode's end) and reports the final success
rate, the first step an evaluation reached 80 %, whether that happened
within the method's budget (``reached_80``), training steps/s and wall time;
the curve is kept in the record for the learning-curve figure (mean over the
seeds with their min-max band, per env and method).

Env options (``--param``), each ``None`` by default (the id's registered
value) or a bool passed on top: ``normalize_actions`` (``[-1, 1]``
actions), ``observe_sensors`` (the task's sensor bits in the observation;
ignored on Maze2D, whose sensors carry no memory and whose ``at_goal`` bit
would contradict HER's relabelled goals). ``maze_goal_obs`` (off by
default): a ``sac`` / ``ppo`` trial on Maze2D's plain ``...Dense-v0`` ids
trains and evaluates on the ``...GoalDense-v0`` sibling (same maze,
dynamics and dense reward) flattened to a Box for ``MlpPolicy``, as the
first recorded results did; without it on the plain id, whose observation
carries the goal (``observe_goal``). ``maze_relative_actions``: Maze2D's
action is the waypoint's offset from the agent (``relative_actions``).
``max_episode_steps``: truncate training and evaluation episodes there
instead of at the id's registered limit (0, the default).

Training is long on a CPU (tens of steps/s per thread), so a trial
checkpoints (model, SAC's replay buffer, curve) at every evaluation under
``cache_dir`` and a killed run resumes there; see
:mod:`steer_envs.baselines.sb3`, the library code every trial calls. ``stop_success`` (off by
default) ends a trial once an evaluation reaches that success rate.

>>> Sb3Params().budget("sac"), Sb3Params().budget("ppo"), Sb3Params().budget("sac-her")
(100000, 100000, 50000)
>>> Sb3Params(timesteps=500).budget("sac")
500
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from steer_envs.baselines.sb3 import (
    GOAL_ENVS,
    METHODS,
    Sb3Options,
    Sb3Run,
    Sb3Settings,
    method_fits,
    train_and_evaluate,
)
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, TrialPlan, TrialResult, register_suite
from steer_envs.io import default_cache_dir
from steer_envs.utils.fields import build_from

if TYPE_CHECKING:
    from steer_envs.bench.suite import Trial, TrialRequest

__all__ = ["DEFAULT_TIMESTEPS", "SB3", "Sb3Params", "dense_envs", "reached_within_budget", "sb3_findings"]

SUITE_NAME = "sb3"
#: the RL-readiness budgets: SAC (and PPO, reported beside it) within 100k steps, SAC + HER within 50k
DEFAULT_TIMESTEPS: dict[str, int] = {"sac": 100_000, "ppo": 100_000, "sac-her": 50_000}
#: the RL-readiness success threshold (%)
TARGET_SUCCESS = 80.0
#: training seeds per env and method; the SAC claim asks :data:`REQUIRED_SEEDS` of them to reach the target
SEEDS = 5
REQUIRED_SEEDS = 4
MAX_TIMESTEPS = 10_000_000


def dense_envs() -> list[str]:
    """The registered 2D dense ids (``...Dense-v0``, not ``...GoalDense-v0``), in registry order."""
    from steer_envs.envs.registry import env_ids

    return [i for i in env_ids(variants=True) if i.endswith("Dense-v0") and not i.endswith("GoalDense-v0")]


def _all_envs() -> list[str]:
    return [*dense_envs(), *GOAL_ENVS]


@dataclass(frozen=True)
class Sb3Params(Sb3Options, SuiteParams):
    """Parameters of ``sb3``: the library's :class:`~steer_envs.baselines.sb3.Sb3Options`, the budget, the cache.

    ``timesteps``: training steps per trial (``None``: 100k for ``sac`` and ``ppo``, 50k for
    ``sac-her``); the env options are described in the module docstring;
    ``threads`` are the trial's; ``checkpoint`` saves model, replay buffer and
    curve at every evaluation under ``cache_dir`` (default
    :func:`~steer_envs.io.default_cache_dir` ``("sb3")``) and resumes from there.
    """

    suite_name: ClassVar[str] = SUITE_NAME
    timesteps: int | None = None
    cache_dir: str = ""

    def __post_init__(self) -> None:
        ok = self.timesteps is None or 1 <= self.timesteps <= MAX_TIMESTEPS
        self.require("timesteps", ok, f"None or an int in [1, {MAX_TIMESTEPS}]")
        self.require_at_least(1, "eval_episodes", "eval_every", "threads")
        self.require_at_least(0, "max_episode_steps")
        self.require_at_most(1000, "eval_episodes")
        self.require_at_most(MAX_TIMESTEPS, "eval_every", "max_episode_steps")
        self.require_at_most(64, "threads")
        self.require("stop_success", 0.0 <= self.stop_success <= 100.0, "in [0, 100] (%)")

    def budget(self, method: str) -> int:
        """The training steps of a ``method`` trial."""
        if method not in DEFAULT_TIMESTEPS:
            raise ValueError(f"method must be one of {METHODS}, got {method!r}")
        return self.timesteps if self.timesteps is not None else DEFAULT_TIMESTEPS[method]

    def settings(self, method: str) -> Sb3Settings:
        """The library's :class:`~steer_envs.baselines.sb3.Sb3Settings` of a ``method`` trial (the same fields)."""
        cache = Path(self.cache_dir) if self.cache_dir else default_cache_dir(SUITE_NAME)
        return build_from(Sb3Settings, self, timesteps=self.budget(method), cache=cache)


def generate_sb3(suite: Suite, request: TrialRequest) -> TrialPlan:
    """The requested envs x methods x seeds, keeping only the pairs that fit (:func:`method_fits`)."""
    params = suite.resolve_params(request.params, request.trials, base=request.base)
    pairs = [(e, m) for e in request.envs for m in request.methods if method_fits(e, m)]
    if not pairs:
        raise ValueError(
            f"sb3: no env fits the chosen methods {list(request.methods)}: 'sac' and 'ppo' run on the "
            f"...Dense-v0 ids, 'sac-her' on {list(GOAL_ENVS)}"
        )
    trials = tuple(suite.trial(e, m, s, params) for e, m in pairs for s in suite.seed_list(request))
    skipped = len(request.envs) * len(request.methods) - len(pairs)
    notes = (f"{skipped} env x method pairs skipped: sac and ppo run on the dense ids, sac-her on the goal ids",)
    return TrialPlan(trials, notes if skipped else ())


def run_sb3_trial(trial: Trial) -> TrialResult:
    """Train (or resume) one agent and evaluate it along the way (a line on stderr per evaluation)."""
    params = Sb3Params.from_json(trial.params)

    def report(step: int, success: float) -> None:  # one line per evaluation: a long trial is not silent
        print(f"[sb3] {trial.label}: step {step}, success {success:.0f} %", file=sys.stderr, flush=True)

    method = str(trial.method)
    run = train_and_evaluate(str(trial.env), method, trial.seed, params.settings(method), on_eval=report)
    reached = run.steps_to(TARGET_SUCCESS)
    metrics: dict[str, float | None] = {
        "success": run.successes[-1],
        "steps_to_goal": None if reached is None else float(reached),
        "reached_80": reached_within_budget(run, DEFAULT_TIMESTEPS[method]),
        "best_success": max(run.successes),
        "timesteps": float(run.timesteps),
        "steps_per_s": run.timesteps / run.train_s if run.train_s > 0 else None,
        "wall_min": run.wall_s / 60.0,
    }
    extra = {
        "curve": run.curve,
        "train_env": run.train_env,
        "learning_starts": run.learning_starts,
        "resumed_from": run.resumed_from,
        "stopped_early": run.stopped_early,
        "stable_baselines3": run.stable_baselines3,
    }
    return TrialResult(metrics, extra)


def reached_within_budget(run: Sb3Run, budget: int) -> float | None:
    """1.0 when an evaluation of ``run`` within ``budget`` steps reached :data:`TARGET_SUCCESS`, 0.0 when none did
    and it trained that far, ``None`` when it stopped short of the budget below the target (no verdict).

    >>> run = Sb3Run([[0, 0.0], [100, 90.0]], 100, 1.0, 1.0, "x", 0, 0, False, "2")
    >>> reached_within_budget(run, 100), reached_within_budget(run, 50), reached_within_budget(run, 200)
    (1.0, 0.0, 1.0)
    >>> reached_within_budget(Sb3Run([[0, 0.0], [100, 10.0]], 100, 1.0, 1.0, "x", 0, 0, False, "2"), 200) is None
    True
    """
    if run.steps_to(TARGET_SUCCESS, within=budget) is not None:
        return 1.0
    return 0.0 if run.timesteps >= budget else None


def _short(env: str | None) -> str:
    return (env or "-").split("/", 1)[-1]


def _seed_counts(table: Any, method: str, env: str) -> list[tuple[int, int]]:
    """``(seeds that reached the target within the budget, seeds with a verdict)`` of each row of the cell."""
    out = []
    for r in table.rows:
        stat = r.stats.get("reached_80") if r.method == method and r.env == env else None
        if stat is not None:
            out.append((round(stat.mean * stat.n), stat.n))
    return out


def _seed_verdict(reached: int, judged: int) -> bool | None:
    """Whether ``reached`` of ``judged`` seeds meet "at least 4 of 5" (4/5 of the seeds when more ran)."""
    seeds = max(judged, SEEDS)
    need = math.ceil(REQUIRED_SEEDS / SEEDS * seeds)
    if reached >= need:
        return True
    return False if judged - reached > seeds - need else None


def _per_seed_claim(table: Any, method: str, envs: list[str], claim: str) -> Finding:
    """Whether every env of ``envs`` reached the target within the budget on at least 4 of 5 seeds (``reached_80``).

    An env holds when one of its rows does, fails when its rows fail (2 of 5 seeds missed), and is unknown
    without rows or with too few judged seeds; the claim fails on one failing env, else is unknown on one unknown.
    """
    verdicts: dict[str, bool | None] = {}
    parts = []
    for env in envs:
        counts = _seed_counts(table, method, env)
        if not counts:
            continue
        row_verdicts = [_seed_verdict(k, n) for k, n in counts]
        verdicts[env] = True if True in row_verdicts else False if False in row_verdicts else None
        parts.append(f"{_short(env)} {', '.join(f'{k}/{n}' for k, n in counts)}")
    if not verdicts:
        return Finding(claim, None)
    detail = "seeds that reached it: " + "; ".join(parts)
    if False in verdicts.values():
        return Finding(claim, False, detail)
    unknown = [_short(e) for e in envs if verdicts.get(e) is None]
    if unknown:
        return Finding(claim, None, f"{detail}; no verdict yet (too few seeds run to the budget): {', '.join(unknown)}")
    return Finding(claim, True, detail)


def _reported(table: Any, method: str, envs: list[str], claim: str) -> Finding:
    """``method``'s results on ``envs`` (seeds that reached the target, the final success), with no verdict."""
    parts = []
    for env in envs:
        counts = _seed_counts(table, method, env)
        cell = [r for r in table.rows if r.method == method and r.env == env]
        finals = [st for r in cell if (st := r.stats.get("success")) is not None]
        if counts or finals:
            reached = ", ".join(f"{k}/{n} seeds" for k, n in counts) or "no seed run to the budget"
            final = ", ".join(f"{st.mean:.0f} % (min {st.min:.0f}, max {st.max:.0f})" for st in finals)
            parts.append(f"{_short(env)} {reached}, final {final}")
    return Finding(claim, None, "; ".join(parts))


def _claim(table: Any, method: str, envs: list[str], budget: int, claim: str) -> Finding:
    """Whether every env of ``envs`` reached the target with ``method`` within ``budget`` steps."""
    rows = [r for r in table.rows if r.method == method and r.env in envs]
    measured: dict[str, tuple[float, float]] = {}
    for r in rows:
        success, steps = r.stats.get("success"), r.stats.get("timesteps")
        if success is None or steps is None or steps.max > budget:
            continue
        best = measured.get(r.env)
        if best is None or success.mean > best[0]:
            measured[r.env] = (success.mean, steps.max)
    if not measured:
        return Finding(claim, None)
    detail = "; ".join(f"{_short(e)} {s:.0f} % at {n / 1000:g}k" for e, (s, n) in measured.items())
    missed = [e for e, (s, n) in measured.items() if s < TARGET_SUCCESS and n >= budget]
    short = [e for e, (s, n) in measured.items() if s < TARGET_SUCCESS and n < budget]  # cut short: no verdict
    absent = [e for e in envs if e not in measured or e in short]
    if missed:
        return Finding(claim, False, detail)
    if absent:
        return Finding(claim, None, f"{detail}; not run to the budget: {', '.join(_short(e) for e in absent)}")
    return Finding(claim, True, detail)


def sb3_findings(table: Any) -> list[Finding]:
    """The RL-readiness claims, and PPO's results beside them.

    SAC: every dense id reaches 80 % within 100k steps on at least 4 of 5
    training seeds, read from the per-trial ``reached_80`` (its mean over a
    cell's seeds times their number is the count): ``False`` as soon as one
    env misses on 2 seeds, ``None`` naming the envs with too few seeds run
    to the budget. SAC + HER: the mean final success of the goal Umaze
    (``None`` when not run or trained past the budget, ``False`` when trained
    to it below 80 %). PPO: reported per env (seeds that reached 80 % within
    100k, final success), no verdict.
    """
    budget = DEFAULT_TIMESTEPS["sac"] // 1000
    sac_claim = (
        f"SAC (SB3 defaults) reaches >= {TARGET_SUCCESS:.0f} % success within {budget}k steps on at least "
        f"{REQUIRED_SEEDS} of {SEEDS} training seeds, on every 2D dense env as registered"
    )
    her_claim = (
        f"SAC + HER reaches >= {TARGET_SUCCESS:.0f} % success on goal-conditioned Maze2D-Umaze within "
        f"{DEFAULT_TIMESTEPS['sac-her'] // 1000}k steps"
    )
    ppo_claim = (
        f"PPO (SB3 defaults) on the 2D dense envs: seeds reaching {TARGET_SUCCESS:.0f} % within "
        f"{DEFAULT_TIMESTEPS['ppo'] // 1000}k steps and final success (reported, no target)"
    )
    return [
        _per_seed_claim(table, "sac", dense_envs(), sac_claim),
        _claim(table, "sac-her", ["steer_envs/Maze2D-UmazeGoal-v0"], DEFAULT_TIMESTEPS["sac-her"], her_claim),
        _reported(table, "ppo", dense_envs(), ppo_claim),
    ]


SB3 = register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "stable-baselines3 with its defaults: SAC and PPO on every 2D dense env as registered, SAC + HER on "
            "goal-conditioned Maze2D-Umaze, 5 training seeds; success rate, learning curves and training steps/s "
            "(trials resume from cache_dir)."
        ),
        metrics=(
            Metric("success", "final success rate over the evaluation episodes (%)", fmt=".0f", goal=TARGET_SUCCESS),
            Metric(
                "steps_to_goal",
                f"first evaluated step with success >= {TARGET_SUCCESS:.0f} %",
                higher_is_better=False,
                fmt=".0f",
            ),
            Metric(
                "reached_80",
                f"1 if an evaluation within the method's budget reached {TARGET_SUCCESS:.0f} %, else 0 "
                "(mean over seeds: the share that did)",
                fmt=".2f",
            ),
            Metric("best_success", "best success rate of any evaluation (%)", fmt=".0f"),
            Metric("timesteps", "training steps done", fmt=".0f"),
            Metric("steps_per_s", "training steps per second (evaluations excluded)", "timing", True, ".1f"),
            Metric("wall_min", "wall time of the trial, evaluations included (min)", "timing", False, ".1f"),
        ),
        run_trial=run_sb3_trial,
        envs=_all_envs,
        methods=METHODS,
        params=Sb3Params(),
        trials_param="eval_episodes",
        default_seeds=SEEDS,
        generate=generate_sb3,
        references=(
            Reference("success", TARGET_SUCCESS, method="sac", source="RL-readiness target (100k steps)"),
            Reference("reached_80", REQUIRED_SEEDS / SEEDS, method="sac", source="RL-readiness target (4 of 5 seeds)"),
            Reference("success", TARGET_SUCCESS, method="sac-her", source="RL-readiness target (50k steps)"),
        ),
        plot="steer_envs.bench.suites.sb3.plots:plot_learning_curves",
        findings=sb3_findings,
    )
)
