"""Thesis BC velocity policy: architecture, training, determinism, bounded output, safetensors I/O."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from steer_envs.baselines.bc.modeling import BCPolicy
from steer_envs.core.policy import VelocityPolicy


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    x = rng.uniform(-6, 6, size=(300, 2))
    v = np.tanh(x @ np.array([[-1.0, 0.5], [-0.5, -1.0]]).T) * 8.0  # a smooth target field
    return x, v


@pytest.fixture(scope="module")
def trained(data) -> tuple[BCPolicy, list[float]]:
    policy = BCPolicy(2, seed=0)
    losses = policy.fit(*data, epochs=150)
    return policy, losses


def test_architecture_matches_thesis() -> None:
    policy = BCPolicy(2)
    linears = [m for m in policy.net if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in linears] == [(2, 100), (100, 100), (100, 2)]
    assert isinstance(policy.net[1], torch.nn.ReLU) and isinstance(policy.net[-1], torch.nn.Tanh)
    assert policy.output_scale == 50.0 and policy.lr == 1e-3 and policy.batch_size == 512
    assert isinstance(policy, VelocityPolicy)


def test_training_reduces_the_error(trained, data) -> None:
    policy, losses = trained
    x, v = data
    assert len(losses) == 150 and policy.epochs_trained == 150
    assert losses[-1] < 0.1 * losses[0]
    assert np.mean((policy(x) - v) ** 2) < 0.1 * np.mean(v**2)


def test_training_is_deterministic_per_seed(data) -> None:
    x, v = data
    a, b, c = BCPolicy(2, seed=3), BCPolicy(2, seed=3), BCPolicy(2, seed=4)
    for p in (a, b, c):
        p.fit(x[:100], v[:100], epochs=5)
    probe = np.random.default_rng(1).uniform(-5, 5, size=(10, 2))
    np.testing.assert_array_equal(a(probe), b(probe))
    assert not np.allclose(a(probe), c(probe))


def test_output_is_bounded_and_batched(trained) -> None:
    policy, _ = trained
    far = np.array([[1e6, -1e6], [-1e6, 1e6], [0.0, 0.0]])
    out = policy(far)
    assert out.shape == (3, 2) and out.dtype == np.float64
    assert np.all(np.abs(out) <= 50.0)
    np.testing.assert_allclose(policy(far[2]), out[2], rtol=1e-5)  # float32 network: batch-size rounding


def test_save_load_round_trip_is_atomic(tmp_path: Path, trained) -> None:
    policy, _ = trained
    path = policy.save(tmp_path / "sub" / "bc.safetensors")
    assert path.exists() and [p.name for p in path.parent.iterdir()] == ["bc.safetensors"]  # no temp left over
    loaded = BCPolicy.load(path)
    probe = np.random.default_rng(2).uniform(-6, 6, size=(25, 2))
    np.testing.assert_array_equal(loaded(probe), policy(probe))
    assert loaded.epochs_trained == policy.epochs_trained and loaded.hidden == (100, 100)
    policy.save(path)  # overwrite in place
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"\x08\x00\x00\x00\x00\x00\x00\x00{}      ")
    with pytest.raises(ValueError, match="not a BCPolicy"):
        BCPolicy.load(junk)


def test_bad_input_is_rejected(data) -> None:
    x, v = data
    policy = BCPolicy(2)
    with pytest.raises(ValueError, match="same length"):
        policy.fit(x, v[:-1], epochs=1)
    with pytest.raises(ValueError, match="inside"):
        policy.fit(x, v * 10, epochs=1)  # targets outside the tanh range can never be fitted
    with pytest.raises(ValueError, match="finite"):
        policy.fit(np.full((3, 2), np.nan), v[:3], epochs=1)
    with pytest.raises(ValueError, match="shape"):
        policy(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="epochs"):
        policy.fit(x, v, epochs=-1)
    with pytest.raises(ValueError, match="state_dim"):
        BCPolicy(0)
    with pytest.raises(ValueError, match="hidden"):
        BCPolicy(2, hidden=())
