"""BlockStack skill records: a short episode, bit-identical save/load, corrupt files refused, determinism, conversion.

One env and one 3-skill episode for the module (env creation takes seconds).
"""

from __future__ import annotations

import zipfile
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from robosuite_helpers import ROBOSUITE_MARKS, module_env

from steer_envs.envs.robosuite.blockstack import SKILLS
from steer_envs.io import DatasetError

pytestmark = ROBOSUITE_MARKS
SEED = 3
env = module_env("steer_envs.data.blockstack_skills:make_env")


@pytest.fixture(scope="module")
def records(env: Any) -> list[Any]:
    from steer_envs.data.blockstack_skills import record_episode

    return record_episode(env, SEED, 3)


def _same(a: Any, b: Any) -> None:
    for f in fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y), f.name
        else:
            assert x == y, f.name


def test_episode_records_one_entry_per_skill(records: list[Any]) -> None:
    from steer_envs.data.blockstack_skills import OBS_DIM, ONTO_NONE

    assert [r.index for r in records] == [0, 1, 2] and all(r.seed == SEED for r in records)
    assert records[0].kind == "pick" and records[0].onto == ONTO_NONE and records[1].kind == "place"
    for r in records:
        assert r.name in SKILLS and r.success and not r.violation
        t = len(r)
        assert t > 10 and r.obs.shape == (t + 1, OBS_DIM) and r.actions.shape == (t, 7)
        assert r.eef.shape == (t + 1, 3) and r.gripper.shape == (t + 1,) and r.modes.shape == (t + 1,)
        assert np.allclose(r.obs[:, :3], r.eef, atol=1e-5)  # the obs starts with the eef position
    pick = records[0]
    assert pick.modes[0] == 0 and pick.modes[-1] == 1 + pick.cube  # free -> holding_cube
    assert np.linalg.norm(pick.eef[-1, :2] - pick.target[:2]) < 0.02  # it lifted the cube where it stood
    assert np.array_equal(records[1].obs[0], records[0].obs[-1])  # skills chain state to state


def test_same_seed_records_the_same_skills(env: Any, records: list[Any]) -> None:
    from steer_envs.data.blockstack_skills import record_episode

    again = record_episode(env, SEED, 2)
    for a, b in zip(records[:2], again, strict=True):
        _same(a, b)


def test_save_load_round_trip_is_bit_identical(records: list[Any], tmp_path: Path) -> None:
    from steer_envs.data.blockstack_skills import load_skills, save_skills

    path = save_skills(tmp_path / "s.npz", records, {"note": "x"})
    back, meta = load_skills(path)
    assert meta["note"] == "x" and meta["skills"] == list(SKILLS) and len(back) == len(records)
    for a, b in zip(records, back, strict=True):
        _same(a, b)
    assert not [p for p in tmp_path.iterdir() if p.name != "s.npz"]  # no temp file left behind


def test_corrupt_files_raise_dataset_error_naming_file_and_field(records: list[Any], tmp_path: Path) -> None:
    from steer_envs.data.blockstack_skills import load_skills, save_skills

    good = save_skills(tmp_path / "good.npz", records)
    torn = tmp_path / "torn.npz"
    torn.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(DatasetError, match=r"torn\.npz"):
        load_skills(torn)
    garbled = tmp_path / "garbled.npz"
    garbled.write_bytes(b"not a zip at all" * 10)
    with pytest.raises(DatasetError, match=r"garbled\.npz"):
        load_skills(garbled)
    with np.load(good) as z:
        arrays = {k: z[k] for k in z.files}

    def write(name: str, **changes: Any) -> Path:
        path = tmp_path / name
        with zipfile.ZipFile(path, "w") as zf:
            for k, v in {**arrays, **changes}.items():
                with zf.open(f"{k}.npy", "w") as fh:
                    np.lib.format.write_array(fh, np.asarray(v))
        return path

    nan_obs = arrays["obs"].copy()
    nan_obs[5, 7] = np.nan
    with pytest.raises(DatasetError, match=r"nan.npz: array 'obs' holds NaN"):
        load_skills(write("nan.npz", obs=nan_obs))
    with pytest.raises(DatasetError, match=r"narrow.npz: array 'obs' has width 32"):
        load_skills(write("narrow.npz", obs=arrays["obs"][:, :32]))
    with pytest.raises(DatasetError, match=r"ints.npz: array 'eef' has dtype int64"):
        load_skills(write("ints.npz", eef=arrays["eef"].astype(np.int64)))
    with pytest.raises(DatasetError, match=r"short.npz: array 'actions' has"):
        load_skills(write("short.npz", actions=arrays["actions"][:-1]))
    with pytest.raises(DatasetError, match=r"cube.npz: arrays 'cube'/'onto' of skill 0"):
        load_skills(write("cube.npz", cube=(arrays["cube"] + 1) % 4))
    with pytest.raises(DatasetError, match=r"missing.npz: missing arrays \['gripper'\]"):
        load_skills(_drop(tmp_path, arrays, "gripper"))


def _drop(tmp_path: Path, arrays: dict[str, np.ndarray], key: str) -> Path:
    path = tmp_path / "missing.npz"
    np.savez(path, **{k: v for k, v in arrays.items() if k != key})
    return path


def test_bad_arguments_name_them(env: Any, records: list[Any], tmp_path: Path) -> None:
    from steer_envs.data.blockstack_skills import record_episode, save_skills, to_trajectory_dataset

    with pytest.raises(ValueError, match="n_skills"):
        record_episode(env, 0, 0)
    with pytest.raises(ValueError, match="seed"):
        record_episode(env, -1, 1)
    with pytest.raises(TypeError, match="env"):
        record_episode(object(), 0, 1)
    with pytest.raises(ValueError, match="path"):
        save_skills(tmp_path / "s.txt", records)
    with pytest.raises(ValueError, match="records"):
        save_skills(tmp_path / "s.npz", [])
    with pytest.raises(ValueError, match=r"records\[0\]"):
        save_skills(tmp_path / "s.npz", [replace(records[0], name="pick_3")])
    with pytest.raises(TypeError, match="successful_only"):
        to_trajectory_dataset(records, successful_only="yes")


def test_trajectory_dataset_has_one_episode_per_skill(records: list[Any]) -> None:
    from steer_envs.data.blockstack_skills import to_trajectory_dataset

    ds = to_trajectory_dataset(records)
    assert len(ds.episode_starts) == 3 and len(ds) == sum(len(r) for r in records)
    assert ds.obs_dim == 33 and ds.action_dim == 4 and ds.meta["skills"] == [r.name for r in records]
    first = records[0]
    assert np.allclose(ds.actions[: len(first), :3], first.eef[1:]) and np.array_equal(ds.observations[0], first.obs[0])
    plain = to_trajectory_dataset(records, gripper=False)
    assert plain.action_dim == 3 and plain.action_obs_indices == (0, 1, 2)


def test_branches_start_from_the_main_episodes_states_and_do_other_skills(env: Any, records: list[Any]) -> None:
    from steer_envs.data.blockstack_skills import record_branches

    recs = record_branches(env, SEED, 2, 1)
    main, extra = recs[:2], recs[2:]
    for a, b in zip(main, records[:2], strict=True):
        _same(a, b)  # the main line is record_episode's
    assert [r.index for r in extra] == [0, 1]
    for r in extra:
        assert np.array_equal(r.obs[0], main[r.index].obs[0]) and r.name != main[r.index].name
        assert r.kind == main[r.index].kind and r.success and not r.violation
    with pytest.raises(ValueError, match="branches"):
        record_branches(env, SEED, 1, -1)
