"""The training CLI: one entry point for DP and ACT on any trajectory dataset, presets, overrides, --check."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from steer_envs.baselines.act import ACTPolicy
from steer_envs.baselines.common import Preset, TrainSettings
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.factory import POLICIES, get_preset, load_policy, make_policy
from steer_envs.baselines.training import check_record, main, parse_overrides
from steer_envs.baselines.training.trainer import CROSS_DEVICE_RTOL
from steer_envs.data.maze_random_walk import generate_random_walk, save_random_walk
from steer_envs.data.trajectories import TrajectoryDataset, save_trajectories

ROOT = Path(__file__).resolve().parents[2]
#: tiny networks for the CLI, per policy
TINY_DP = ["--model", "horizon=8", "--model", "down_dims=[8,16]", "--model", "step_embed_dim=16"]
TINY_DP += ["--model", "obs_embed_dim=16", "--model", "kernel_size=3"]
TINY_ACT = ["--model", "chunk_size=8", "--model", "d_model=16", "--model", "n_heads=2"]
TINY_ACT += ["--model", "dim_feedforward=16", "--model", "n_encoder_layers=1", "--model", "latent_dim=4"]
TINY = {"dp": TINY_DP, "act": TINY_ACT}


@pytest.fixture(scope="module")
def walk_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    walk = generate_random_walk("large", 8_000, seed=3, progress=False)
    return save_random_walk(walk, tmp_path_factory.mktemp("walk") / "walk.npz")


def _synthetic(declare: bool) -> TrajectoryDataset:
    """A robot-arm-like dataset: 7-D observation (eef xyz, gripper, block xyz), 4-D action (next eef xyz + gripper)."""
    rng = np.random.default_rng(0)
    eef = np.cumsum(rng.normal(scale=0.01, size=(121, 4)), axis=0)
    block = np.repeat(rng.uniform(size=(1, 3)), 121, axis=0)
    obs = np.concatenate([eef, block], axis=1)[:-1]
    return TrajectoryDataset(
        obs,
        eef[1:],
        episode_starts=[0, 60],
        action_obs_indices=(0, 1, 2, 3) if declare else None,
        meta={"domain": "synthetic-arm", "seed": 0},
    )


def _usage_error(argv: list[str], capsys: pytest.CaptureFixture[str], match: str) -> None:
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert match in capsys.readouterr().err


@pytest.mark.parametrize("name", ["dp", "act"])
def test_one_cli_trains_and_samples_both_policies_on_a_non_2d_dataset(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """obs dim 7, action dim 4: the same code and CLI as Maze2D; features and statistics come from the data."""
    data = save_trajectories(_synthetic(declare=True), tmp_path / "arm.npz")
    out = tmp_path / f"{name}.safetensors"
    argv = ["--policy", name, "--dataset", str(data), "--preset", "cpu", *TINY[name]]
    assert main([*argv, "--steps", "3", "--batch-size", "4", "--seed", "1", "--out", str(out), "--no-progress"]) == 0
    assert "obs 7, action 4" in capsys.readouterr().out
    policy = load_policy(out, name=name)
    assert (policy.obs_dim, policy.action_dim, policy.horizon) == (7, 4, 8)
    assert policy.config.action_obs_indices == (0, 1, 2, 3)
    np.testing.assert_array_equal(
        policy.stats["observation"].max[4:], _synthetic(True).stats()["observation"]["max"][4:]
    )
    plans = policy.sample(np.zeros(7), 5, generator=np.random.default_rng(0))
    assert plans.shape == (5, 8, 4) and np.all(np.isfinite(plans))
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["policy"] == name and record["training"]["preset"] == "cpu"
    assert record["config"]["obs_dim"] == 7 and record["training"]["data"] == {
        "domain": "synthetic-arm",
        "seed": 0,
        "file": "arm.npz",
    }
    assert len(record["training"]["losses"]) == 1 and record["training"]["settings"]["seed"] == 1


def test_relative_plans_need_declared_action_targets(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The cpu DP plans relative to the state the actions set: a dataset that declares none needs relative=false."""
    data = save_trajectories(_synthetic(declare=False), tmp_path / "arm.npz")
    argv = ["--policy", "dp", "--dataset", str(data), *TINY_DP, "--steps", "2", "--batch-size", "4", "--no-progress"]
    _usage_error([*argv, "--out", str(tmp_path / "dp.safetensors")], capsys, "relative=True needs action_obs_indices")
    assert main([*argv, "--model", "relative=false", "--out", str(tmp_path / "dp.safetensors")]) == 0
    assert not DiffusionPolicy.load(tmp_path / "dp.safetensors").config.relative


def test_maze_cli_writes_checkpoint_and_record(tmp_path: Path, walk_file: Path) -> None:
    out = tmp_path / "ck" / "dp.safetensors"
    argv = ["--policy", "dp", "--dataset", str(walk_file), "--out", str(out), "--steps", "3", "--batch-size", "4"]
    assert main([*argv, *TINY_DP, "--threads", "1", "--seed", "2", "--no-progress"]) == 0
    record = json.loads(out.with_suffix(".json").read_text())
    assert record["policy"] == "dp" and record["config"]["down_dims"] == [8, 16]
    assert record["config"]["obs_indices"] == [0, 1] and record["config"]["relative"] is True
    settings = record["training"]["settings"]
    assert settings["steps"] == 3 and settings["lr"] == 2e-3 and settings["static_history_prob"] == 0.2
    assert record["training"]["data"]["seed"] == 3 and record["training"]["data"]["maze"] == "large"
    assert record["training"]["threads"] == 1 and record["training"]["command"].startswith("python -m ")
    assert record["stats"]["observation"] == record["stats"]["action"]  # positions and plans share one box
    policy = DiffusionPolicy.load(out)
    assert policy.checkpoint_info["steps"] == 3
    assert not list(out.parent.glob(".*tmp"))  # atomic writes


def test_usage_errors_exit_2(tmp_path: Path, walk_file: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = str(tmp_path / "x.safetensors")
    base = ["--dataset", str(walk_file), "--steps", "1", "--no-progress"]
    cases = [
        (["--policy", "bc", *base, "--out", out], "invalid choice"),
        (["--policy", "dp", *base, "--out", str(tmp_path / "x.pt")], ".safetensors"),
        (["--policy", "dp", *base], "--out is required"),
        ([*base, "--out", out], "--policy is required"),
        (
            ["--policy", "dp", *base, "--out", out, "--preset", "gpu"],
            "preset must be one of ['blockstack', 'cpu', 'itps', 'kitchen']",
        ),
        (["--policy", "dp", *base, "--out", out, "--model", "nope=1"], "--model nope: not a field"),
        (["--policy", "dp", *base, "--out", out, "--model", "down_dims=[7]"], "down_dims"),
        (["--policy", "dp", *base, "--out", out, "--model", "d_model"], "KEY=VALUE"),
        (["--policy", "act", *base, "--out", out, "--train", "momentum=0.9"], "--train momentum: not a field"),
        (["--policy", "dp", *base, "--out", out, "--steps", "0"], "steps"),
        (["--policy", "dp", "--dataset", str(tmp_path / "missing.npz"), "--out", out], "no dataset file"),
        (["--policy", "dp", *base, "--out", out, "--threads", "0"], "--threads"),
    ]
    for argv, match in cases:
        _usage_error(argv, capsys, match)
    assert not (tmp_path / "x.safetensors").exists()


def test_help_lists_the_options() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "steer_envs.baselines.training", "--help"], capture_output=True, text=True, cwd=ROOT
    )
    assert proc.returncode == 0, proc.stderr
    for flag in ("--policy", "--dataset", "--preset", "--model", "--train", "--check", "--out"):
        assert flag in proc.stdout


def test_train_settings_overrides(tmp_path: Path, walk_file: Path) -> None:
    out = tmp_path / "act.safetensors"
    argv = ["--policy", "act", "--dataset", str(walk_file), "--out", str(out), *TINY_ACT, "--no-progress"]
    assert main([*argv, "--steps", "4", "--train", "log_every=2", "--train", "batch_size=3", "--lr", "1e-3"]) == 0
    settings = json.loads(out.with_suffix(".json").read_text())["training"]["settings"]
    assert (settings["log_every"], settings["batch_size"], settings["lr"], settings["weight_decay"]) == (
        2,
        3,
        1e-3,
        1e-4,
    )
    assert isinstance(ACTPolicy.load(out), ACTPolicy)


def _recorded_tiny_dp(tmp_path: Path, walk_file: Path) -> tuple[Path, list[str]]:
    """A tiny DP trained 3 steps with the CLI: its JSON record and the ``--check`` arguments that replay it."""
    out = tmp_path / "dp.safetensors"
    argv = ["--policy", "dp", "--dataset", str(walk_file), "--out", str(out), "--steps", "3", "--batch-size", "4"]
    assert main([*argv, *TINY_DP, "--threads", "1", "--no-progress"]) == 0
    record = out.with_suffix(".json")
    return record, ["--dataset", str(walk_file), "--check", str(record), "--check-steps", "3", "--no-progress"]


def test_check_reruns_a_recorded_run_and_flags_a_difference(
    tmp_path: Path, walk_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--check re-runs the start of a recorded run: same losses -> exit 0; a tampered record -> exit 1."""
    record, check = _recorded_tiny_dp(tmp_path, walk_file)
    assert main(check) == 0
    assert main(["--policy", "dp", *check]) == 0
    assert "dp: reproduced" in capsys.readouterr().out
    summary = json.loads(record.read_text())
    del summary["sha256"]  # a record edited by hand drops its checksum (else it is refused as damaged)
    summary["training"]["losses"][-1][1] *= 1.01
    record.write_text(json.dumps(summary))
    assert main(check) == 1
    assert "DIFFERENT" in capsys.readouterr().out
    _usage_error([*check[:-3], "--check-steps", "2"], capsys, "no logged step")
    _usage_error(["--policy", "act", *check], capsys, "records a 'dp' run")
    other = save_random_walk(generate_random_walk("large", 8_000, seed=4, progress=False), tmp_path / "w4.npz")
    _usage_error(["--dataset", str(other), *check[2:]], capsys, "seed=4")


def test_check_of_a_run_begun_on_another_device_checks_the_recipe(
    tmp_path: Path, walk_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A record whose first segment ran on CUDA replays on the CPU within CROSS_DEVICE_RTOL, not 1e-3."""
    record, check = _recorded_tiny_dp(tmp_path, walk_file)
    summary = json.loads(record.read_text())
    del summary["sha256"]  # a record edited by hand drops its checksum
    assert summary["training"]["first_device"] == "cpu"
    summary["training"]["first_device"] = "cuda"
    summary["training"]["losses"][-1][1] *= 1.05  # another noise stream: a few per cent off
    record.write_text(json.dumps(summary))
    assert main(check) == 0
    printed = capsys.readouterr().out
    assert "started on cuda" in printed and f"rtol {CROSS_DEVICE_RTOL:g}" in printed
    assert check_record(record, walk_file, 3)["cross_device"] == "cuda"
    summary["training"]["losses"][-1][1] *= 1.2  # a recipe that differs: far outside
    record.write_text(json.dumps(summary))
    assert main(check) == 1
    summary["training"]["first_device"] = 3
    record.write_text(json.dumps(summary))
    _usage_error(check, capsys, "first_device")


def test_check_reads_records_written_before_the_factory(tmp_path: Path, walk_file: Path) -> None:
    """The shipped records use ``kind`` / ``model`` (2-D positions implied); --check upgrades and re-runs them."""
    out = tmp_path / "act.safetensors"
    argv = ["--policy", "act", "--dataset", str(walk_file), "--out", str(out), "--steps", "2", "--batch-size", "4"]
    assert main([*argv, *TINY_ACT, "--threads", "1", "--no-progress"]) == 0
    summary = json.loads(out.with_suffix(".json").read_text())
    model = dict(summary.pop("config"))
    model["state_dim"] = model.pop("obs_dim")
    for key in ("normalization", "obs_indices", "action_obs_indices"):
        del model[key]
    legacy = {"kind": summary.pop("policy"), "model": model, "training": summary["training"]}
    legacy["training"]["settings"].pop("ema_power")
    legacy["training"]["data"] = {k: legacy["training"]["data"][k] for k in ("format", "maze", "seed", "raw_steps")}
    path = tmp_path / "legacy.json"
    path.write_text(json.dumps(legacy))
    res = check_record(path, walk_file, 2)
    assert res["policy"] == "act" and res["max_rel_diff"] == 0.0


def test_presets_are_typed_and_registered_per_policy() -> None:
    for name, spec in POLICIES.items():
        assert {"cpu", "itps"} <= set(spec.presets), name
        for preset in spec.presets.values():
            assert isinstance(preset, Preset) and isinstance(preset.model, spec.config_class)
            assert isinstance(preset.train, TrainSettings) and preset.model.obs_dim is None  # features: the data
    assert get_preset("dp", "cpu").train.steps == 40_000 and get_preset("act", "cpu").train.steps == 3_000
    itps = get_preset("dp", "itps")
    assert itps.train.batch_size == 256 and itps.model.down_dims == (128, 256, 512)
    dp = make_policy(itps.model.replace(obs_dim=2, action_dim=2))
    assert 15e6 < dp.num_parameters() < 18e6  # ITPS: about 16M
    assert get_preset("act", "itps").model.d_model == 512
    with pytest.raises(ValueError, match="preset must be one of"):
        get_preset("act", "gpu")


def test_parse_overrides() -> None:
    fields = DiffusionConfig.field_names()
    assert parse_overrides(["down_dims=[8,16]", "prediction=epsilon", "relative=false"], fields, "--model") == {
        "down_dims": (8, 16),
        "prediction": "epsilon",
        "relative": False,
    }
    with pytest.raises(ValueError, match="--model d_model: not a field"):
        parse_overrides(["d_model=8"], fields, "--model")
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_overrides(["d_model"], fields, "--model")


@pytest.mark.slow
def test_shipped_checkpoints_reproduce_with_the_committed_commands(tmp_path: Path) -> None:
    """scripts/train_maze_checkpoints.sh --check: the data, then the first steps of both recorded runs."""
    env = {**os.environ, "PYTHON": sys.executable}
    proc = subprocess.run(
        ["bash", str(ROOT / "scripts" / "train_maze_checkpoints.sh"), "--check", str(tmp_path)],
        capture_output=True,
        text=True,
        env=env,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.count("reproduced") == 2, proc.stdout


def test_cli_refuses_outputs_it_cannot_write_before_training(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = save_trajectories(_synthetic(declare=True), tmp_path / "arm.npz")
    argv = ["--policy", "act", "--dataset", str(data), *TINY["act"], "--steps", "2", "--no-progress"]
    blocker = tmp_path / "file"
    blocker.write_text("x")
    _usage_error([*argv, "--out", str(blocker / "act.safetensors")], capsys, "is not a folder")
    (tmp_path / "dir.safetensors").mkdir()
    _usage_error([*argv, "--out", str(tmp_path / "dir.safetensors")], capsys, "is a folder")
    _usage_error([*argv, "--out", str(tmp_path / "a.safetensors"), "--threads", "100000"], capsys, "--threads")
    _usage_error([*argv, "--out", str(tmp_path / "a.safetensors"), "--device", "nope"], capsys, "device")
    bad = tmp_path / "bad.npz"
    bad.write_text("not an archive")
    _usage_error(
        ["--policy", "act", "--dataset", str(bad), "--out", str(tmp_path / "a.safetensors")], capsys, "bad.npz"
    )


def test_check_reports_a_broken_record_as_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = save_trajectories(_synthetic(declare=True), tmp_path / "arm.npz")
    record = tmp_path / "r.json"
    record.write_text('{"policy": "act", "training": {"settings": {}, "losses": "many"}}')
    _usage_error(["--dataset", str(data), "--check", str(record)], capsys, "r.json")
    record.write_text("[1, 2]")
    _usage_error(["--dataset", str(data), "--check", str(record)], capsys, "a training record is a JSON object")
