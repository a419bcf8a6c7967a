"""DP / ACT / BC inputs: bad observations, counts, generators and batches are clear errors; valid ones unchanged."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from steer_envs.baselines.act import ACTConfig, ACTPolicy
from steer_envs.baselines.bc import BCConfig, BCPolicy
from steer_envs.baselines.common import TrainSettings
from steer_envs.baselines.diffusion import DiffusionConfig, DiffusionPolicy
from steer_envs.baselines.glide.classifier import ModeClassifier
from steer_envs.baselines.glide.kmeans import KMeansSegmentation

DP = DiffusionPolicy(
    DiffusionConfig(obs_dim=4, action_dim=2, horizon=8, down_dims=(8, 16), obs_embed_dim=8, step_embed_dim=8)
)
ACT = ACTPolicy(ACTConfig(obs_dim=4, action_dim=2, chunk_size=4, d_model=8, n_heads=1, dim_feedforward=8))
BC = BCPolicy(BCConfig(state_dim=4, hidden=(8,), epochs=1))
GOOD = np.array([0.1, 0.2, 0.3, 0.4])

BAD_OBS: list[tuple[Any, type[Exception]]] = [
    ("0.1 0.2 0.3 0.4", TypeError),
    (["0.1", "0.2", "0.3", "0.4"], TypeError),
    ([0.1, float("nan"), 0.3, 0.4], ValueError),
    ([0.1, 0.2, float("inf"), 0.4], ValueError),
    (np.array([1 + 2j, 0, 0, 0]), TypeError),
    ([True, False, True, False], TypeError),
    ([0.1, 0.2, 0.3], ValueError),
    (np.zeros((2, 2, 4)), ValueError),
    (np.zeros((0, 4)), ValueError),
    ([[0.1, 0.2], [0.3]], ValueError),
    (None, TypeError),
    ({"x": 1}, TypeError),
    ([object(), 1, 2, 3], TypeError),
]


@pytest.mark.parametrize("policy", [DP, ACT], ids=["dp", "act"])
@pytest.mark.parametrize(("obs", "exc"), BAD_OBS, ids=[f"obs{i}" for i in range(len(BAD_OBS))])
def test_sample_refuses_bad_observations(policy: Any, obs: Any, exc: type[Exception]) -> None:
    with pytest.raises(exc, match=rf"{type(policy).__name__}: obs"):
        policy.sample(obs, 2, generator=np.random.default_rng(0))


@pytest.mark.parametrize(("obs", "exc"), BAD_OBS, ids=[f"obs{i}" for i in range(len(BAD_OBS))])
def test_bc_refuses_bad_states(obs: Any, exc: type[Exception]) -> None:
    with pytest.raises(exc, match="BCPolicy: states"):
        BC(obs)


@pytest.mark.parametrize("policy", [DP, ACT], ids=["dp", "act"])
def test_sample_refuses_bad_counts_and_generators(policy: Any) -> None:
    for n, exc in [(0, ValueError), (-1, ValueError), (2.0, TypeError), ("3", TypeError), (True, TypeError)]:
        with pytest.raises(exc, match="sample: n must be an int"):
            policy.sample(GOOD, n)
    with pytest.raises(ValueError, match=r"n must be an int in \[1, 65536\]"):
        policy.sample(GOOD, 10**12)
    for gen in (0, np.random.RandomState(0), torch.Generator(), "rng"):
        with pytest.raises(TypeError, match="sample: generator must be a numpy Generator"):
            policy.sample(GOOD, 2, generator=gen)


@pytest.mark.parametrize("policy", [DP, ACT], ids=["dp", "act"])
def test_valid_observation_kinds_give_identical_plans(policy: Any) -> None:
    ref = policy.sample(GOOD, 3, generator=np.random.default_rng(5))
    as_list = policy.sample(GOOD.tolist(), 3, generator=np.random.default_rng(5))
    as_f32 = policy.sample(GOOD.astype(np.float32), 3, generator=np.random.default_rng(5))
    grad = torch.tensor(GOOD, requires_grad=True)
    as_tensor = policy.sample(grad, 3, generator=np.random.default_rng(5))
    as_history = policy.sample(np.stack([GOOD, GOOD]), 3, generator=np.random.default_rng(5))
    for other in (as_list, as_tensor, as_history):
        np.testing.assert_array_equal(other, ref)
    np.testing.assert_allclose(as_f32, ref, rtol=1e-5)
    assert BC(grad).shape == (2,)
    np.testing.assert_array_equal(BC(grad), BC(GOOD))


def test_predict_noise_and_loss_arguments() -> None:
    cond = DP.encode_obs(GOOD)
    x = torch.zeros(2, 8, 2)
    assert DP.predict_noise(x, 5, cond).shape == (2, 8, 2)
    assert DP.predict_noise(x, torch.tensor([1, 2]), cond.numpy()).shape == (2, 8, 2)
    cases: list[tuple[dict[str, Any], type[Exception], str]] = [
        ({"x_t": np.zeros((2, 8, 2))}, TypeError, "x_t must be a floating-point torch.Tensor"),
        ({"x_t": torch.zeros(2, 8, 2, dtype=torch.int64)}, TypeError, "x_t must be a floating-point"),
        ({"x_t": torch.full((2, 8, 2), float("nan"))}, ValueError, "x_t must be finite"),
        ({"x_t": torch.zeros(2, 7, 2)}, ValueError, "x_t must have shape"),
        ({"t": 2.5}, TypeError, "t must be an int"),
        ({"t": torch.tensor(2.0)}, TypeError, "t must hold integer timesteps"),
        ({"t": 100}, ValueError, r"t must be in \[0, 100\)"),
        ({"t": -1}, ValueError, "t must be in"),
        ({"t": torch.tensor([1, 2, 3])}, ValueError, "t must be a scalar or have 2 entries"),
        ({"cond": "c"}, TypeError, "cond must be a torch.Tensor"),
        ({"cond": torch.zeros(1, 3)}, ValueError, "cond must have shape"),
        ({"cond": torch.full((1, 8), float("inf"))}, ValueError, "cond must be finite"),
    ]
    for change, exc, match in cases:
        args = {"x_t": x, "t": 5, "cond": cond, **change}
        with pytest.raises(exc, match=f"DiffusionPolicy.predict_noise: {match}"):
            DP.predict_noise(**args)
    for policy in (DP, ACT):
        n_obs, h = policy.n_obs_steps, policy.horizon
        obs, plans = torch.zeros(3, n_obs, 4), torch.zeros(3, h, 2)
        assert torch.isfinite(policy.loss(obs, plans, torch.Generator().manual_seed(0)))
        bad: list[tuple[tuple[Any, ...], type[Exception], str]] = [
            ((obs.numpy(), plans), TypeError, "obs must be a torch.Tensor"),
            ((obs, plans.to(torch.complex64)), TypeError, "plans must hold real numbers"),
            ((obs, torch.full_like(plans, float("nan"))), ValueError, "plans must be finite"),
            ((obs[:2], plans), ValueError, "obs must have shape"),
            ((obs, plans, np.random.default_rng()), TypeError, "generator must be a torch.Generator"),
        ]
        for args, exc, match in bad:
            with pytest.raises(exc, match=f"{type(policy).__name__}.loss: {match}"):
                policy.loss(*args)


def test_devices_and_seeds() -> None:
    with pytest.raises(TypeError, match=r"device must be a torch.device or a str"):
        DP.to(0)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="device must name a torch device"):
        DP.to("gpu please")
    if not torch.cuda.is_available():
        with pytest.raises(ValueError, match="CUDA is not available"):
            DP.to("cuda")
    with pytest.raises(TypeError, match="seed must be an int"):
        DiffusionPolicy(DP.config, seed="1")  # type: ignore[arg-type]
    assert DP.to("cpu") is DP


@pytest.mark.parametrize(
    ("make", "exc", "match"),
    [
        (lambda: DiffusionConfig(down_dims=("16", "32")), TypeError, "down_dims entry must be an int"),
        (lambda: DiffusionConfig(down_dims="16"), TypeError, "down_dims must be a list or tuple"),
        (lambda: DiffusionConfig(horizon=64.0), TypeError, "horizon must be an int"),
        (lambda: DiffusionConfig(time_channel="no"), TypeError, "time_channel must be a bool"),
        (lambda: DiffusionConfig(beta_schedule="cosine"), ValueError, "beta_schedule must be one of"),
        (lambda: DiffusionConfig(clip_sample_range="1"), TypeError, "clip_sample_range must be a real number"),
        (lambda: DiffusionConfig(relative="yes"), TypeError, "relative must be a bool"),
        (lambda: ACTConfig(dropout=float("nan")), ValueError, "dropout must be a finite"),
        (lambda: ACTConfig(n_encoder_layers=10**6), ValueError, "n_encoder_layers must be <="),
        (lambda: TrainSettings(lr="1e-3"), TypeError, "lr must be a real number"),
        (lambda: TrainSettings(betas=("0.9", 0.99)), TypeError, "betas entry"),
        (lambda: TrainSettings(batch_size=10**9), ValueError, "batch_size must be an int in"),
        (lambda: BCConfig(hidden=["8"]), TypeError, "hidden entry must be an int"),
        (lambda: BCConfig(standardize="no"), TypeError, "standardize must be a bool"),
        (lambda: BCConfig(lr=float("inf")), ValueError, "lr must be a finite"),
    ],
)
def test_configs_refuse_coercions(make: Any, exc: type[Exception], match: str) -> None:
    with pytest.raises(exc, match=match):
        make()


def test_glide_predictors_refuse_bad_states() -> None:
    clf = ModeClassifier(2, 3, hidden=4)
    km = KMeansSegmentation(2, n_init=1).fit([np.stack([np.linspace(0, 1, 10), np.zeros(10)], 1)])
    for predictor, owner in ((clf, "ModeClassifier"), (km, "KMeansSegmentation")):
        with pytest.raises(TypeError, match=f"{owner}: states must hold real numbers"):
            predictor.predict(np.array([["1", "2"]]))
        with pytest.raises(ValueError, match=f"{owner}: states must be finite"):
            predictor.predict(np.array([[np.nan, 0.0]]))
    with pytest.raises(TypeError, match="seed must be an int"):
        KMeansSegmentation(2, seed=1.5)  # type: ignore[arg-type]


# --------------------------------------------------------------------- properties
_SCALARS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(10**6), 10**6),
    st.text(max_size=3),
    st.complex_numbers(allow_nan=False, max_magnitude=10),
    st.booleans(),
    st.none(),
)
_OBS = st.one_of(
    _SCALARS,
    st.lists(_SCALARS, max_size=6),
    st.lists(st.lists(_SCALARS, max_size=5), max_size=3),
    st.integers(0, 6).map(lambda k: np.full(k, np.nan)),
    st.integers(0, 3).map(lambda k: torch.zeros(k, 4, requires_grad=True)),
)


@settings(max_examples=80, deadline=None)
@given(obs=_OBS, n=st.one_of(st.integers(-3, 4), st.floats(0, 4), st.text(max_size=2)), which=st.sampled_from("da"))
def test_random_inputs_give_plans_or_clean_errors(obs: Any, n: Any, which: str) -> None:
    policy = DP if which == "d" else ACT
    try:
        plans = policy.sample(obs, n, generator=np.random.default_rng(0))
    except (TypeError, ValueError) as err:
        assert type(policy).__name__ in str(err)
    else:
        assert plans.shape == (n, policy.horizon, 2) and np.all(np.isfinite(plans))


@settings(max_examples=60, deadline=None)
@given(states=_OBS)
def test_random_bc_states_give_actions_or_clean_errors(states: Any) -> None:
    try:
        out = BC(states)
    except (TypeError, ValueError) as err:
        assert "BCPolicy" in str(err)
    else:
        assert np.all(np.isfinite(out)) and out.shape[-1] == 2


def test_bc_states_whose_actions_overflow_are_refused() -> None:
    """Found by the property test above: a finite state near float32's limit overflowed the MLP to NaN actions."""
    with pytest.raises(ValueError, match=r"BCPolicy: states must be within the network's range"):
        BC([0.0, 3.4028235677973366e38, 0.0, 0.0])
