"""All six ITPS samplers steer a real LeRobot ``DiffusionPolicy`` (trained here by ``lerobot-train``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
import torch

import steer_envs  # noqa: F401 - registers the envs
from steer_envs.adapters import LeRobotDiffusion
from steer_envs.core.policy import DiffusionPolicyLike
from steer_envs.steering import SAMPLERS
from steer_envs.steering.maze import method_sampler, steering_trial
from steer_envs.users.sketcher import SketchUser
from steer_envs.wrappers import SteeringWrapper

ENV_ID = "steer_envs/Maze2D-Large-v0"
NAMES = ("RS", "PR", "OP", "BI", "GD", "SS")


@pytest.fixture(scope="module")
def policy(trained_lerobot: tuple[Path, list[float]]) -> LeRobotDiffusion:
    """The trained DP with its own DDPM scheduler (100 steps, stochastic steps)."""
    return LeRobotDiffusion.from_pretrained(trained_lerobot[0])


@pytest.fixture(scope="module")
def fast_policy(trained_lerobot: tuple[Path, list[float]]) -> LeRobotDiffusion:
    """The same weights with a DDIM scheduler from the same config, 10 steps (ITPS's setting)."""
    return LeRobotDiffusion.from_pretrained(trained_lerobot[0], scheduler="ddim", num_inference_steps=10)


def test_lerobot_train_learned_on_the_export(trained_lerobot: tuple[Path, list[float]]) -> None:
    path, losses = trained_lerobot
    assert (path / "model.safetensors").is_file() and len(losses) >= 5
    print(f"lerobot-train loss: first log {losses[0]:.3f}, last {losses[-1]:.3f}")
    assert losses[-1] < 0.5 * losses[0]


def test_the_adapter_is_a_diffusion_policy(policy: LeRobotDiffusion) -> None:
    assert set(SAMPLERS) == set(NAMES)
    assert isinstance(policy, DiffusionPolicyLike)
    assert (policy.horizon, policy.action_dim, policy.n_obs_steps, policy.exec_start) == (32, 2, 2, 1)
    assert type(policy.scheduler).__name__ == "DDPMScheduler" and policy.num_inference_steps == 100
    xy = np.array([[1.0, 2.0], [3.0, 4.0]])
    np.testing.assert_allclose(policy.unnormalize(policy.normalize(xy)), xy, atol=1e-5)
    plans = policy.sample(np.array([2.0, 3.0]), 4, generator=np.random.default_rng(0))
    assert plans.shape == (4, 32, 2) and np.all(np.isfinite(plans))


@pytest.mark.parametrize("name", NAMES)
def test_every_sampler_steers_it_through_the_wrapper(policy: LeRobotDiffusion, name: str) -> None:
    env = gym.make(ENV_ID, sample_goal=False)
    maze: Any = env.unwrapped
    steer = SteeringWrapper(env, policy, method_sampler(name, maze), batch=8)
    try:
        steer.reset(seed=4)
        drawn = SketchUser(maze.grid, seed=4).draw(maze.state)
        _, _, _, _, info = steer.step(drawn.sketch)
        assert info["plans"].shape == (8, 32, 2) and np.all(np.isfinite(info["plans"]))
        assert len(info["executed"]) > 0
    finally:
        steer.close()


@pytest.mark.parametrize("name", NAMES)
def test_the_same_seed_gives_the_same_plans(policy: LeRobotDiffusion, name: str) -> None:
    env: Any = gym.make(ENV_ID, sample_goal=False).unwrapped
    obs, _ = env.reset(seed=2)
    sketch = SketchUser(env.grid, seed=2).draw(env.state).sketch
    sampler = method_sampler(name, env)
    global_state = torch.random.get_rng_state()

    def plans(seed: int) -> np.ndarray:
        return sampler(policy, np.stack([obs, obs]), sketch, 8, generator=np.random.default_rng(seed)).plans

    first, again, other = plans(7), plans(7), plans(8)
    np.testing.assert_array_equal(first, again)
    assert not np.array_equal(first, other)
    assert torch.equal(torch.random.get_rng_state(), global_state), "DDPM's noise must not come from torch's generator"
    env.close()


def test_ss_aligns_with_the_sketch_better_than_rs_on_20_starts(fast_policy: LeRobotDiffusion) -> None:
    rows = []
    for seed in range(20):
        rs, _ = steering_trial(ENV_ID, seed, fast_policy, "RS", batch=32)
        ss, _ = steering_trial(ENV_ID, seed, fast_policy, "SS", batch=32)
        rows.append((seed, rs["min_l2"], ss["min_l2"], rs["collision"], ss["collision"]))
    table = np.array(rows)
    print("\nseed  RS min L2  SS min L2   RS coll  SS coll")
    for seed, rs_l2, ss_l2, rs_c, ss_c in rows:
        print(f"{seed:4d}  {rs_l2:8.3f}  {ss_l2:9.3f}  {rs_c:8.2f} {ss_c:8.2f}")
    wins = int((table[:, 2] < table[:, 1]).sum())
    print(f"mean  {table[:, 1].mean():8.3f}  {table[:, 2].mean():9.3f}  {table[:, 3].mean():8.2f} "
          f"{table[:, 4].mean():8.2f}   SS better on {wins}/20 starts")  # fmt: skip
    assert table[:, 2].mean() < table[:, 1].mean() and wins >= 15


def test_x0_prediction_policies_steer(maze_trajectories: Any, lerobot_root: Path) -> None:
    """A LeRobot DP trained with ``prediction_type="sample"``: the samplers convert, GD(0) reproduces RS."""
    from lerobot.configs.types import FeatureType
    from lerobot.datasets.lerobot_dataset import LeRobotDatasetMetadata
    from lerobot.datasets.utils import dataset_to_policy_features
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig
    from lerobot.policies.diffusion.modeling_diffusion import DiffusionPolicy
    from lerobot.policies.factory import make_pre_post_processors

    meta = LeRobotDatasetMetadata("steer/maze2d", root=lerobot_root)
    features = dataset_to_policy_features(meta.features)
    outputs = {k: f for k, f in features.items() if f.type is FeatureType.ACTION}
    inputs = {k: f for k, f in features.items() if k not in outputs}
    config = DiffusionConfig(input_features=inputs, output_features=outputs, down_dims=(16, 32), horizon=16,
                             n_action_steps=4, prediction_type="sample", device="cpu")  # fmt: skip
    torch.manual_seed(0)
    lerobot_policy = DiffusionPolicy(config).eval()
    pre, post = make_pre_post_processors(config, dataset_stats=meta.stats)
    policy = LeRobotDiffusion(lerobot_policy, pre, post, scheduler="ddim", num_inference_steps=10)
    obs = maze_trajectories.observations[:2]
    from steer_envs.core.interaction import Sketch
    from steer_envs.steering import make_sampler

    sketch = Sketch(np.linspace(obs[-1], obs[-1] + [1.0, 0.5], 10))
    for name in ("BI", "GD", "SS"):
        result = make_sampler(name)(policy, obs, sketch, 4, generator=np.random.default_rng(0))
        assert result.plans.shape == (4, 16, 2) and np.all(np.isfinite(result.plans))
    unguided = make_sampler("GD", guide_ratio=0.0)(policy, obs, sketch, 4, generator=np.random.default_rng(1))
    plain = make_sampler("RS")(policy, obs, None, 4, generator=np.random.default_rng(1))
    np.testing.assert_allclose(unguided.plans, plain.plans, atol=1e-5)


def test_bad_input_is_named(policy: LeRobotDiffusion) -> None:
    with pytest.raises(ValueError, match="encode_obs: `obs` must be one observation or"):
        policy.encode_obs(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="observation_features names"):
        LeRobotDiffusion(policy.lerobot_policy, policy.preprocessor, policy.postprocessor,
                         observation_features={"observation.images": (0,)})  # fmt: skip
    with pytest.raises(TypeError, match="must be a LeRobot DiffusionPolicy"):
        LeRobotDiffusion(object(), policy.preprocessor, policy.postprocessor)
