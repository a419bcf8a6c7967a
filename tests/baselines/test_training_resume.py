"""Resumable training (--run-dir / --resume) and the speed options (bf16, fused AdamW, torch.compile)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch

from steer_envs.baselines.common import TrainSettings
from steer_envs.baselines.common.checkpoint import read_safetensors, write_safetensors
from steer_envs.baselines.factory import make_policy, make_policy_config
from steer_envs.baselines.training import main, snapshot_run, train_policy
from steer_envs.baselines.training.run_state import RUN_FILE, STATE_FILE
from steer_envs.data.trajectories import TrajectoryDataset, save_trajectories
from steer_envs.io import CheckpointError

ROOT = Path(__file__).resolve().parents[2]
TINY: dict[str, dict[str, Any]] = {
    "dp": {"horizon": 8, "down_dims": (8, 16), "step_embed_dim": 16, "obs_embed_dim": 8, "kernel_size": 3},
    "act": {"chunk_size": 4, "d_model": 8, "n_heads": 1, "dim_feedforward": 8, "n_encoder_layers": 1},
}
TINY_ARGS = ["--model", "horizon=8", "--model", "down_dims=[8,16]", "--model", "step_embed_dim=16"]
TINY_ARGS += ["--model", "relative=false"]


@pytest.fixture(scope="module")
def data() -> TrajectoryDataset:
    rng = np.random.default_rng(0)
    return TrajectoryDataset(
        rng.normal(size=(300, 3)), rng.normal(size=(300, 2)), episode_starts=[0, 150], meta={"domain": "toy"}
    )


@pytest.fixture(scope="module")
def data_file(data: TrajectoryDataset, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return save_trajectories(data, tmp_path_factory.mktemp("data") / "toy.npz")


def _weights(policy: object) -> dict[str, torch.Tensor]:
    return {k: v.clone() for k, v in policy.model.state_dict().items()}  # type: ignore[attr-defined]


def _same(a: dict[str, torch.Tensor], b: dict[str, torch.Tensor]) -> bool:
    return a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.parametrize(
    ("name", "options"),
    [
        ("dp", {"ema_power": 0.75}),
        ("dp", {"fused_optimizer": True, "precision": "bf16"}),
        ("act", {}),  # dropout: torch's global RNG must be restored too
    ],
)
def test_a_stopped_and_resumed_run_ends_with_the_uninterrupted_weights(
    name: str, options: dict[str, object], data: TrajectoryDataset, tmp_path: Path
) -> None:
    config = make_policy_config(name, **TINY[name])
    settings = TrainSettings(steps=24, batch_size=8, log_every=5, warmup_steps=4, **options)
    whole = make_policy(config, dataset=data)
    record = train_policy(whole, data, settings, progress=False)
    for seed, stop in ((0, 7), (1, 15)):  # two stops: resumed twice
        part = make_policy(config, dataset=data, seed=seed)  # after a stop other weights: the state must replace them
        train_policy(part, data, settings, progress=False, run_dir=tmp_path, stop_after=stop)
    resumed = make_policy(config, dataset=data, seed=2)
    again = train_policy(resumed, data, settings, progress=False, run_dir=tmp_path)
    assert _same(_weights(whole), _weights(resumed))
    assert again["losses"] == record["losses"]
    assert again["resumed_at"] == [7, 15]
    assert "resumed_at" not in record


@pytest.mark.parametrize("name", ["dp", "act"])
def test_a_snapshot_holds_the_weights_the_run_has_reached(
    name: str, data: TrajectoryDataset, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = make_policy_config(name, **TINY[name])
    settings = TrainSettings(steps=24, batch_size=8, log_every=5, warmup_steps=4, ema_power=0.75 if name == "dp" else 0)
    with pytest.raises(CheckpointError, match="no saved training state"):
        snapshot_run(make_policy(config, dataset=data), data, settings, tmp_path)
    part = make_policy(config, dataset=data)
    train_policy(part, data, settings, progress=False, run_dir=tmp_path, stop_after=10)  # the EMA weights at 10
    state = (tmp_path / STATE_FILE).read_bytes()
    snap = make_policy(config, dataset=data, seed=3)
    record = snapshot_run(snap, data, settings, tmp_path)
    assert _same(_weights(snap), _weights(part)) and record["snapshot_step"] == 10
    assert record["losses"][-1][0] == 10 and (tmp_path / STATE_FILE).read_bytes() == state  # nothing written
    # the run goes on to the weights of an uninterrupted run
    train_policy(make_policy(config, dataset=data, seed=4), data, settings, progress=False, run_dir=tmp_path)


def test_cli_snapshot_writes_the_current_weights(
    data_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    run = tmp_path / "run"
    base = ["--policy", "act", "--dataset", str(data_file), "--model", "chunk_size=4", "--model", "d_model=8"]
    base += ["--model", "n_heads=1", "--model", "dim_feedforward=8", "--steps", "6", "--no-progress"]
    assert main([*base, "--run-dir", str(run)]) == 0
    assert main(["--resume", str(run), "--snapshot"]) == 0
    assert "step 6 of 6" in capsys.readouterr().out
    snap, _ = read_safetensors(run / "snapshot-step6.safetensors", "config")
    final, _ = read_safetensors(run / "act.safetensors", "config")
    assert _same(snap, final)
    assert json.loads((run / "snapshot-step6.json").read_text())["training"]["snapshot_step"] == 6
    with pytest.raises(SystemExit) as exc:
        main([*base, "--snapshot", "--out", str(tmp_path / "x.safetensors")])
    assert exc.value.code == 2 and "--snapshot needs --resume" in capsys.readouterr().err


def test_a_resumed_run_records_its_first_segments_threads(data: TrajectoryDataset, tmp_path: Path) -> None:
    """A check replays a run's first steps, so the record keeps the thread count they ran on."""
    from steer_envs.utils.threads import limit_threads

    config = make_policy_config("dp", **TINY["dp"])
    settings = TrainSettings(steps=12, batch_size=8, log_every=4, warmup_steps=2)
    with limit_threads(torch_threads=2):
        train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path, stop_after=6)
    with limit_threads(torch_threads=1):
        record = train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path)
    assert record["resumed_at"] == [6] and record["threads"] == 2


def test_the_state_file_is_checked_before_it_is_loaded(data: TrajectoryDataset, tmp_path: Path) -> None:
    config = make_policy_config("dp", **TINY["dp"])
    settings = TrainSettings(steps=10, batch_size=4, log_every=5)
    train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path, stop_after=4)
    state = tmp_path / STATE_FILE
    fresh = make_policy(config, dataset=data)
    with pytest.raises(CheckpointError, match="other training settings \\(differ: lr\\)"):
        train_policy(fresh, data, settings.replace(lr=0.5), progress=False, run_dir=tmp_path)
    with pytest.raises(ValueError, match="already at step 4"):
        train_policy(fresh, data, settings, progress=False, run_dir=tmp_path, stop_after=2)
    wider = make_policy(make_policy_config("dp", **{**TINY["dp"], "down_dims": (8, 32)}), dataset=data)
    with pytest.raises(CheckpointError, match=r"do not match the network|shape"):
        train_policy(wider, data, settings, progress=False, run_dir=tmp_path)
    tensors, meta = read_safetensors(state, "training_state")
    write_safetensors(state, tensors, "training_state", {**meta, "step": 11})
    with pytest.raises(CheckpointError, match="not a training state of this run"):
        train_policy(fresh, data, settings, progress=False, run_dir=tmp_path)
    state.write_bytes(state.read_bytes()[:100])
    with pytest.raises(CheckpointError, match=str(state.name)):
        train_policy(fresh, data, settings, progress=False, run_dir=tmp_path)
    with pytest.raises(ValueError, match="save_every"):
        train_policy(fresh, data, settings, progress=False, run_dir=tmp_path, save_every=-1)


def test_a_run_moved_to_another_device_kind_restarts_its_noise_generator(
    data: TrajectoryDataset, tmp_path: Path
) -> None:
    """A state saved on a GPU continues on the CPU: everything carries over but the noise generator's state."""
    config = make_policy_config("dp", **TINY["dp"])
    settings = TrainSettings(steps=12, batch_size=8, log_every=4, warmup_steps=2)
    train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path, stop_after=6)
    state = tmp_path / STATE_FILE
    tensors, meta = read_safetensors(state, "training_state")
    cuda_like = {**tensors, "torch_generator": torch.zeros(16, dtype=torch.uint8)}  # a CUDA generator's state size
    write_safetensors(state, cuda_like, "training_state", {**meta, "generator_device": "cuda"})
    record = train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path)
    assert record["resumed_at"] == [6] and record["moved_at"] == [6]
    assert record["losses"][-1][0] == 12 and np.isfinite(record["final_loss"])
    # a state from before the device was kept: told apart by the generator state's size
    train_policy(
        make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path / "b", stop_after=6
    )
    tensors, meta = read_safetensors(tmp_path / "b" / STATE_FILE, "training_state")
    del meta["generator_device"]
    write_safetensors(tmp_path / "b" / STATE_FILE, cuda_like, "training_state", meta)
    again = train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path / "b")
    assert again["moved_at"] == [6] and again["losses"] == record["losses"]
    # a generator state of no known device, or a bad device name, is refused
    train_policy(
        make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path / "c", stop_after=6
    )
    tensors, meta = read_safetensors(tmp_path / "c" / STATE_FILE, "training_state")
    for bad_tensors, bad_meta in (
        (
            {**tensors, "torch_generator": torch.zeros(7, dtype=torch.uint8)},
            {k: v for k, v in meta.items() if k != "generator_device"},
        ),
        (tensors, {**meta, "generator_device": 3}),
    ):
        write_safetensors(tmp_path / "c" / STATE_FILE, bad_tensors, "training_state", bad_meta)
        with pytest.raises(CheckpointError, match="does not fit this run"):
            train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path / "c")


def test_speed_options_are_validated_and_recorded(data: TrajectoryDataset) -> None:
    with pytest.raises(ValueError, match="precision must be one of \\['bf16', 'fp32'\\]"):
        TrainSettings(precision="fp16")
    with pytest.raises(TypeError, match="fused_optimizer"):
        TrainSettings(fused_optimizer="yes")
    with pytest.raises(TypeError, match="compile_model"):
        TrainSettings(compile_model=1)
    settings = TrainSettings(steps=30, batch_size=16, log_every=10, precision="bf16", fused_optimizer=True)
    policy = make_policy(make_policy_config("dp", **TINY["dp"]), dataset=data)
    record = train_policy(policy, data, settings, progress=False)
    assert record["settings"]["precision"] == "bf16" and record["settings"]["fused_optimizer"] is True
    assert all(p.dtype == torch.float32 for p in policy.model.parameters())  # autocast keeps float32 weights
    assert record["losses"][-1][1] < record["losses"][0][1]
    # records written before these settings existed still load (the defaults apply)
    old = {k: v for k, v in settings.to_dict().items() if k not in ("precision", "fused_optimizer", "compile_model")}
    assert TrainSettings.from_dict(old).precision == "fp32"


def test_cli_resume_continues_a_killed_run_to_the_uninterrupted_checkpoint(data_file: Path, tmp_path: Path) -> None:
    common = ["--policy", "dp", "--dataset", str(data_file), *TINY_ARGS, "--steps", "300", "--no-progress"]
    common += ["--train", "batch_size=4", "--train", "log_every=20"]
    assert main([*common, "--out", str(tmp_path / "whole.safetensors")]) == 0
    run = tmp_path / "run"
    cmd = [sys.executable, "-m", "steer_envs.baselines.training", *common, "--run-dir", str(run), "--save-every", "0.2"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 120
        while not (run / STATE_FILE).exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)  # no chance to save: the last periodic state must do
    finally:
        proc.wait(timeout=60)
    assert (run / STATE_FILE).exists(), proc.stdout.read() if proc.stdout else ""
    _, meta = read_safetensors(run / STATE_FILE, "training_state")
    assert meta["step"] < 300, "the run finished before it was killed: make it longer"
    assert main(["--resume", str(run), "--no-progress"]) == 0
    whole, _ = read_safetensors(tmp_path / "whole.safetensors", "config")
    resumed, _ = read_safetensors(run / "dp.safetensors", "config")
    assert _same(whole, resumed)
    record = json.loads((run / "dp.json").read_text())["training"]
    assert (
        record["resumed_at"]
        and record["losses"] == json.loads((tmp_path / "whole.json").read_text())["training"]["losses"]
    )
    assert record["command"].endswith(f"--run-dir {run} --save-every 0.2")


def test_sigterm_saves_the_state_and_exits_130(data_file: Path, tmp_path: Path) -> None:
    run = tmp_path / "run"
    cmd = [sys.executable, "-m", "steer_envs.baselines.training", "--policy", "dp", "--dataset", str(data_file)]
    cmd += [*TINY_ARGS, "--steps", "100000", "--no-progress", "--run-dir", str(run), "--save-every", "3600"]
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    deadline = time.monotonic() + 120
    while not (run / RUN_FILE).exists() and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=60)
    assert proc.returncode == 130, out
    assert f"--resume {run}" in out
    _, meta = read_safetensors(run / STATE_FILE, "training_state")
    assert 1 <= meta["step"] < 100000


def test_cli_resume_usage_errors(data_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def usage(argv: list[str], match: str) -> None:
        with pytest.raises(SystemExit) as exc:
            main(argv)
        assert exc.value.code == 2
        assert match in capsys.readouterr().err

    run = tmp_path / "run"
    base = ["--policy", "dp", "--dataset", str(data_file), *TINY_ARGS, "--steps", "3", "--no-progress"]
    assert main([*base, "--run-dir", str(run)]) == 0
    assert (run / "dp.safetensors").exists() and (run / "dp.json").exists()
    usage([*base, "--run-dir", str(run)], "holds a run already")
    usage(["--resume", str(run), "--steps", "5"], "drop --steps")
    usage(["--resume", str(run), "--out", str(tmp_path / "x.pt")], "must end with .safetensors")
    usage(["--resume", str(run), "--run-dir", str(run)], "give one of them")
    usage(["--resume", str(tmp_path / "nothing")], "not a run folder")
    usage([*base, "--run-dir", str(tmp_path / "r2"), "--save-every", "-1"], "--save-every")
    usage(["--policy", "dp", "--out", str(tmp_path / "x.safetensors")], "--dataset is required")
    run_json = json.loads((run / RUN_FILE).read_text())
    (run / RUN_FILE).write_text(json.dumps({**run_json, "settings": {**run_json["settings"], "lr": "fast"}}))
    usage(["--resume", str(run)], "not a run folder")
    # a finished run resumed again writes the same checkpoint
    (run / RUN_FILE).write_text(json.dumps(run_json))
    before = (run / "dp.safetensors").read_bytes()
    assert main(["--resume", str(run), "--no-progress"]) == 0
    assert (run / "dp.safetensors").read_bytes() == before
    # the run folder may move (another machine, another checkout): its checkpoint goes with it
    moved = run.rename(tmp_path / "moved")
    (moved / "dp.safetensors").unlink()
    assert main(["--resume", str(moved), "--no-progress"]) == 0
    assert (moved / "dp.safetensors").read_bytes() == before
    # --out and --device may change on a resume (a GPU run finished on this machine, its recorded out elsewhere)
    elsewhere = tmp_path / "elsewhere" / "dp.safetensors"
    assert main(["--resume", str(moved), "--no-progress", "--device", "cpu", "--out", str(elsewhere)]) == 0
    assert elsewhere.read_bytes() == before


@pytest.mark.slow
def test_compiled_training_resumes_and_learns(data: TrajectoryDataset, tmp_path: Path) -> None:
    """torch.compile costs minutes on first use: slow."""
    config = make_policy_config("dp", **TINY["dp"])
    settings = TrainSettings(steps=20, batch_size=8, log_every=5, compile_model=True)
    whole = make_policy(config, dataset=data)
    train_policy(whole, data, settings, progress=False)
    assert not hasattr(whole.model, "_orig_mod")  # the policy keeps its own network
    train_policy(make_policy(config, dataset=data), data, settings, progress=False, run_dir=tmp_path, stop_after=9)
    resumed = make_policy(config, dataset=data)
    train_policy(resumed, data, settings, progress=False, run_dir=tmp_path)
    assert _same(_weights(whole), _weights(resumed))


def test_threads_default_to_one(data_file: Path, tmp_path: Path) -> None:
    out = tmp_path / "dp.safetensors"
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        argv = ["--policy", "dp", "--dataset", str(data_file), *TINY_ARGS, "--steps", "2", "--no-progress"]
        assert main([*argv, "--out", str(out)]) == 0
    finally:
        torch.set_num_threads(before)
    assert json.loads(out.with_suffix(".json").read_text())["training"]["threads"] == 1
