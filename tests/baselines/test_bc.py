"""The one BC policy: thesis architecture, training, determinism, bounded output, safetensors I/O, GLiDE settings."""

from __future__ import annotations

from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import pytest
import torch

from steer_envs.baselines.bc import BCConfig, BCPolicy, clip_speed
from steer_envs.baselines.glide.mode_policies import GlideBCConfig
from steer_envs.core.policy import VelocityPolicy


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    x = rng.uniform(-6, 6, size=(300, 2))
    v = np.tanh(x @ np.array([[-1.0, 0.5], [-0.5, -1.0]]).T) * 8.0  # a smooth target field
    return x, v


@pytest.fixture(scope="module")
def trained(data) -> tuple[BCPolicy, list[float]]:
    policy = BCPolicy(BCConfig(epochs=150), seed=0)
    losses = policy.fit(*data)
    return policy, losses


def test_architecture_matches_thesis() -> None:
    policy = BCPolicy()
    linears = [m for m in policy.net if isinstance(m, torch.nn.Linear)]
    assert [(m.in_features, m.out_features) for m in linears] == [(2, 100), (100, 100), (100, 2)]
    assert isinstance(policy.net[1], torch.nn.ReLU) and isinstance(policy.net[-1], torch.nn.Tanh)
    cfg = policy.config
    assert cfg.output_scale == 50.0 and cfg.lr == 1e-3 and cfg.batch_size == 512 and cfg.epochs == 4000
    assert isinstance(policy, VelocityPolicy)


def test_initial_weights_are_pytorch_defaults_and_leave_the_global_rng_alone() -> None:
    state = torch.random.get_rng_state()
    policy = BCPolicy(GlideBCConfig(), seed=5)
    assert torch.equal(state, torch.random.get_rng_state())
    torch.manual_seed(5)  # the same stream: nn.Linear's own initialisation, layer by layer
    first = torch.nn.Linear(2, 128)
    np.testing.assert_array_equal(policy.net[0].weight.detach(), first.weight.detach())
    np.testing.assert_array_equal(policy.net[0].bias.detach(), first.bias.detach())


def test_training_reduces_the_error(trained, data) -> None:
    policy, losses = trained
    x, v = data
    assert len(losses) == 150 and policy.trained_for == 150
    assert losses[-1] < 0.1 * losses[0]
    assert np.mean((policy(x) - v) ** 2) < 0.1 * np.mean(v**2)


def test_training_is_deterministic_per_seed(data) -> None:
    x, v = data
    cfg = BCConfig(epochs=5)
    a, b, c = BCPolicy(cfg, seed=3), BCPolicy(cfg, seed=3), BCPolicy(cfg, seed=4)
    for p in (a, b, c):
        p.fit(x[:100], v[:100])
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
    np.testing.assert_array_equal(policy.act(far), out)


def test_glide_settings_standardize_and_clip_the_speed() -> None:
    rng = np.random.default_rng(0)
    states = rng.uniform(-1, 1, (400, 2))
    actions = -0.1 * states / np.maximum(np.linalg.norm(states, axis=1, keepdims=True), 1.0)
    policy = BCPolicy(replace(GlideBCConfig(steps=600), output_scale=0.1), seed=0)
    losses = policy.fit(states, actions)
    assert len(losses) == 600 and policy.trained_for == 600
    assert policy.input_mean is not None and policy.input_scale is not None
    assert [m.out_features for m in policy.net if isinstance(m, torch.nn.Linear)] == [128, 128, 2]
    assert not isinstance(policy.net[-1], torch.nn.Tanh)
    assert np.mean(np.linalg.norm(policy(states) - actions, axis=1)) < 0.02
    assert np.all(np.linalg.norm(policy(rng.uniform(-9, 9, (50, 2))), axis=1) <= 0.1 + 1e-9)


@pytest.mark.parametrize("config", [BCConfig(epochs=150), replace(GlideBCConfig(steps=50), output_scale=9.0)])
def test_save_load_round_trip_is_atomic(tmp_path: Path, data, config: BCConfig) -> None:
    policy = BCPolicy(config, seed=1)
    policy.fit(*data)
    path = policy.save(tmp_path / "sub" / "bc.safetensors")
    assert path.exists() and [p.name for p in path.parent.iterdir()] == ["bc.safetensors"]  # no temp left over
    loaded = BCPolicy.load(path)
    probe = np.random.default_rng(2).uniform(-6, 6, size=(25, 2))
    np.testing.assert_array_equal(loaded(probe), policy(probe))
    assert loaded.trained_for == policy.trained_for and asdict(loaded.config) == asdict(policy.config)
    policy.save(path)  # overwrite in place
    junk = tmp_path / "junk.safetensors"
    junk.write_bytes(b"\x08\x00\x00\x00\x00\x00\x00\x00{}      ")
    with pytest.raises(ValueError, match="not a steer-envs safetensors checkpoint"):
        BCPolicy.load(junk)


def test_bad_input_is_rejected(data) -> None:
    x, v = data
    policy = BCPolicy(BCConfig(epochs=1))
    with pytest.raises(ValueError, match="same length"):
        policy.fit(x, v[:-1])
    with pytest.raises(ValueError, match="inside"):
        policy.fit(x, v * 10)  # targets outside the tanh range can never be fitted
    with pytest.raises(ValueError, match="finite"):
        policy.fit(np.full((3, 2), np.nan), v[:3])
    with pytest.raises(ValueError, match="shape"):
        policy(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="epochs"):
        BCConfig(epochs=-1)
    with pytest.raises(ValueError, match="exactly one of epochs and steps"):
        BCConfig(steps=10)
    with pytest.raises(ValueError, match="state_dim"):
        BCConfig(state_dim=0)
    with pytest.raises(ValueError, match="hidden"):
        BCConfig(hidden=())
    with pytest.raises(ValueError, match="output"):
        BCConfig(output="sigmoid")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="config"):
        BCPolicy({"epochs": 1})  # type: ignore[arg-type]


def test_clip_speed_scales_only_fast_rows() -> None:
    out = clip_speed(np.array([[3.0, 4.0], [0.0, 0.0], [0.1, 0.0]]), 1.0)
    np.testing.assert_allclose(out, [[0.6, 0.8], [0.0, 0.0], [0.1, 0.0]])
