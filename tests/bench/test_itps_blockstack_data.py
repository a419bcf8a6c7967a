"""``itps-blockstack-data``: a trial builds one shard into a tmp cache, a second finds it; merging; parameters."""

from __future__ import annotations

from pathlib import Path

import pytest
from bench_helpers import check_data_params, needs_robosuite

from steer_envs.bench.suites.itps_blockstack.suite import DATA_SUITE, ENV_ID, DataParams

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning", "ignore::UserWarning")


def test_params_refuse_bad_values(monkeypatch: pytest.MonkeyPatch) -> None:
    check_data_params(DataParams, "skills_per_episode", "itps-blockstack", monkeypatch)


def test_suite_is_registered() -> None:
    from steer_envs.bench.suite import get_suite

    suite = get_suite(DATA_SUITE)
    assert suite.envs == (ENV_ID,) and suite.default_seeds == 50 and suite.defaults.skills_per_episode == 12


@needs_robosuite
def test_trial_builds_a_shard_once_and_merging_reuses_it(tmp_path: Path) -> None:
    from steer_envs.bench.executors import execute_trial
    from steer_envs.bench.suite import get_suite
    from steer_envs.data.blockstack_shards import skills_dataset
    from steer_envs.data.blockstack_skills import load_skills

    suite = get_suite(DATA_SUITE)
    trial = suite.trial(ENV_ID, None, 0, DataParams(skills_per_episode=2, cache_dir=str(tmp_path)))
    first = execute_trial(trial)
    assert first.ok, first.error
    m = first.record["metrics"]
    assert m["skills"] == 2.0 and m["built"] == 1.0 and 0.0 <= m["skill_success"] <= 1.0
    shard = Path(first.record["extra"]["shard"])
    assert shard.parent == tmp_path / "shards" and load_skills(shard)[0][0].seed == 0
    again = execute_trial(trial)
    assert again.record["metrics"]["built"] == 0.0 and again.record["metrics"]["skill_success"] == m["skill_success"]
    stamp = shard.stat().st_mtime_ns
    records, merged = skills_dataset(tmp_path, 1, 2)  # the shard exists: nothing is recorded
    assert shard.stat().st_mtime_ns == stamp and len(records) == 2 and merged.parent == tmp_path
    assert [r.name for r in load_skills(merged)[0]] == [r.name for r in records]


def test_branched_shards_have_their_own_names_and_unbranched_ones_keep_theirs() -> None:
    from steer_envs.data.blockstack_shards import ShardSettings

    assert ShardSettings(3, 12).file_name() == ShardSettings(3, 12, 0).file_name()
    assert ShardSettings(3, 12).digest == "8ddf641272"  # the name shards had before branches existed
    assert ShardSettings(3, 12, 3).digest != ShardSettings(3, 12).digest
    with pytest.raises(ValueError, match="branches"):
        DataParams(branches=-1)
