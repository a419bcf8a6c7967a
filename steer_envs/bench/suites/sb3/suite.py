"""``sb3``: can an RL user train stable-baselines3 agents on the library's envs with SB3's defaults?

Method ``sac``: ``SAC("MlpPolicy", env)`` with every SB3 default on each 2D
dense env (the registered ids ending ``Dense-v0``, not the goal ones); method
``sac-her``: SAC with ``HerReplayBuffer`` (SB3's default ``future`` strategy,
4 sampled goals) on the goal-conditioned ``steer_envs/Maze2D-UmazeGoal-v0``
(sparse reward). A trial trains one agent for ``timesteps`` steps (default
100k for ``sac``, 50k for ``sac-her``, the RL-readiness budgets), evaluates it
deterministically on ``eval_episodes`` episodes every ``eval_every`` steps
(success = ``info["is_success"]`` at the episode's end) and reports the final
success rate, the first step an evaluation reached 80 %, training steps/s and
wall time; the curve is kept in the record for the learning-curve figure.

Env options (``--param``): ``normalize_actions`` (``[-1, 1]`` actions, which
SAC's tanh policy assumes; default on); ``observe_sensors`` (the task's
sensor bits in the observation, which makes task memory such as "soup on the
spoon" observable; default on, ignored on Maze2D, whose sensors carry no
memory and whose ``at_goal`` bit would contradict HER's relabelled goals);
``maze_goal_obs``: with it (default) a ``sac`` trial on Maze2D's plain
``...Dense-v0`` ids trains and evaluates on the ``...GoalDense-v0`` sibling
(same maze, dynamics and dense reward) flattened to a Box for ``MlpPolicy``,
as the recorded results did; without it, on the plain id, whose observation
also carries the goal (``observe_goal``). ``maze_relative_actions``: Maze2D's
action is the waypoint's offset from the agent (``relative_actions``) instead
of the absolute waypoint. ``max_episode_steps``: truncate training and
evaluation episodes there instead of at the id's registered limit (0, the
default).

Training is long on a CPU (tens of steps/s per thread), so a trial
checkpoints (model, replay buffer, curve) at every evaluation under
``cache_dir`` and a killed run resumes there; see
:mod:`steer_envs.baselines.sb3`, the library code every trial calls. ``stop_success`` (off by
default) ends a trial once an evaluation reaches that success rate.

>>> Sb3Params().budget("sac"), Sb3Params().budget("sac-her"), Sb3Params(timesteps=500).budget("sac")
(100000, 50000, 500)
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from steer_envs.baselines.sb3 import GOAL_ENVS, METHODS, Sb3Options, Sb3Settings, method_fits, train_and_evaluate
from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Reference, Suite, TrialPlan, TrialResult, register_suite
from steer_envs.io import default_cache_dir
from steer_envs.utils.fields import build_from

if TYPE_CHECKING:
    from steer_envs.bench.suite import Trial, TrialRequest

__all__ = ["DEFAULT_TIMESTEPS", "SB3", "Sb3Params", "dense_envs", "sb3_findings"]

SUITE_NAME = "sb3"
#: the RL-readiness budgets: SAC within 100k steps, SAC + HER within 50k
DEFAULT_TIMESTEPS: dict[str, int] = {"sac": 100_000, "sac-her": 50_000}
#: the RL-readiness success threshold (%)
TARGET_SUCCESS = 80.0
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

    ``timesteps``: training steps per trial (``None``: 100k for ``sac``, 50k for
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
            f"sb3: no env fits the chosen methods {list(request.methods)}: 'sac' runs on the ...Dense-v0 ids, "
            f"'sac-her' on {list(GOAL_ENVS)}"
        )
    trials = tuple(suite.trial(e, m, s, params) for e, m in pairs for s in suite.seed_list(request))
    skipped = len(request.envs) * len(request.methods) - len(pairs)
    notes = (f"{skipped} env x method pairs skipped: sac runs on the dense ids, sac-her on the goal ids",)
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


def _short(env: str | None) -> str:
    return (env or "-").split("/", 1)[-1]


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
    """The two RL-readiness claims, judged on the final success of each env (mean over seeds).

    A claim is ``None`` when none of its cells ran (or all trained past the
    budget), ``False`` as soon as one env trained to the budget misses 80 %,
    and ``None`` with the missing envs named when every measured env made it
    but some did not run (or stopped short of the budget below 80 %).
    """
    sac_claim = (
        f"SAC (SB3 defaults) reaches >= {TARGET_SUCCESS:.0f} % success on every 2D dense env within "
        f"{DEFAULT_TIMESTEPS['sac'] // 1000}k steps"
    )
    her_claim = (
        f"SAC + HER reaches >= {TARGET_SUCCESS:.0f} % success on goal-conditioned Maze2D-Umaze within "
        f"{DEFAULT_TIMESTEPS['sac-her'] // 1000}k steps"
    )
    return [
        _claim(table, "sac", dense_envs(), DEFAULT_TIMESTEPS["sac"], sac_claim),
        _claim(table, "sac-her", ["steer_envs/Maze2D-UmazeGoal-v0"], DEFAULT_TIMESTEPS["sac-her"], her_claim),
    ]


SB3 = register_suite(
    Suite(
        name=SUITE_NAME,
        description=(
            "stable-baselines3 with its defaults: SAC on every 2D dense env, SAC + HER on goal-conditioned "
            "Maze2D-Umaze; success rate, learning curves and training steps/s (trials resume from cache_dir)."
        ),
        metrics=(
            Metric("success", "final success rate over the evaluation episodes (%)", fmt=".0f", goal=TARGET_SUCCESS),
            Metric(
                "steps_to_goal",
                f"first evaluated step with success >= {TARGET_SUCCESS:.0f} %",
                higher_is_better=False,
                fmt=".0f",
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
        default_seeds=1,
        generate=generate_sb3,
        references=(
            Reference("success", TARGET_SUCCESS, method="sac", source="RL-readiness target (100k steps)"),
            Reference("success", TARGET_SUCCESS, method="sac-her", source="RL-readiness target (50k steps)"),
        ),
        plot="steer_envs.bench.suites.sb3.plots:plot_learning_curves",
        findings=sb3_findings,
    )
)
