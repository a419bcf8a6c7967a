"""The Diffusion Policy's denoiser rewritten for a lean ONNX graph (fewer, cheaper nodes for ONNX Runtime on CPU).

At Diffusion Policy's widths an ONNX Runtime call of the denoiser is bound
by per-node work more than by arithmetic: every activation of a batch-32 plan
is only ~32k floats, so a broadcast ``Mul``/``Add`` over short rows costs as
much as a convolution's share. :class:`ExportDenoiser` computes exactly what
:class:`~steer_envs.baselines.diffusion.modeling.DiffusionNet` computes, with
the graph shaped for ONNX Runtime:

- 4-D ``(n, C, 1, L)`` activations throughout, every ``Conv1d`` as a ``(1, k)``
  2-D convolution (ONNX Runtime's blocked NCHWc kernels are 2-D only);
- GroupNorm as ``InstanceNormalization`` on a reshape with static sizes (no
  ``Shape`` arithmetic for the free batch size);
- per-channel affines (GroupNorm's, and FiLM's where one condition is shared
  by the batch) as ``BatchNormalization`` in inference form, one node instead
  of a broadcast ``Mul`` and ``Add``;
- every block's FiLM in one ``Gemm`` (the blocks' linear layers stacked).

With ``shared_condition`` the graph takes one timestep ``(1,)`` and one
condition ``(1, c)`` for the whole batch (as the ITPS samplers call it), and
the condition path runs once instead of per plan.
"""

from __future__ import annotations

import copy
from typing import cast

import torch
import torch.nn.functional as F
from diffusers.models.embeddings import get_timestep_embedding
from torch import nn

from steer_envs.baselines.diffusion.network import ConditionalUnet1D, DiffusionNet, _ConvBlock, _FiLMResBlock

__all__ = ["ExportDenoiser"]


def _conv(conv: nn.Conv1d | nn.Conv2d, h: torch.Tensor) -> torch.Tensor:
    """``conv`` (a ``Conv1d`` whose weights were made 2-D in :class:`ExportDenoiser`) on ``(n, C, 1, L)``."""
    return F.conv2d(h, conv.weight, conv.bias, stride=(1, conv.stride[-1]), padding=(0, _padding(conv)))


def _padding(conv: nn.Module) -> int:
    return int(cast(tuple[int, ...], conv.padding)[-1])


def _affine(h: torch.Tensor, scale: torch.Tensor, shift: torch.Tensor) -> torch.Tensor:
    """``h * scale + shift`` per channel (``scale``, ``shift``: ``(C,)``) as one ``BatchNormalization`` node."""
    c = scale.shape[0]
    mean, var = torch.zeros(c, dtype=h.dtype), torch.ones(c, dtype=h.dtype)
    return F.batch_norm(h, mean, var, scale, shift, training=False, momentum=0.0, eps=0.0)


class ExportDenoiser(nn.Module):
    """``DiffusionNet``'s forward, ``(x (n, H, d), t, cond) -> (n, H, d)``, written for export (see the module doc).

    Holds copies of the network's weights (taken at construction); build it
    anew after the weights change. ``shared_condition``: ``t (1,)`` and
    ``cond (1, c)`` for the whole batch; otherwise ``(n,)`` and ``(n, c)``.
    """

    def __init__(self, net: DiffusionNet, *, shared_condition: bool) -> None:
        super().__init__()
        if not isinstance(net, DiffusionNet):
            raise TypeError(f"ExportDenoiser: `net` must be a DiffusionNet, got {type(net).__name__}")
        net = copy.deepcopy(net).eval()
        for module in net.modules():
            if isinstance(module, nn.Conv1d):
                module.weight = nn.Parameter(module.weight.detach().unsqueeze(2))
        self.net = net
        self.shared_condition = shared_condition
        unet = net.unet
        blocks = [m for m in unet.modules() if isinstance(m, _FiLMResBlock)]
        # each block's FiLM output is [scale, shift], a half each
        self._film_sizes = [cast(nn.Linear, b.film[1]).out_features // 2 for b in blocks for _ in range(2)]
        self._block_index = {id(b): i for i, b in enumerate(blocks)}
        self.film_weight = nn.Parameter(torch.cat([cast(nn.Linear, b.film[1]).weight.detach() for b in blocks]))
        self.film_bias = nn.Parameter(torch.cat([cast(nn.Linear, b.film[1]).bias.detach() for b in blocks]))
        horizon = net.ramp.shape[1] if net.time_channel else None
        self._horizon = None if horizon is None else int(horizon)

    def forward(self, x: torch.Tensor, t: torch.Tensor, cond: torch.Tensor) -> torch.Tensor:
        net, unet = self.net, cast(ConditionalUnet1D, self.net.unet)
        length = self._horizon if self._horizon is not None else int(x.shape[1])
        emb = get_timestep_embedding(t, unet.step_embed_dim, flip_sin_to_cos=True, downscale_freq_shift=1)
        condition = torch.cat([unet.step_mlp(emb.to(x.dtype)), net.obs_encoder(cond)], dim=-1)
        films = F.linear(F.silu(condition), self.film_weight, self.film_bias)
        if self.shared_condition:
            halves = films.reshape(-1).split(self._film_sizes)
        else:
            halves = films.split(self._film_sizes, dim=1)
        if net.time_channel:
            x = torch.cat([x, net.ramp.expand(x.shape[0], -1, -1).to(x.dtype)], dim=-1)
        h = x.transpose(1, 2).unsqueeze(2)

        def res(block: nn.Module, h: torch.Tensor, length: int) -> torch.Tensor:
            b = cast(_FiLMResBlock, block)
            index = 2 * self._block_index[id(b)]
            scale, shift = halves[index], halves[index + 1]
            y = self._conv_block(b.block1, h, length)
            if self.shared_condition:
                y = _affine(y, scale, shift)
            else:
                c = scale.shape[-1]
                y = y * scale.reshape(-1, c, 1, 1) + shift.reshape(-1, c, 1, 1)
            skip = h if isinstance(b.residual, nn.Identity) else _conv(cast(nn.Conv1d, b.residual), h)
            return self._conv_block(b.block2, y, length) + skip

        skips = []
        for level in unet.down:
            res1, res2, downsample = cast(nn.ModuleList, level)
            h = res(res2, res(res1, h, length), length)
            skips.append(h)
            if not isinstance(downsample, nn.Identity):
                down = cast(nn.Conv1d, downsample)
                h = _conv(down, h)
                length = (length + 2 * _padding(down) - down.kernel_size[0]) // down.stride[0] + 1
        for block in unet.mid:
            h = res(block, h, length)
        for level in unet.up:
            res1, res2, upsample = cast(nn.ModuleList, level)
            h = torch.cat([h, skips.pop()], dim=1)
            h = res(res2, res(res1, h, length), length)
            up = cast(nn.ConvTranspose1d, upsample)
            stride = up.stride[0]
            h = F.conv_transpose2d(h, up.weight.unsqueeze(2), up.bias, stride=(1, stride), padding=(0, _padding(up)))
            length = (length - 1) * stride - 2 * _padding(up) + up.kernel_size[0]
        final = cast(nn.Sequential, unet.final)
        h = _conv(cast(nn.Conv1d, final[1]), self._conv_block(final[0], h, length))
        return h.squeeze(2).transpose(1, 2)

    @staticmethod
    def _conv_block(block: nn.Module, h: torch.Tensor, length: int) -> torch.Tensor:
        """``Conv -> GroupNorm -> SiLU`` on ``(n, C, 1, L)``; GroupNorm as InstanceNormalization of static groups."""
        conv, norm = cast(nn.Conv1d, cast(_ConvBlock, block)[0]), cast(nn.GroupNorm, cast(_ConvBlock, block)[1])
        h = _conv(conv, h)
        channels, groups = conv.out_channels, norm.num_groups
        ones, zeros = torch.ones(groups, dtype=h.dtype), torch.zeros(groups, dtype=h.dtype)
        grouped = h.reshape(-1, groups, (channels // groups) * length)
        h = F.instance_norm(grouped, weight=ones, bias=zeros, eps=norm.eps).reshape(-1, channels, 1, length)
        return F.silu(_affine(h, norm.weight, norm.bias))
