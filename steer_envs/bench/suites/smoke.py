"""``smoke``: scripted experts and step throughput on every registered env.

One trial = one env x one seed:

* the env's scripted expert runs ``episodes`` episodes (``gymnasium.make``,
  so the registered time limit applies): success rate, constraint-violation
  rate, episode length, expert+env steps/s;
* ``single_steps`` random-action steps of the single env give ``env_sps``;
* for the 2D kinematic envs, ``vec_steps`` random-action steps of
  ``gymnasium.make_vec(id, num_envs, vectorization_mode="vector_entry_point")``
  give ``vec_sps`` (agent-steps per second) and ``vec_speedup = vec_sps /
  env_sps``, both measured in the same trial (goal: >= 20x);
* for the robosuite envs (a sim step costs milliseconds, so ``single_steps``
  is not used there): ``raw_steps`` random-action steps of our env and as many
  of robosuite's raw env (``env.unwrapped.rs_env.step``, the same actions from
  the same seeded state), in alternating blocks of :data:`RAW_BLOCK_STEPS` so a
  change of machine load hits both; ``env_sps`` and ``raw_sps`` are the
  medians over the blocks, ``adapter_ratio = env_sps / raw_sps`` what the
  adapter keeps of the raw rate (goal: >= 0.9). ``render_frames`` 256x256
  RGB-D frames (``render_rgbd``) of a second env built with
  ``render_mode="rgb_array", fast_render=True`` give ``rgbd_ms``, the median
  ms per frame (goal: <= 30; 0 frames skips it).

Envs whose module does not exist yet are skipped with a note; an env whose
expert module is missing still gets its throughput measured.

>>> SmokeParams(episodes=3).to_json()
{'episodes': 3, 'single_steps': 2000, 'num_envs': 1024, 'vec_steps': 50, 'raw_steps': 200, 'render_frames': 10}
"""

from __future__ import annotations

import importlib.util
import statistics
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from steer_envs.bench.params import SuiteParams
from steer_envs.bench.suite import Finding, Metric, Suite, Trial, TrialPlan, TrialRequest, TrialResult, register_suite

EXPERT_PACKAGE = "steer_envs.data.experts"
#: entry-point module prefix of the envs that wrap a robosuite sim (raw-step and RGB-D measurements)
ROBOSUITE_PREFIX = "steer_envs.envs.robosuite."
#: steps per block of the interleaved env / raw-sim throughput measurement
RAW_BLOCK_STEPS = 50
#: side of the RGB-D frames timed for ``rgbd_ms`` (pixels)
RGBD_SIZE = 256
#: goals of the robosuite adapter: share of the raw step rate kept, ms per RGB-D frame
ADAPTER_RATIO_GOAL = 0.9
RGBD_MS_GOAL = 30.0


@dataclass(frozen=True)
class SmokeParams(SuiteParams):
    """Parameters of ``smoke``: expert episodes and the random-action step counts of the throughput runs.

    ``raw_steps`` (steps of each of our env and the raw sim, rounded down to
    whole blocks of :data:`RAW_BLOCK_STEPS`, at least one) and ``render_frames``
    (0 skips the RGB-D timing) apply to the robosuite envs only. Each count is
    bounded (episodes <= 10^5, single_steps <= 10^7, num_envs <= 2^20,
    vec_steps <= 10^6, raw_steps <= 10^5, render_frames <= 1000) so a typo
    cannot exhaust memory or run for days.
    """

    suite_name: ClassVar[str] = "smoke"
    episodes: int = 10
    single_steps: int = 2000
    num_envs: int = 1024
    vec_steps: int = 50
    raw_steps: int = 200
    render_frames: int = 10

    def __post_init__(self) -> None:
        self.require_at_least(0, "episodes", "render_frames")
        self.require_at_least(1, "single_steps", "num_envs", "vec_steps", "raw_steps")
        self.require_at_most(100_000, "episodes")
        self.require_at_most(10_000_000, "single_steps")
        self.require_at_most(1 << 20, "num_envs")
        self.require_at_most(1_000_000, "vec_steps")
        self.require_at_most(100_000, "raw_steps")
        self.require_at_most(1000, "render_frames")


def _registered_envs() -> list[str]:
    import steer_envs

    return steer_envs.env_ids()


def _missing_env_module(env_id: str) -> str | None:
    """Name of the env's entry-point module when it cannot be found, else ``None``."""
    from steer_envs.envs.registry import entry

    e = entry(env_id)
    for point in (e.entry_point, e.vector_entry_point):
        if point is None:
            continue
        module = point.split(":")[0]
        try:
            if importlib.util.find_spec(module) is None:
                return module
        except ModuleNotFoundError:
            return module
    return None


def _plan_smoke(suite: Suite, request: TrialRequest) -> TrialPlan:
    from steer_envs.data.experts import has_expert

    params: SmokeParams = suite.resolve_params(request.params, request.trials, base=request.base)
    trials: list[Trial] = []
    notes: list[str] = []
    for env_id in request.envs:
        assert env_id is not None
        missing = _missing_env_module(env_id)
        if missing is not None:
            notes.append(f"skipped {env_id}: module {missing} does not exist (yet)")
            continue
        if not has_expert(env_id):
            notes.append(f"{env_id}: no scripted expert; throughput only")
        for method in request.methods:
            trials += [suite.trial(env_id, method, seed, params) for seed in suite.seed_list(request)]
    return TrialPlan(tuple(trials), tuple(notes))


def _episode_seed(seed: int, episode: int) -> int:
    """Independent reset seed of episode ``episode`` of trial ``seed``."""
    return int(np.random.SeedSequence([seed, episode]).generate_state(1)[0])


def _expert_episodes(env: Any, expert: Any, seed: int, episodes: int) -> dict[str, float]:
    successes = violations = steps = 0
    t0 = time.perf_counter()
    for ep in range(episodes):
        obs, info = env.reset(seed=_episode_seed(seed, ep))
        expert.reset(obs, info)
        violated = False
        while True:
            obs, _, terminated, truncated, info = env.step(expert.act(obs, info))
            steps += 1
            violated |= bool(info.get("constraint_violation", False))
            if terminated or truncated:
                break
        successes += bool(info.get("success", False))
        violations += violated
    elapsed = time.perf_counter() - t0
    return {
        "success_rate": successes / episodes,
        "violation_rate": violations / episodes,
        "episode_len": steps / episodes,
        "expert_sps": steps / max(elapsed, 1e-9),
    }


def _single_throughput(env: Any, seed: int, steps: int) -> float:
    """Random-action steps per second of a single env (resets included)."""
    env.action_space.seed(seed)
    actions = [env.action_space.sample() for _ in range(steps)]
    env.reset(seed=seed)
    env.step(actions[0])  # warm-up (lazy initialisation)
    env.reset(seed=seed)
    t0 = time.perf_counter()
    for action in actions:
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / max(time.perf_counter() - t0, 1e-9)


def _is_robosuite(env_id: str) -> bool:
    """Whether ``env_id``'s env wraps a robosuite sim (``env.unwrapped.rs_env``)."""
    from steer_envs.envs.registry import entry

    return entry(env_id).entry_point.startswith(ROBOSUITE_PREFIX)


def _raw_throughput(env: Any, seed: int, steps: int) -> tuple[float, float]:
    """``(env_sps, raw_sps)``: our env's and robosuite's raw steps/s on the same random actions.

    Blocks of :data:`RAW_BLOCK_STEPS` alternate (which one goes first flips
    every block); before each block both start from the same seeded reset
    (untimed), so both run the same physics. Medians over the blocks.
    """
    raw = env.unwrapped.rs_env
    block = min(RAW_BLOCK_STEPS, steps)
    blocks = max(1, steps // block)
    env.action_space.seed(seed)
    actions = [[env.action_space.sample() for _ in range(block)] for _ in range(blocks)]

    def timed(step: Any, b: int) -> float:
        env.reset(seed=_episode_seed(seed, b))
        t0 = time.perf_counter()
        for action in actions[b]:
            step(action)
        return block / max(time.perf_counter() - t0, 1e-9)

    env.reset(seed=seed)
    env.step(actions[0][0])  # warm-up (lazy initialisation) of both paths
    raw.step(actions[0][0])
    env_rates: list[float] = []
    raw_rates: list[float] = []
    for b in range(blocks):
        order = ((env.step, env_rates), (raw.step, raw_rates))
        for step, rates in order if b % 2 == 0 else order[::-1]:
            rates.append(timed(step, b))
    return statistics.median(env_rates), statistics.median(raw_rates)


def _rgbd_ms(env_id: str, seed: int, frames: int) -> float:
    """Median ms of one ``RGBD_SIZE`` RGB-D frame (``render_rgbd``) of a fresh ``fast_render`` env."""
    import gymnasium as gym

    env = gym.make(env_id, render_mode="rgb_array", render_size=RGBD_SIZE, fast_render=True)
    try:
        env.action_space.seed(seed)
        env.reset(seed=seed)
        base: Any = env.unwrapped
        base.render_rgbd()  # warm-up (the first frame sets the renderer up)
        times = []
        for _ in range(frames):
            env.step(env.action_space.sample())  # a new state per frame (untimed)
            t0 = time.perf_counter()
            base.render_rgbd()
            times.append(time.perf_counter() - t0)
        return 1e3 * statistics.median(times)
    finally:
        env.close()


def _vector_throughput(env_id: str, seed: int, num_envs: int, steps: int) -> float:
    """Random-action agent-steps per second of the batched env (autoreset included)."""
    import gymnasium as gym

    venv = gym.make_vec(env_id, num_envs=num_envs, vectorization_mode="vector_entry_point")
    try:
        venv.action_space.seed(seed)
        actions = [venv.action_space.sample() for _ in range(steps)]
        venv.reset(seed=seed)
        venv.step(actions[0])  # warm-up
        venv.reset(seed=seed)
        t0 = time.perf_counter()
        for action in actions:
            venv.step(action)
        return steps * num_envs / max(time.perf_counter() - t0, 1e-9)
    finally:
        venv.close()


def run_smoke_trial(trial: Trial) -> TrialResult:
    """Expert episodes and throughput of ``trial.env`` (see the module docstring)."""
    import gymnasium as gym

    import steer_envs  # noqa: F401 - registers the envs in this (possibly fresh worker) process
    from steer_envs.data.experts import has_expert, make_expert
    from steer_envs.envs.registry import entry

    params = SmokeParams.from_json(trial.params)
    env_id = str(trial.env)
    metrics: dict[str, float | None] = {m.name: None for m in SMOKE.metrics}
    extra: dict[str, Any] = {}
    env = gym.make(env_id)
    try:
        expert = None
        if has_expert(env_id) and params.episodes > 0:
            try:
                expert = make_expert(env)
            except ModuleNotFoundError as exc:
                if not (exc.name or "").startswith(EXPERT_PACKAGE):
                    raise
                extra["note"] = f"expert module {exc.name} does not exist (yet)"
        if expert is not None:
            metrics.update(_expert_episodes(env, expert, trial.seed, params.episodes))
        if _is_robosuite(env_id):
            env_sps, raw_sps = _raw_throughput(env, trial.seed, params.raw_steps)
            metrics.update(env_sps=env_sps, raw_sps=raw_sps, adapter_ratio=env_sps / raw_sps)
        else:
            metrics["env_sps"] = _single_throughput(env, trial.seed, params.single_steps)
    finally:
        env.close()
    if _is_robosuite(env_id) and params.render_frames > 0:
        metrics["rgbd_ms"] = _rgbd_ms(env_id, trial.seed, params.render_frames)
    if entry(env_id).kinematic and entry(env_id).vector_entry_point:
        num_envs = params.num_envs
        metrics["vec_sps"] = _vector_throughput(env_id, trial.seed, num_envs, params.vec_steps)
        metrics["vec_speedup"] = metrics["vec_sps"] / metrics["env_sps"]  # type: ignore[operator]
        extra["num_envs"] = num_envs
    return TrialResult(metrics, extra)


def smoke_findings(table: Any) -> list[Finding]:
    """The robosuite adapter's claims: it keeps >= 90 % of the raw step rate; an RGB-D frame costs <= 30 ms."""
    claims = (
        ("adapter_ratio", f"the robosuite adapter keeps >= {ADAPTER_RATIO_GOAL:g}x robosuite's raw step rate"),
        ("rgbd_ms", f"a {RGBD_SIZE}x{RGBD_SIZE} RGB-D frame (fast_render) takes <= {RGBD_MS_GOAL:g} ms"),
    )
    declared = {m.name: m for m in table.metrics}
    findings = []
    for name, claim in claims:
        means = [(r.label(), stat.mean) for r in table.rows if (stat := r.stats.get(name)) is not None]
        if not means or name not in declared:
            findings.append(Finding(claim, None))
            continue
        metric = declared[name]
        holds = all(metric.meets_goal(mean) for _, mean in means)
        findings.append(Finding(claim, holds, ", ".join(f"{label} {mean:{metric.fmt}}" for label, mean in means)))
    return findings


def plot_throughput(suite: Suite, records: Sequence[Mapping[str, Any]], out_dir: str) -> list[str]:
    """Per-suite figure: single vs. vectorized steps/s per env (log scale), speed-up on top."""
    from steer_envs.bench.report import summarize
    from steer_envs.utils.plots import figure_legend, new_figure, save_figure

    tables = [t for t in summarize(records) if t.suite == suite.name]
    if not tables:
        return []
    rows = [r for r in tables[0].rows if r.stats.get("env_sps") is not None]
    if not rows:
        return []
    fig = new_figure(max(6.0, 1.2 * len(rows) + 2.0), 4.5)
    ax = fig.add_subplot()
    xs = np.arange(len(rows))
    single = [r.stats["env_sps"].mean for r in rows]  # type: ignore[union-attr]
    vector = [r.stats["vec_sps"].mean if r.stats.get("vec_sps") else 0.0 for r in rows]  # type: ignore[union-attr]
    ax.bar(xs - 0.2, single, 0.4, label="single env (gymnasium.make)", color="#4C72B0")
    ax.bar(xs + 0.2, vector, 0.4, label="vectorized (make_vec)", color="#DD8452")
    for x, s, v in zip(xs, single, vector, strict=True):
        if v > 0:
            ax.annotate(f"{v / s:.0f}x", (x + 0.2, v), ha="center", va="bottom", fontsize=8)
    ax.set_yscale("log")
    ax.set_xticks(xs)
    ax.set_xticklabels([r.label() for r in rows], rotation=30, ha="right")
    ax.set_ylabel("steps / s (random actions)")
    ax.set_title("smoke: step throughput, single vs. vectorized", fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    figure_legend(fig, ax.get_legend_handles_labels()[0], fontsize=8)  # below the axes: covers no bar
    return [str(save_figure(fig, Path(out_dir) / f"{suite.name}_throughput.png"))]


SMOKE = register_suite(
    Suite(
        name="smoke",
        description=(
            "Scripted experts on every registered env: success and step throughput (single vs. vectorized; "
            "robosuite: adapter vs. raw sim, RGB-D frame time)."
        ),
        metrics=(
            Metric("success_rate", "fraction of expert episodes that succeed", fmt=".2f"),
            Metric(
                "violation_rate",
                "fraction of expert episodes with a constraint violation",
                higher_is_better=False,
                fmt=".2f",
            ),
            Metric("episode_len", "mean expert episode length (steps)", higher_is_better=False, fmt=".1f"),
            Metric("expert_sps", "expert + env steps/s (single env)", kind="timing", fmt=".0f"),
            Metric("env_sps", "single-env steps/s, random actions (gymnasium.make)", kind="timing", fmt=".0f"),
            Metric("vec_sps", "vectorized agent-steps/s, random actions (make_vec)", kind="timing", fmt=".0f"),
            Metric("vec_speedup", "vec_sps / env_sps, same trial", kind="timing", fmt=".1f", goal=20.0),
            Metric(
                "raw_sps",
                "robosuite's raw env steps/s, same actions, interleaved with env_sps",
                kind="timing",
                fmt=".0f",
            ),
            Metric(
                "adapter_ratio",
                "env_sps / raw_sps, same trial (robosuite envs)",
                kind="timing",
                fmt=".2f",
                goal=ADAPTER_RATIO_GOAL,
            ),
            Metric(
                "rgbd_ms",
                f"ms per {RGBD_SIZE}x{RGBD_SIZE} RGB-D frame, fast_render (robosuite envs)",
                kind="timing",
                higher_is_better=False,
                fmt=".1f",
                goal=RGBD_MS_GOAL,
            ),
        ),
        run_trial=run_smoke_trial,
        envs=_registered_envs,
        methods=("expert",),
        params=SmokeParams(),
        trials_param="episodes",
        default_seeds=3,
        generate=_plan_smoke,
        quick={"episodes": 3, "single_steps": 1000, "vec_steps": 20},
        quick_seeds=1,
        plot=plot_throughput,
        findings=smoke_findings,
    )
)
