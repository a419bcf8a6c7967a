"""Dataset files (trajectories, Maze2D random walks, GLiDE counterfactual data): checked loads, DatasetError."""

from __future__ import annotations

import io
import json
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from samples import tiny_counterfactual

from steer_envs.data.counterfactual_dataset import CounterfactualDataset
from steer_envs.data.datasets import load_dataset
from steer_envs.data.maze_random_walk import generate_random_walk, load_random_walk, save_random_walk
from steer_envs.data.trajectories import DatasetError, TrajectoryDataset, load_trajectories, save_trajectories


def _npz(path: Path, **arrays: Any) -> Path:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())
    return path


def _arrays(path: Path) -> dict[str, np.ndarray]:
    with np.load(path, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


@pytest.fixture(scope="module")
def walk_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return save_random_walk(
        generate_random_walk("umaze", 80, seed=0, progress=False), tmp_path_factory.mktemp("w") / "w.npz"
    )


#: loader name -> (load, write a good file)
def _good_traj(path: Path) -> Path:
    return save_trajectories(TrajectoryDataset(np.zeros((6, 2)), np.ones((6, 2)), meta={"seed": 1}), path)


LOADERS: dict[str, Callable[[Path], Any]] = {
    "trajectories": load_trajectories,
    "random_walk": load_random_walk,
    "counterfactual": CounterfactualDataset.load,
}


@pytest.mark.parametrize("name", sorted(LOADERS))
def test_foreign_missing_and_pickled_files(name: str, tmp_path: Path) -> None:
    load = LOADERS[name]
    with pytest.raises(DatasetError, match=r"missing.npz"):
        load(tmp_path / "missing.npz")
    foreign = _npz(tmp_path / "foreign.npz", x=np.zeros(3), meta=np.array("{}"))
    with pytest.raises(DatasetError, match=r"foreign.npz"):
        load(foreign)
    pickled = _npz(tmp_path / "pickled.npz", meta=np.array([{"a": 1}], dtype=object))
    with pytest.raises(DatasetError, match=r"pickled.npz.*pickled objects are never loaded"):
        load(pickled)
    (tmp_path / "text.npz").write_text("hello")
    with pytest.raises(DatasetError, match=r"text.npz"):
        load(tmp_path / "text.npz")
    assert issubclass(DatasetError, ValueError)


def test_trajectory_files(tmp_path: Path) -> None:
    good = _good_traj(tmp_path / "t.npz")
    arrays = _arrays(good)
    assert load_trajectories(good).meta == {"seed": 1}
    cases: list[tuple[dict[str, Any], str]] = [
        ({"header": np.array("{not json")}, "'header' is not JSON"),
        ({"header": np.array("[]")}, "must be a JSON object"),
        ({"header": np.array(json.dumps({"format": "other/1"}))}, "format 'other/1'"),
        ({"observations": np.array(["a", "b"])}, "'observations' has dtype"),
        ({"observations": np.full((6, 2), np.nan)}, "finite"),
        ({"actions": np.zeros((5, 2))}, "actions must have shape"),
        ({"episode_starts": np.array([0.0])}, "'episode_starts' has dtype"),
        ({"episode_starts": np.array([3, 1])}, "episode_starts must be increasing"),
    ]
    for change, match in cases:
        bad = _npz(tmp_path / "bad.npz", **{**arrays, **change})
        with pytest.raises(DatasetError, match=f"bad.npz.*{match}"):
            load_trajectories(bad)
    no_obs = {k: v for k, v in arrays.items() if k != "observations"}
    with pytest.raises(DatasetError, match=r"missing arrays \['observations'\]"):
        load_trajectories(_npz(tmp_path / "bad.npz", **no_obs))


def test_random_walk_files(walk_file: Path, tmp_path: Path) -> None:
    arrays = _arrays(walk_file)
    assert len(load_dataset(walk_file)) == len(load_random_walk(walk_file))
    with pytest.raises(DatasetError, match="no header"):
        load_trajectories(walk_file)
    meta = json.loads(str(arrays["meta"]))
    cases: list[tuple[dict[str, Any], str]] = [
        ({"meta": np.array("nope")}, "'meta' is not JSON"),
        ({"meta": np.array(json.dumps({**meta, "format": "x"}))}, "format 'x'"),
        ({"observations": np.full_like(arrays["observations"], np.inf)}, "'observations' holds NaN or infinite"),
        ({"wall_contact": arrays["wall_contact"].astype(np.float32)}, "'wall_contact' has dtype"),
        ({"goals": arrays["goals"][:3]}, "goals must have shape"),
        ({"leg_starts": np.array([5, 2])}, "leg_starts must be increasing"),
        ({"episode_starts": np.array([1])}, "episode_starts must be increasing"),
    ]
    for change, match in cases:
        bad = _npz(tmp_path / "bad.npz", **{**arrays, **change})
        with pytest.raises(DatasetError, match=f"bad.npz.*{match}"):
            load_random_walk(bad)
        with pytest.raises(DatasetError, match=r"bad.npz"):
            load_trajectories(bad)
    no_goals = {k: v for k, v in arrays.items() if k != "goals"}
    with pytest.raises(DatasetError, match=r"missing \['goals'\]"):
        load_random_walk(_npz(tmp_path / "bad.npz", **no_goals))


def test_counterfactual_files(tmp_path: Path) -> None:
    good = tiny_counterfactual().save(tmp_path / "c.npz")
    assert len(CounterfactualDataset.load(good)) == 2
    arrays = _arrays(good)
    cases: list[tuple[dict[str, Any], str]] = [
        ({"meta": np.array(json.dumps({"format_version": 99}))}, "format_version 99"),
        ({"states": np.full((6, 2), np.nan, np.float32)}, "'states' holds NaN"),
        ({"kind": np.array([0, 9], np.int8)}, "'kind' holds values outside"),
        ({"offsets": np.array([0, 4, 3])}, "offsets|at least one state"),
        ({"success": np.array([1, 0])}, "'success' has dtype"),
        ({"window": np.zeros((2, 3), np.int32)}, "window must be"),
        ({"extra": np.zeros(2)}, "unexpected arrays"),
    ]
    for change, match in cases:
        bad = _npz(tmp_path / "bad.npz", **{**arrays, **change})
        with pytest.raises(DatasetError, match=f"bad.npz.*({match})"):
            CounterfactualDataset.load(bad)


def test_saving_refuses_meta_that_is_not_json(tmp_path: Path) -> None:
    data = TrajectoryDataset(np.zeros((3, 2)), np.zeros((3, 2)), meta={"x": object()})
    with pytest.raises(TypeError, match="JSON-serializable"):
        save_trajectories(data, tmp_path / "t.npz")
    assert not (tmp_path / "t.npz").exists()


@pytest.mark.parametrize(
    ("kwargs", "exc", "match"),
    [
        ({"observations": [["1", "2"]] * 3}, TypeError, "observations must hold real numbers"),
        ({"observations": np.zeros((3, 2), complex)}, TypeError, "real numbers"),
        ({"actions": np.zeros((3, 2), bool)}, TypeError, "actions must hold real numbers"),
        ({"episode_starts": [0.0]}, TypeError, "episode_starts must hold ints"),
        ({"episode_starts": "0"}, TypeError, "episode_starts"),
        ({"obs_indices": "01"}, TypeError, "obs_indices"),
        ({"obs_indices": (0, 1.0)}, TypeError, "obs_indices entry"),
        ({"meta": {1: "x"}}, TypeError, "meta keys"),
    ],
)
def test_dataset_constructor_refuses_coercions(kwargs: dict[str, Any], exc: type[Exception], match: str) -> None:
    base: dict[str, Any] = {"observations": np.zeros((3, 2)), "actions": np.zeros((3, 2))}
    with pytest.raises(exc, match=match):
        TrajectoryDataset(**{**base, **kwargs})


@settings(max_examples=50, deadline=None)
@given(
    name=st.sampled_from(sorted(LOADERS)),
    key=st.sampled_from(["observations", "actions", "episode_starts", "states", "offsets", "meta", "header", "goals"]),
    value=st.one_of(
        st.just(np.zeros(0)),
        st.just(np.array("x")),
        st.just(np.full((4, 2), np.nan)),
        st.just(np.zeros((2, 2, 2))),
        st.just(np.array([1 + 1j])),
        st.just(np.array([True])),
        st.integers(-5, 5).map(np.array),
        st.text(max_size=20).map(np.array),
    ),
)
def test_random_array_swaps_load_or_raise_dataset_error(name: str, key: str, value: np.ndarray) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        src = {
            "trajectories": lambda p: _good_traj(p),
            "random_walk": lambda p: save_random_walk(_WALK, p),
            "counterfactual": lambda p: tiny_counterfactual().save(p),
        }[name](Path(tmp, "good.npz"))
        arrays = {**_arrays(src), key: value}
        bad = _npz(Path(tmp, "bad.npz"), **arrays)
        try:
            LOADERS[name](bad)
        except DatasetError as err:
            assert "bad.npz" in str(err)


_WALK = generate_random_walk("umaze", 40, seed=0, progress=False)
