"""ExportDenoiser: the lean ONNX form of the Diffusion Policy's denoiser computes what DiffusionNet computes."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tiny_policies import UNET_ARCH
from torch import nn

from steer_envs.baselines.diffusion import DiffusionConfig
from steer_envs.baselines.diffusion.acceleration import FastNetwork
from steer_envs.baselines.diffusion.export import ExportDenoiser
from steer_envs.baselines.diffusion.network import DiffusionNet

#: networks unlike the shipped one: two or four levels, kernel 3 or 7, no time channel, no observation encoder
CONFIGS = [
    UNET_ARCH,
    {"horizon": 32, "down_dims": (8, 16, 16, 32), "kernel_size": 7, "n_groups": 4, "time_channel": False},
    {"horizon": 8, "down_dims": (8,), "obs_embed_dim": 0, "n_obs_steps": 1, "prediction": "epsilon"},
]


def _net(config: dict, seed: int = 0) -> DiffusionNet:
    torch.manual_seed(seed)
    net = DiffusionNet(DiffusionConfig(**{"obs_dim": 3, "action_dim": 2, **config})).eval()
    with torch.no_grad():  # GroupNorm's affine starts at (1, 0): make it count
        for module in net.modules():
            if isinstance(module, nn.GroupNorm):
                module.weight.uniform_(0.5, 1.5)
                module.bias.uniform_(-0.5, 0.5)
    return net


def _inputs(net: DiffusionNet, n: int, config: dict) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(1)
    width = config.get("n_obs_steps", 2) * 3
    x = torch.randn(n, config["horizon"], 2, generator=g)
    return x, torch.randint(0, 100, (n,), generator=g), torch.randn(n, width, generator=g)


@pytest.mark.parametrize("config", CONFIGS, ids=["two-levels", "four-levels", "one-level-no-encoder"])
def test_export_denoiser_computes_the_network_for_shared_and_per_plan_conditions(config: dict) -> None:
    net = _net(config)
    x, t, cond = _inputs(net, 5, config)
    with torch.no_grad():
        per_plan = ExportDenoiser(net, shared_condition=False)(x, t, cond)
        torch.testing.assert_close(per_plan, net(x, t, cond), rtol=0, atol=1e-5)
        shared = ExportDenoiser(net, shared_condition=True)(x, t[:1], cond[:1])
        torch.testing.assert_close(shared, net(x, t[:1].expand(5), cond[:1].expand(5, -1)), rtol=0, atol=1e-5)


@pytest.mark.parametrize("config", CONFIGS, ids=["two-levels", "four-levels", "one-level-no-encoder"])
def test_onnx_runtime_runs_the_export_for_any_batch(config: dict) -> None:
    pytest.importorskip("onnxruntime")
    net, fast = _net(config), FastNetwork("onnx")
    for n in (3, 6):
        x, t, cond = _inputs(net, n, config)
        with torch.no_grad():
            expected = net(x, t, cond)
            torch.testing.assert_close(fast(net, x, t, cond), expected, rtol=0, atol=1e-5)
            shared = net(x, t[:1].expand(n), cond[:1].expand(n, -1))
            torch.testing.assert_close(fast(net, x, t[:1], cond[:1]), shared, rtol=0, atol=1e-5)
    assert len(fast._sessions) == 2  # one export per kind of condition, each for every batch size


def test_export_denoiser_keeps_its_own_weights() -> None:
    net = _net(CONFIGS[0])
    export = ExportDenoiser(net, shared_condition=False)
    x, t, cond = _inputs(net, 2, CONFIGS[0])
    with torch.no_grad():
        before = export(x, t, cond)
        for w in net.parameters():
            w.mul_(1.1)
        torch.testing.assert_close(export(x, t, cond), before, rtol=0, atol=0)
        assert not torch.allclose(net(x, t, cond), before)
    assert all(m.weight.ndim == 3 for m in net.modules() if isinstance(m, nn.Conv1d))  # the original is untouched


def test_export_denoiser_wants_a_diffusion_net() -> None:
    with pytest.raises(TypeError, match=r"ExportDenoiser: `net` must be a DiffusionNet, got Linear"):
        ExportDenoiser(nn.Linear(2, 2), shared_condition=True)  # type: ignore[arg-type]


def test_onnx_runs_another_model_with_a_shared_condition_expanded() -> None:
    """A model that is not a DiffusionNet is exported as is; a shared row is expanded for it."""
    pytest.importorskip("onnxruntime")

    class Plain(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.conv = nn.Conv1d(2, 2, 3, padding=1)
            self.cond = nn.Linear(4, 2)

        def forward(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
            h = self.conv(x.transpose(1, 2)) + self.cond(cond).unsqueeze(-1) + t[:, None, None].float() / 100
            return h.transpose(1, 2)

    model, fast = Plain().eval(), FastNetwork("onnx")
    x, t, cond = torch.randn(4, 8, 2), torch.tensor([30]), torch.randn(1, 4)
    with torch.no_grad():
        expected = model(x, t.expand(4), cond.expand(4, -1))
        np.testing.assert_allclose(fast(model, x, t, cond).numpy(), expected.numpy(), rtol=0, atol=1e-5)


@pytest.mark.parametrize("mode", ["onnx", "trace"])
def test_threads_sharing_a_policy_build_its_export_once_at_a_time(mode: str) -> None:
    """steer-ui's sessions share one policy: first calls from several threads at once must not clash."""
    if mode == "onnx":
        pytest.importorskip("onnxruntime")
    from concurrent.futures import ThreadPoolExecutor

    net, fast = _net(CONFIGS[0]), FastNetwork(mode)
    x, t, cond = _inputs(net, 4, CONFIGS[0])
    with torch.no_grad():
        expected = net(x, t[:1].expand(4), cond[:1].expand(4, -1))

        def call(_: int) -> torch.Tensor:
            with torch.no_grad():
                return fast(net, x, t[:1], cond[:1])

        with ThreadPoolExecutor(max_workers=6) as pool:
            outputs = list(pool.map(call, range(12)))
    for out in outputs:
        torch.testing.assert_close(out, expected, rtol=0, atol=1e-5)
