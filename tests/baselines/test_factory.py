"""The policy factory: registry, configs from presets, policies fitted to a dataset, loading any checkpoint."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
import torch

from steer_envs.baselines.act import ACTConfig, ACTPolicy
from steer_envs.baselines.common import FeatureStats, Normalizer, Preset, TrainSettings, observation_history
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.factory import (
    POLICIES,
    get_config_class,
    get_policy_class,
    get_preset,
    load_policy,
    make_policy,
    make_policy_config,
    policy_names,
    register_policy,
    register_preset,
)
from steer_envs.baselines.pretrained import checkpoint_path, load_pretrained
from steer_envs.data.trajectories import TrajectoryDataset

DP_TINY = {"horizon": 8, "down_dims": (8, 16), "step_embed_dim": 16, "obs_embed_dim": 8, "kernel_size": 3}


def _data(obs_dim: int = 5, action_dim: int = 3, **declared) -> TrajectoryDataset:
    rng = np.random.default_rng(0)
    return TrajectoryDataset(rng.normal(size=(60, obs_dim)), rng.normal(size=(60, action_dim)) * 2, **declared)


def test_registry_maps_names_to_classes() -> None:
    assert policy_names() == ["act", "dp", "flow"]
    assert get_policy_class("dp") is DiffusionPolicy and get_config_class("dp") is DiffusionConfig
    assert get_policy_class("act") is ACTPolicy and get_config_class("act") is ACTConfig
    for name, spec in POLICIES.items():
        assert spec.policy_class.name == name and spec.policy_class.config_class is spec.config_class
    with pytest.raises(ValueError, match="policy must be one of"):
        get_policy_class("bc")


def test_configs_from_defaults_presets_and_overrides() -> None:
    assert make_policy_config("dp") == DiffusionConfig()
    cfg = make_policy_config("dp", preset="cpu", horizon=16)
    assert cfg.relative and cfg.horizon == 16 and cfg.down_dims == get_preset("dp", "cpu").model.down_dims
    with pytest.raises(ValueError, match="not fields of DiffusionConfig"):
        make_policy_config("dp", d_model=3)
    with pytest.raises(ValueError, match="preset must be one of"):
        make_policy_config("act", preset="nope")


def test_make_policy_takes_features_and_statistics_from_the_dataset() -> None:
    data = _data(obs_indices=(4, 3, 2, 1, 0))
    policy = make_policy(make_policy_config("dp", **DP_TINY), dataset=data, seed=3)
    assert (policy.obs_dim, policy.action_dim, policy.config.obs_indices) == (5, 3, (4, 3, 2, 1, 0))
    stats = data.stats()
    np.testing.assert_array_equal(policy.stats["action"].max, stats["action"]["max"])
    np.testing.assert_array_equal(policy.stats["observation"].min, stats["observation"]["min"])
    # the env observation's entries are reordered as declared
    hist = policy.observation_history(np.arange(5.0))
    np.testing.assert_array_equal(hist, [[4, 3, 2, 1, 0]] * 2)
    act = make_policy(make_policy_config("act", chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8), dataset=data)
    np.testing.assert_array_equal(act.stats["observation"].std, stats["observation"]["std"])
    assert act.sample(np.zeros(5), 2, generator=np.random.default_rng(0)).shape == (2, 4, 3)
    # explicit statistics win; a fixed feature that disagrees with the data is an error
    custom = {"observation": {"min": -np.ones(5), "max": np.ones(5)}, "action": {"min": -np.ones(3), "max": np.ones(3)}}
    assert make_policy(DiffusionConfig(**DP_TINY), dataset=data, stats=custom).stats["action"].max.tolist() == [1] * 3
    with pytest.raises(ValueError, match=r"config\.obs_dim is 4 but the dataset has 5"):
        make_policy(DiffusionConfig(**DP_TINY, obs_dim=4), dataset=data)
    with pytest.raises(ValueError, match="obs_dim and action_dim must be set"):
        make_policy("dp")
    with pytest.raises(TypeError, match="dataset must be a TrajectoryDataset"):
        make_policy(DiffusionConfig(**DP_TINY), dataset={"observations": []})  # type: ignore[arg-type]


def test_same_seed_same_policy() -> None:
    data = _data()
    a, b = (make_policy(DiffusionConfig(**DP_TINY), dataset=data, seed=1) for _ in range(2))
    for (name, x), y in zip(a.model.state_dict().items(), b.model.state_dict().values(), strict=True):
        assert torch.equal(x, y), name


def test_load_policy_reads_any_registered_kind(tmp_path: Path) -> None:
    data = _data()
    dp = make_policy(DiffusionConfig(**DP_TINY), dataset=data).save(tmp_path / "dp.safetensors")
    act_cfg = ACTConfig(chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8)
    act = make_policy(act_cfg, dataset=data).save(tmp_path / "act.safetensors")
    assert isinstance(load_policy(dp), DiffusionPolicy) and isinstance(load_policy(act), ACTPolicy)
    assert isinstance(load_pretrained("act", checkpoint=act), ACTPolicy)
    assert isinstance(load_pretrained(act), ACTPolicy)  # a path loads whatever it holds
    with pytest.raises(ValueError, match="holds a 'act' policy, expected 'dp'"):
        load_pretrained("dp", checkpoint=act)
    with pytest.raises(ValueError, match="no checkpoint file"):
        load_policy(tmp_path / "absent.safetensors")
    with pytest.raises(ValueError, match="name must be one of"):
        load_pretrained("bc", checkpoint=dp)


def test_shipped_checkpoints_load_through_the_factory() -> None:
    """``load_pretrained(kind)`` keeps its signature (the benchmark records ``module:function``)."""
    dp, act = load_pretrained("dp"), load_pretrained("act")
    assert isinstance(dp, DiffusionPolicy) and isinstance(act, ACTPolicy)
    assert load_policy(checkpoint_path("dp")).config == dp.config
    assert dp.config.normalization == "min_max" and act.config.normalization == "mean_std"
    assert dp.stats["observation"] == dp.stats["action"] and act.stats["observation"] == act.stats["action"]


def test_registering_presets_and_policies_is_checked() -> None:
    preset = Preset(DiffusionConfig(horizon=16), TrainSettings(steps=5), "a domain's settings")
    register_preset("dp", "test-domain", preset)
    try:
        assert get_preset("dp", "test-domain") is preset
        with pytest.raises(ValueError, match="already has a preset"):
            register_preset("dp", "test-domain", preset)
    finally:
        del POLICIES["dp"].presets["test-domain"]
    with pytest.raises(TypeError, match="Preset of a ACTConfig"):
        register_preset("act", "x", preset)
    with pytest.raises(TypeError, match="model must be a PolicyConfig"):
        Preset({"horizon": 16}, TrainSettings())  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="already registered"):
        register_policy("dp", DiffusionConfig, DiffusionPolicy)
    with pytest.raises(ValueError, match="name must be 'dp2'"):
        register_policy("dp2", DiffusionConfig, DiffusionPolicy)

    @dataclass(frozen=True, kw_only=True)
    class OtherConfig(DiffusionConfig):
        pass

    with pytest.raises(TypeError, match="policy_class"):
        register_policy("other", OtherConfig, dict)  # type: ignore[arg-type]


def test_normalizer_modes_and_errors() -> None:
    x = np.array([[1.0, 2.0], [3.0, 6.0]])
    stats = FeatureStats.from_data(x)
    for mode in ("min_max", "mean_std", "identity"):
        norm = Normalizer(mode, stats, 2)
        np.testing.assert_allclose(norm.unnormalize(norm.normalize(x)), x)
        t = torch.tensor(x, dtype=torch.float32)
        torch.testing.assert_close(norm.normalize(t), torch.tensor(norm.normalize(x), dtype=torch.float32))
    np.testing.assert_allclose(Normalizer("min_max", stats, 2).normalize(x), [[-1, -1], [1, 1]])
    np.testing.assert_allclose(Normalizer("mean_std", stats, 2).normalize(x), [[-1, -1], [1, 1]])
    with pytest.raises(ValueError, match="mode must be one of"):
        Normalizer("z", stats, 2)
    with pytest.raises(ValueError, match="needs the statistics"):
        Normalizer("min_max", FeatureStats(mean=[0.0, 0.0]), 2)
    with pytest.raises(ValueError, match="one length"):
        FeatureStats(min=[0.0], max=[1.0, 2.0])
    with pytest.raises(ValueError, match="finite"):
        FeatureStats(min=[np.nan])
    with pytest.raises(ValueError, match="unknown statistics"):
        FeatureStats.from_dict({"median": [0.0]})
    assert FeatureStats.from_dict(stats.to_dict()) == stats


def test_observation_history_forms() -> None:
    np.testing.assert_array_equal(observation_history([1.0, 2.0, 3.0], 2, 3), [[1, 2, 3], [1, 2, 3]])
    hist = np.arange(12.0).reshape(4, 3)
    np.testing.assert_array_equal(observation_history(hist, 2, 3), hist[2:])
    np.testing.assert_array_equal(observation_history(hist, 2, 2, (2, 0)), hist[2:, [2, 0]])
    with pytest.raises(ValueError, match="D = obs_dim = 3"):
        observation_history(np.zeros(4), 1, 3)
    with pytest.raises(ValueError, match="finite"):
        observation_history([np.inf, 0.0, 0.0], 1, 3)
    with pytest.raises(TypeError, match="real numbers"):
        observation_history("abc", 1, 3)
