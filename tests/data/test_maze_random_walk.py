"""D4RL maze2d random walk: controller, determinism, collision-free data, file round trip, training view, CLI."""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from steer_envs.data.datasets import load_dataset
from steer_envs.data.maze_random_walk import (
    RandomWalkDataset,
    generate_random_walk,
    goal_episodes,
    goal_rewards,
    load_random_walk,
    load_transitions,
    main,
    save_random_walk,
    to_minari,
)
from steer_envs.data.trajectories import PlanWindows
from steer_envs.envs.maze_grid import AGENT_RADIUS, MazeGrid, maze_map

LARGE = MazeGrid(maze_map("large"))


@pytest.fixture(scope="module")
def walk() -> RandomWalkDataset:
    return generate_random_walk("large", 40_000, seed=3, progress=False)


def test_same_seed_gives_identical_data(walk: RandomWalkDataset) -> None:
    again = generate_random_walk("large", 40_000, seed=3, progress=False)
    for name in ("observations", "actions", "waypoints", "goals", "wall_contact", "leg_starts"):
        np.testing.assert_array_equal(getattr(walk, name), getattr(again, name))
    other = generate_random_walk("large", 40_000, seed=4, progress=False)
    assert not np.array_equal(walk.observations, other.observations)


def test_walk_is_collision_free_continuous_and_covers_the_maze(walk: RandomWalkDataset) -> None:
    assert len(walk) == 10_000 and walk.meta["raw_steps"] == 40_000 and walk.meta["dt"] == pytest.approx(0.04)
    for points in (walk.xy, walk.actions, walk.waypoints):
        assert LARGE.is_wall(points).mean() == 0.0  # the ITPS rule: no waypoint in a wall cell
    assert LARGE.clearance(walk.xy).min() >= AGENT_RADIUS - 0.01  # the ball never penetrates a wall
    np.testing.assert_array_equal(walk.actions[:-1], walk.xy[1:])  # action = next xy
    speeds = np.linalg.norm(np.diff(walk.xy, axis=0), axis=1) / walk.meta["dt"]
    assert speeds.max() < 12.0  # cells per second: no teleports
    visited = {tuple(c) for c in LARGE.xy_to_cell(walk.xy).tolist()}
    assert len(visited) >= 0.9 * len(LARGE.free_cells)
    # the goal is constant within a leg and changes at leg starts (no reset: the walk just continues)
    assert len(walk.leg_starts) > 20 and walk.leg_starts[0] == 0
    for a, b in zip(walk.leg_starts[:-1], walk.leg_starts[1:], strict=True):
        assert np.all(walk.goals[a:b] == walk.goals[a]) and np.any(walk.goals[b] != walk.goals[b - 1])
    assert np.all(np.abs(walk.goals - np.round(walk.goals)) <= 0.1 + 1e-6)


def test_save_load_round_trip(tmp_path: Path, walk: RandomWalkDataset) -> None:
    path = save_random_walk(walk, tmp_path / "sub" / "walk.npz")
    assert [p.name for p in path.parent.iterdir()] == ["walk.npz"]  # no temp file left behind
    loaded = load_random_walk(path)
    for name in ("observations", "actions", "waypoints", "goals", "wall_contact", "episode_starts", "leg_starts"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(walk, name))
    assert loaded.meta == json.loads(json.dumps(walk.meta))
    obs, actions, starts = load_transitions(path)
    assert obs.shape == (10_000, 4) and actions.shape == (10_000, 2) and starts.tolist() == [0]
    with pytest.raises(ValueError, match="npz"):
        save_random_walk(walk, tmp_path / "walk.h5")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="missing"):
        load_random_walk(tmp_path / "other.npz")
    with pytest.raises(ValueError, match="no dataset"):
        load_random_walk(tmp_path / "absent.npz")


def test_training_view_declares_positions_and_pools_their_statistics(tmp_path: Path, walk: RandomWalkDataset) -> None:
    """to_trajectories: observation = xy (entries 0, 1 of the env observation), action = next xy (a target for them)."""
    traj = walk.to_trajectories()
    np.testing.assert_array_equal(traj.observations, walk.xy)
    np.testing.assert_array_equal(traj.actions, walk.actions)
    assert traj.obs_indices == (0, 1) and traj.action_obs_indices == (0, 1)
    assert traj.meta == walk.meta and traj.provenance()["seed"] == 3
    stats = traj.stats()
    lo, hi = walk.xy_bounds()
    for feature in ("observation", "action"):  # positions and plans share one box (and one mean/std)
        np.testing.assert_array_equal(stats[feature]["min"], lo)
        np.testing.assert_array_equal(stats[feature]["max"], hi)
    np.testing.assert_array_equal(stats["observation"]["mean"], stats["action"]["mean"])
    # the training CLI's loader reads a random-walk file as this view
    loaded = load_dataset(save_random_walk(walk, tmp_path / "walk.npz"))
    np.testing.assert_array_equal(loaded.observations, traj.observations)
    assert loaded.action_obs_indices == (0, 1)


def test_itps_windows_on_generated_data(walk: RandomWalkDataset) -> None:
    windows = PlanWindows(walk.to_trajectories(), n_obs=2, horizon=64)
    assert len(windows) == len(walk) - 64 - (2 - 1) + 1
    idx = np.arange(0, len(windows), 97)
    obs, plans = windows.gather(idx)
    t = windows.steps[idx]
    np.testing.assert_array_equal(obs[:, 1], walk.xy[t])
    np.testing.assert_array_equal(obs[:, 0], walk.xy[t - 1])
    np.testing.assert_array_equal(plans[:, 0], walk.xy[t + 1])
    assert not LARGE.plan_collides(plans).any()
    lo, hi = walk.xy_bounds()
    assert np.all(lo > 0.5) and np.all(hi < np.array([7.5, 10.5]))


def test_generator_validates_arguments() -> None:
    with pytest.raises(ValueError, match="maze"):
        generate_random_walk("huge", 100, progress=False)
    with pytest.raises(ValueError, match="steps"):
        generate_random_walk("umaze", 2, subsample=4, progress=False)
    with pytest.raises(TypeError, match="seed"):
        generate_random_walk("umaze", 100, seed=1.5, progress=False)  # type: ignore[arg-type]


def test_cli_writes_a_dataset(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--out", str(tmp_path), "--maze", "umaze", "--steps", "2000", "--seed", "1", "--no-progress"]) == 0
    out = tmp_path / "maze2d-umaze-randomwalk-seed1.npz"
    ds = load_random_walk(out)
    assert len(ds) == 500 and ds.meta["maze"] == "umaze" and ds.meta["seed"] == 1
    assert "raw steps/s" in capsys.readouterr().out
    help_text = subprocess.run(
        [sys.executable, "-m", "steer_envs.data.maze_random_walk", "--help"], capture_output=True, text=True, check=True
    ).stdout
    assert "--out" in help_text and "--steps" in help_text and "--seed" in help_text


def test_cli_progress_bar_only_on_a_terminal_or_when_asked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["--out", str(tmp_path), "--maze", "umaze", "--steps", "400"]
    assert main(argv) == 0
    assert "maze2d random walk" not in capsys.readouterr().err  # stderr is no terminal here: no bar by default
    assert main([*argv, "--progress"]) == 0
    assert "maze2d random walk" in capsys.readouterr().err


def test_goal_episodes_follow_the_env_rules() -> None:
    ds = generate_random_walk("umaze", 6000, seed=1, progress=False)
    episodes = goal_episodes(ds)
    rewards = goal_rewards(ds)
    assert rewards.sum() > 0 and len(episodes) >= 3
    grid = MazeGrid(maze_map("umaze"))
    for ep in episodes:
        assert len(ep) == len(ep.rewards) > 0
        np.testing.assert_array_equal(ep.rewards, rewards[ep.start : ep.stop])
        # terminated exactly when the last step enters the goal cell, and no earlier step does
        assert ep.rewards[:-1].sum() == 0 and ep.rewards[-1] == float(ep.terminated)
        goal_cell = tuple(grid.xy_to_cell(ds.goals[ep.stop - 1]).tolist())
        assert (tuple(grid.xy_to_cell(ds.actions[ep.stop - 1]).tolist()) == goal_cell) == ep.terminated
    starts = [ep.start for ep in episodes]
    assert starts == sorted(starts) and all(a.stop <= b.start for a, b in itertools.pairwise(episodes))
    assert episodes[-1].stop <= len(ds) - 1  # the walk's last sample has no kept next observation
    assert set(starts) <= {0, *ds.leg_starts.tolist()}
    with pytest.raises(TypeError, match="dataset must be a RandomWalkDataset"):
        goal_episodes("walk")  # type: ignore[arg-type]


def test_minari_round_trip(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("h5py", reason="Minari needs its hdf5 backend (pip install 'minari[hdf5]')")
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    ds = generate_random_walk("umaze", 4000, seed=0, progress=False)
    to_minari(ds, "steer_envs/maze2d-umaze/randomwalk-v0")
    loaded = minari.load_dataset("steer_envs/maze2d-umaze/randomwalk-v0")
    episodes = goal_episodes(ds)
    assert loaded.total_episodes == len(episodes) > 1
    for ep, stored in zip(episodes, loaded.iterate_episodes(), strict=True):
        np.testing.assert_allclose(stored.observations, ds.observations[ep.start : ep.stop + 1])
        np.testing.assert_allclose(stored.actions, ds.actions[ep.start : ep.stop])
        np.testing.assert_allclose(stored.rewards, ep.rewards)
        np.testing.assert_allclose(stored.infos["waypoint"], ds.waypoints[ep.start : ep.stop])
        assert bool(stored.terminations[-1]) == ep.terminated != bool(stored.truncations[-1])
    assert os.path.isdir(tmp_path / "minari")
    with pytest.raises(ValueError, match="dataset_id"):
        to_minari(ds, "steer/it's-v0")
    with pytest.raises(TypeError, match="root"):
        to_minari(ds, "steer/x-v0", root=3)  # type: ignore[arg-type]


_LOAD_CHECK = """
import json, sys
import minari
data = minari.load_dataset(sys.argv[1])
episodes = list(data.iterate_episodes())
print(json.dumps({
    "episodes": len(episodes),
    "steps": int(data.total_steps),
    "rewards": [float(e.rewards.sum()) for e in episodes],
    "terminated": [bool(e.terminations[-1]) for e in episodes],
    "truncated": [bool(e.truncations[-1]) for e in episodes],
}))
"""


@pytest.mark.parametrize("how", ["--minari-root", "MINARI_DATASETS_PATH"])
def test_cli_minari_export_with_relative_paths_loads_in_a_fresh_shell(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], how: str
) -> None:
    """A relative ``--out`` / data path must not double; the printed line must load the data."""
    pytest.importorskip("h5py", reason="Minari needs its hdf5 backend (pip install 'minari[hdf5]')")
    monkeypatch.chdir(tmp_path)
    argv = ["--out", "out/data", "--maze", "umaze", "--steps", "4000", "--seed", "2", "--no-progress"]
    argv += ["--minari-id", "steer/walk-v0"]
    if how == "--minari-root":
        monkeypatch.delenv("MINARI_DATASETS_PATH", raising=False)
        argv += ["--minari-root", "out/minari"]
        root = tmp_path / "out" / "minari"
    else:
        monkeypatch.setenv("MINARI_DATASETS_PATH", "out/data/minari")
        root = tmp_path / "out" / "data" / "minari"
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert f"to {root / 'steer' / 'walk-v0'}:" in out
    (line,) = [x.split("load it with: ", 1)[1] for x in out.splitlines() if x.startswith("load it with: ")]
    assert line.startswith(f"MINARI_DATASETS_PATH={root} python -c ")
    assert not [p for p in root.rglob("*") if p.name.endswith(".tmp")]  # no leftovers of the build

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k != "MINARI_DATASETS_PATH"}
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"  # `python` is this one
    shown = subprocess.run(line, shell=True, cwd=elsewhere, env=env, capture_output=True, text=True, timeout=120)
    assert shown.returncode == 0, shown.stderr
    assert "steer/walk-v0" in shown.stdout or "MinariDataset" in shown.stdout

    env["MINARI_DATASETS_PATH"] = str(root)
    res = subprocess.run(
        [sys.executable, "-c", _LOAD_CHECK, "steer/walk-v0"],
        cwd=elsewhere,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert res.returncode == 0, res.stderr
    stored = json.loads(res.stdout.strip().splitlines()[-1])
    expected = goal_episodes(load_random_walk(tmp_path / "out" / "data" / "maze2d-umaze-randomwalk-seed2.npz"))
    assert stored["episodes"] == len(expected) > 1
    assert stored["steps"] == sum(len(e) for e in expected)
    assert stored["rewards"] == [float(e.terminated) for e in expected]
    assert stored["terminated"] == [e.terminated for e in expected] and any(stored["terminated"])
    assert stored["truncated"] == [not e.terminated for e in expected]


def test_cli_refuses_a_bad_minari_id_before_generating(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["--out", str(tmp_path), "--maze", "umaze", "--steps", "40", "--no-progress"]
    for extra, match in (
        (["--minari-id", "../up"], "--minari-id"),
        (["--minari-root", str(tmp_path / "m")], "--minari-root needs --minari-id"),
    ):
        with pytest.raises(SystemExit) as exc:
            main([*base, *extra])
        assert exc.value.code == 2 and match in capsys.readouterr().err
    assert not list(tmp_path.glob("*.npz"))


@pytest.mark.slow
def test_itps_scale_walk_is_collision_free() -> None:
    """The ITPS data size: 1M raw steps subsampled x4 (about 40 s on one core)."""
    ds = generate_random_walk("large", 1_000_000, seed=0, progress=False)
    assert len(ds) == 250_000
    assert LARGE.is_wall(ds.actions).sum() == 0 and LARGE.is_wall(ds.waypoints).sum() == 0
    assert len({tuple(c) for c in LARGE.xy_to_cell(ds.xy).tolist()}) == len(LARGE.free_cells)


def test_generator_refuses_coercions_and_huge_walks() -> None:
    with pytest.raises(TypeError, match="progress must be True, False or None"):
        generate_random_walk("umaze", 100, progress="no")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="steps must be an int in"):
        generate_random_walk("umaze", 10**12, progress=False)
    with pytest.raises(TypeError, match="max_leg_steps must be an int"):
        generate_random_walk("umaze", 100, max_leg_steps=2.5, progress=False)  # type: ignore[arg-type]


def test_cli_output_errors_are_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    for out, match in (("", "--out must not be empty"), (str(tmp_path / "f" / "x.npz"), "is not a folder")):
        (tmp_path / "f").write_text("x")
        with pytest.raises(SystemExit) as exc:
            main(["--out", out, "--maze", "umaze", "--steps", "40", "--no-progress"])
        assert exc.value.code == 2 and match in capsys.readouterr().err
