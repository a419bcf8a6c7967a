"""``itps-kitchen-data``: a trial builds one shard into a tmp cache, a second finds it; merging; the CLI; parameters.

One sink episode (seed 1: the default tasks alternate microwave / sink) is
recorded for the module; the process's shard env is closed at the end.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bench_helpers import check_data_params, needs_robosuite

from steer_envs.bench.suites.itps_kitchen.suite import DATA_SUITE, ENV_ID, TASKS, DataParams

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::UserWarning")


def test_params_refuse_bad_values(monkeypatch: pytest.MonkeyPatch) -> None:
    check_data_params(DataParams, "max_skills", "itps-kitchen", monkeypatch)
    with pytest.raises(ValueError, match="tasks"):
        DataParams(tasks=("oven",))
    with pytest.raises(ValueError, match="tasks"):
        DataParams(tasks=())
    with pytest.raises(ValueError, match="tasks"):
        DataParams.from_json({"tasks": 3})


def test_suite_is_registered_and_seeds_alternate_tasks() -> None:
    from steer_envs.bench.suite import BUILTIN_SUITE_MODULES, get_suite
    from steer_envs.envs.robosuite.kitchen import KITCHEN_TASKS

    assert "steer_envs.bench.suites.itps_kitchen.suite" in BUILTIN_SUITE_MODULES
    suite = get_suite(DATA_SUITE)
    assert suite.envs == (ENV_ID,) and suite.default_seeds == 120 and suite.quick_seeds == 1
    params = suite.defaults
    assert isinstance(params, DataParams) and params.tasks == ("microwave", "sink") and TASKS == KITCHEN_TASKS
    assert [params.task_of(s) for s in range(4)] == ["microwave", "sink", "microwave", "sink"]
    assert DataParams.from_json({"tasks": ["sink"]}).task_of(7) == "sink"
    assert suite.resolve_params({}, base=suite.quick).tasks == ("sink",)


def test_shard_settings_name_and_check_their_fields() -> None:
    from steer_envs.data.kitchen_shards import ShardSettings, ensure_shard

    a, b = ShardSettings(3, "sink"), ShardSettings(3, "microwave")
    assert a.file_name().startswith("kitchen-sink-ep00003-") and a.digest == b.digest
    assert ShardSettings(3, "sink", 4).digest != a.digest
    with pytest.raises(ValueError, match="task"):
        ShardSettings(0, "oven")
    with pytest.raises(ValueError, match="seed"):
        ShardSettings(-1, "sink")
    with pytest.raises(TypeError, match="max_skills"):
        ShardSettings(0, "sink", 2.0)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="settings"):
        ensure_shard("/tmp", (0, "sink"))  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def envs() -> Iterator[None]:
    from steer_envs.data.kitchen_shards import close_envs

    yield
    close_envs()


@needs_robosuite
def test_trial_builds_a_shard_once_and_merging_reuses_it(tmp_path: Path, envs: Any) -> None:
    from steer_envs.bench.executors import execute_trial
    from steer_envs.bench.suite import get_suite
    from steer_envs.data.kitchen_shards import env_for, main, skills_dataset
    from steer_envs.data.kitchen_skills import load_skills, record_episode
    from steer_envs.data.trajectories import load_trajectories

    suite = get_suite(DATA_SUITE)
    trial = suite.trial(ENV_ID, None, 1, DataParams(cache_dir=str(tmp_path)))
    first = execute_trial(trial)
    assert first.ok and first.record is not None, first.error
    m = first.record["metrics"]
    assert m == {"skills": 2.0, "skill_success": 1.0, "violations": 0.0, "goal": 1.0, "steps": m["steps"], "built": 1.0}
    assert first.record["extra"]["task"] == "sink" and first.record["extra"]["skills"] == ["pick_bowl", "place_in_sink"]
    shard = Path(first.record["extra"]["shard"])
    assert shard.parent == tmp_path / "shards" and shard.name.startswith("kitchen-sink-ep00001-")
    stamp = shard.stat().st_mtime_ns
    again = execute_trial(trial)  # resumes: the shard is found, not rebuilt
    assert again.record is not None and again.record["metrics"]["built"] == 0.0 and shard.stat().st_mtime_ns == stamp
    # the same seed records the same skills (on the env that already ran them)
    stored = load_skills(shard)[0]
    fresh = record_episode(env_for("sink"), 1)
    for a, b in zip(stored, fresh, strict=True):
        assert a.name == b.name and np.array_equal(a.obs, b.obs) and np.array_equal(a.actions, b.actions)
        assert np.array_equal(a.yaw, b.yaw) and a.seed == b.seed == 1 and a.task == b.task == "sink"
    # merging the one shard of the sink-only cycle, then the plans CLI on it
    records, merged = skills_dataset(tmp_path, 2, ("sink",))  # seed 0 (sink here) is built, seed 1 found
    assert shard.stat().st_mtime_ns == stamp and len(records) == 4 and merged.parent == tmp_path
    assert [r.name for r in load_skills(merged)[0]] == [r.name for r in records]
    out = tmp_path / "plans.npz"
    assert main(["--cache-dir", str(tmp_path), "--episodes", "2", "--tasks", "sink", "--out", str(out)]) == 0
    data = load_trajectories(out)
    assert data.meta["skills"] == ["pick_bowl", "place_in_sink"] * 2 and data.meta["episode_seeds"] == [0, 0, 1, 1]


def test_skills_dataset_refuses_bad_input(tmp_path: Path) -> None:
    from steer_envs.data.kitchen_shards import env_for, skills_dataset

    with pytest.raises(ValueError, match="n_episodes"):
        skills_dataset(tmp_path, 0)
    with pytest.raises(TypeError, match="tasks"):
        skills_dataset(tmp_path, 1, "sink")
    with pytest.raises(ValueError, match="tasks"):
        skills_dataset(tmp_path, 1, ["oven"])
    with pytest.raises(TypeError, match="max_skills"):
        skills_dataset(tmp_path, 1, max_skills=None)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="task"):
        env_for("oven")


def test_every_task_records_each_task_from_the_same_scene(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from types import SimpleNamespace

    from steer_envs.bench.executors import execute_trial
    from steer_envs.bench.suite import get_suite
    from steer_envs.data import kitchen_shards as data

    params = DataParams(every_task=True)
    assert params.tasks_of(3) == ("microwave", "sink") and params.task_of(3) == "microwave"
    assert DataParams().tasks_of(3) == ("sink",)
    with pytest.raises(ValueError, match="every_task"):
        DataParams.from_json({"every_task": "yes"})
    calls: list[tuple[int, str]] = []
    last = {"microwave": "closed_microwave", "sink": "closed_sink"}

    def fake_shard(cache_dir: Any, settings: Any) -> tuple[list[Any], Path, bool]:
        calls.append((settings.seed, settings.task))
        record = SimpleNamespace(name="pick_bowl", success=True, violation=False, mode_after=last[settings.task])
        return [_Sized(record, 10)], tmp_path / f"{settings.task}-{settings.seed}.npz", True

    monkeypatch.setattr(data, "ensure_shard", fake_shard)
    trial = get_suite(DATA_SUITE).trial(ENV_ID, None, 3, DataParams(cache_dir=str(tmp_path), every_task=True))
    result = execute_trial(trial)
    assert result.ok and result.record is not None, result.error
    assert calls == [(3, "microwave"), (3, "sink")]
    assert result.record["metrics"]["skills"] == 2.0 and result.record["metrics"]["goal"] == 1.0
    assert result.record["extra"]["tasks"] == ["microwave", "sink"] and len(result.record["extra"]["shards"]) == 2
    calls.clear()
    monkeypatch.setattr(data, "record_shard", lambda settings: fake_shard(tmp_path, settings)[0])
    monkeypatch.setattr(data.ks, "save_skills", lambda path, records, meta: None)
    records, merged = data.skills_dataset(tmp_path, 2, every_task=True)
    assert calls == [(0, "microwave"), (0, "sink"), (1, "microwave"), (1, "sink")] and len(records) == 4
    assert merged.name.startswith("kitchen-skills-2allmicrowave-sink-")
    with pytest.raises(TypeError, match="every_task"):
        data.skills_dataset(tmp_path, 2, every_task="yes")  # type: ignore[arg-type]


class _Sized:
    """A skill record stand-in with a length (control steps)."""

    def __init__(self, record: Any, steps: int) -> None:
        self._record, self._steps = record, steps

    def __getattr__(self, name: str) -> Any:
        return getattr(self._record, name)

    def __len__(self) -> int:
        return self._steps


# ------------------------------------------------------------------ perturbed starts
#: the plain shards' digest (max_skills 8) before perturbed_starts existed: the shipped recipe's shards keep it.
PLAIN_DIGEST = "abfe7fb01d"


def test_perturbed_starts_is_a_separate_shard_and_leaves_plain_names_alone() -> None:
    from steer_envs.data.kitchen_shards import ShardSettings, shard_settings

    plain, pushed = ShardSettings(3, "sink"), ShardSettings(3, "sink", perturbed_starts=True)
    assert plain.digest == PLAIN_DIGEST and plain.file_name() == f"kitchen-sink-ep00003-{PLAIN_DIGEST}.npz"
    assert pushed.digest != plain.digest and pushed.file_name() == f"kitchen-sink-ep00003-push-{pushed.digest}.npz"
    assert ShardSettings(3, "sink", 4, True).digest != pushed.digest
    assert shard_settings(3, "sink") == [plain]
    assert shard_settings(3, "sink", 8, True) == [plain, pushed]
    with pytest.raises(TypeError, match="perturbed_starts"):
        ShardSettings(0, "sink", 8, "yes")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="perturbed_starts"):
        shard_settings(0, "sink", 8, 1)  # type: ignore[arg-type]
    assert DataParams().perturbed_starts is False
    with pytest.raises(ValueError, match="perturbed_starts"):
        DataParams.from_json({"perturbed_starts": "yes"})


def test_perturbed_starts_builds_the_pushed_shard_beside_the_plain_one(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from types import SimpleNamespace

    from steer_envs.bench.executors import execute_trial
    from steer_envs.bench.suite import get_suite
    from steer_envs.data import kitchen_shards as data

    calls: list[tuple[int, str, bool]] = []

    def fake_shard(cache_dir: Any, settings: Any) -> tuple[list[Any], Path, bool]:
        calls.append((settings.seed, settings.task, settings.perturbed_starts))
        record = SimpleNamespace(name="pick_bowl", success=True, violation=False, mode_after="closed_sink")
        return [_Sized(record, 10)], tmp_path / settings.file_name(), True

    monkeypatch.setattr(data, "ensure_shard", fake_shard)
    params = DataParams(cache_dir=str(tmp_path), tasks=("sink",), perturbed_starts=True)
    result = execute_trial(get_suite(DATA_SUITE).trial(ENV_ID, None, 2, params))
    assert result.ok, result.error
    record = result.record
    assert record is not None and calls == [(2, "sink", False), (2, "sink", True)]
    assert record["metrics"]["skills"] == 2.0
    assert [Path(p).stem.split("-")[3] for p in record["extra"]["shards"]] == [PLAIN_DIGEST, "push"]
    calls.clear()
    monkeypatch.setattr(data, "record_shard", lambda settings: fake_shard(tmp_path, settings)[0])
    saved: list[dict[str, Any]] = []
    monkeypatch.setattr(data.ks, "save_skills", lambda path, records, meta: saved.append(meta))
    records, merged = data.skills_dataset(tmp_path, 2, ("sink",), perturbed_starts=True)
    assert calls == [(0, "sink", False), (0, "sink", True), (1, "sink", False), (1, "sink", True)]
    assert len(records) == 4 and merged.name.startswith("kitchen-skills-2xsink-push-")
    assert saved[-1]["perturbed_starts"] is True and saved[-1]["push_distance"] == 0.15
    plain = data.skills_dataset(tmp_path, 2, ("sink",))[1]
    assert "push" not in plain.name and plain.name.endswith(f"-{PLAIN_DIGEST}.npz")
    assert "perturbed_starts" not in saved[-1]
    with pytest.raises(TypeError, match="perturbed_starts"):
        data.skills_dataset(tmp_path, 2, perturbed_starts="yes")  # type: ignore[arg-type]


@needs_robosuite
def test_a_perturbed_start_is_pushed_toward_the_skill_and_the_expert_goes_on_from_there(envs: Any) -> None:
    from steer_envs.data.kitchen_shards import env_for
    from steer_envs.data.kitchen_skills import PUSH_DISTANCE, PUSH_JITTER, push_toward_skill, record_episode

    env = env_for("sink")
    plain = record_episode(env, 1, max_skills=1)
    pushed = record_episode(env, 1, max_skills=1, perturbed_starts=True)
    assert [r.name for r in plain] == [r.name for r in pushed] == ["pick_bowl"]
    p, q = plain[0], pushed[0]
    moved = q.eef[0] - p.eef[0]
    length = float(np.linalg.norm(moved))
    assert 0.5 * PUSH_DISTANCE - 0.01 <= length <= PUSH_DISTANCE + 0.01  # the push, not a rest start
    bowl = p.obs[0, 9:12].astype(np.float64)
    toward = (bowl - p.eef[0]) / np.linalg.norm(bowl - p.eef[0])
    assert float(moved @ toward) / length > 0.9  # toward the bowl (the aim is jittered by a few cm)
    assert np.array_equal(q.obs[0, :3], q.eef[0].astype(np.float32))  # the record starts at the pushed pose
    assert np.allclose(q.obs[0, 9:12], p.obs[0, 9:12], atol=1e-3)  # the bowl was not touched
    assert q.success and not q.violation and q.mode_after == p.mode_after == "closed_held"
    again = record_episode(env, 1, max_skills=1, perturbed_starts=True)[0]
    assert np.array_equal(again.obs, q.obs) and np.array_equal(again.actions, q.actions)  # deterministic
    env.reset(seed=1)
    with pytest.raises(ValueError, match="skill"):
        push_toward_skill(env, "fly", np.random.default_rng(0))
    with pytest.raises(TypeError, match="rng"):
        push_toward_skill(env, "pick_bowl", 0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="distance"):
        push_toward_skill(env, "pick_bowl", np.random.default_rng(0), distance=-0.1)
    with pytest.raises(TypeError, match="perturbed_starts"):
        record_episode(env, 1, perturbed_starts="yes")  # type: ignore[arg-type]
    assert PUSH_JITTER < PUSH_DISTANCE / 2
