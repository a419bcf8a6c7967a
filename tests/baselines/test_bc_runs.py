"""Resumable BC runs: bit-identical to one fit, continued from saved states, damaged or foreign states refused."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from steer_envs.baselines.bc import BCConfig, BCPolicy, BCRun, train_run
from steer_envs.baselines.bc.runs import LATEST_FILE, step_file
from steer_envs.io import CheckpointError

X = np.random.default_rng(0).normal(size=(64, 3))
Y = np.tanh(X[:, :2] * 2.0)
CONFIG = BCConfig(state_dim=3, action_dim=2, hidden=(16, 16), output="clip", output_scale=2.0, epochs=None, steps=40)


def _run(seed: int = 1, config: BCConfig = CONFIG, y: np.ndarray = Y) -> BCRun:
    return BCRun(BCPolicy(config, seed=seed), X, y, log_every=10)


def _fit(seed: int = 1, steps: int = 40) -> BCPolicy:
    policy = BCPolicy(BCConfig(**{**CONFIG.__dict__, "steps": steps}), seed=seed)
    policy.fit(X, Y)
    return policy


def test_a_run_in_segments_is_one_fit_bit_for_bit(tmp_path: Path) -> None:
    whole = _fit()
    run = _run()
    kept = train_run(run, 40, keep=(10, 25))
    assert sorted(kept) == [10, 25, 40] and run.step == 40 and run.steps_trained == 40
    np.testing.assert_array_equal(run.policy(X), whole(X))
    # the kept weights are those of a run that stopped there
    at_25 = BCPolicy(CONFIG, seed=1)
    at_25.net.load_state_dict(kept[25])
    np.testing.assert_array_equal(at_25(X), _fit(steps=25)(X))
    assert [s for s, _ in run.losses] == [10, 20, 30, 40]


def test_a_folder_keeps_the_steps_and_a_larger_budget_continues_the_run(tmp_path: Path) -> None:
    first = _run()
    train_run(first, 20, folder=tmp_path, keep=(10,))
    assert sorted(p.name for p in tmp_path.iterdir()) == [step_file(10), step_file(20)]
    again = _run()
    train_run(again, 20, folder=tmp_path)
    assert again.steps_trained == 0 and again.trained_from == 20  # read, not trained
    np.testing.assert_array_equal(again.policy(X), first.policy(X))
    longer = _run()
    train_run(longer, 40, folder=tmp_path)
    assert longer.trained_from == 20 and longer.steps_trained == 20
    np.testing.assert_array_equal(longer.policy(X), _fit()(X))
    assert longer.losses == _losses_of_whole_run()
    # a step before the saved ones (a learning-curve point asked for later) trains from the start again
    early = _run()
    kept = train_run(early, 40, folder=tmp_path, keep=(5,))
    assert early.steps_trained == 5 and (tmp_path / step_file(5)).is_file()
    np.testing.assert_array_equal(early.policy(X), _fit()(X))
    assert sorted(kept) == [5, 40]


def _losses_of_whole_run() -> list[list[float]]:
    run = _run()
    train_run(run, 40)
    return run.losses


def test_a_killed_run_continues_from_its_latest_state(tmp_path: Path) -> None:
    run = _run()
    run.advance(17, save=lambda: run.save(tmp_path / LATEST_FILE), save_every=0.0)  # saved after each step but the last
    assert BCRun.saved_step(tmp_path / LATEST_FILE) == 16  # then the process was killed
    resumed = _run()
    train_run(resumed, 40, folder=tmp_path)
    assert resumed.trained_from == 16 and resumed.steps_trained == 24
    np.testing.assert_array_equal(resumed.policy(X), _fit()(X))


def test_damaged_and_foreign_states_are_refused(tmp_path: Path) -> None:
    run = _run()
    train_run(run, 20, folder=tmp_path)
    path = tmp_path / step_file(20)
    raw = bytearray(path.read_bytes())
    raw[-3] ^= 0xFF  # a flipped bit in the tensors
    path.write_bytes(bytes(raw))
    with pytest.raises(CheckpointError, match=str(path.name)):
        _run().load(path)
    again = _run()
    train_run(again, 20, folder=tmp_path)  # the damaged state is skipped: trained again, and rewritten
    assert again.steps_trained == 20
    np.testing.assert_array_equal(again.policy(X), _fit(steps=20)(X))
    other = _run(seed=2)  # another seed is another run: its key differs
    assert other.key != run.key and _run(y=Y * 0.5).key != run.key
    with pytest.raises(CheckpointError, match="not a state of this BC run"):
        other.load(path)
    assert _run(config=BCConfig(**{**CONFIG.__dict__, "steps": 99})).key == run.key  # the budget is not part of it


def test_bad_arguments_are_refused() -> None:
    with pytest.raises(ValueError, match="steps"):
        BCRun(BCPolicy(BCConfig(state_dim=3, action_dim=2, epochs=2)), X, Y)
    trained = _fit(steps=3)
    with pytest.raises(ValueError, match="untrained"):
        BCRun(trained, X, Y)
    with pytest.raises(TypeError, match="policy"):
        BCRun(torch.nn.Linear(3, 2), X, Y)  # type: ignore[arg-type]
    run = _run()
    with pytest.raises(ValueError, match="keep"):
        train_run(run, 10, keep=(11,))
    with pytest.raises(ValueError, match="until"):
        train_run(run, 0)
    with pytest.raises(ValueError, match="nothing to save"):
        run.save("x.safetensors")
    train_run(run, 10)
    with pytest.raises(ValueError, match="past the first step"):
        train_run(run, 20, keep=(5,))
