"""VGN's volumetric grasp network: a small 3D fully-convolutional encoder-decoder on a TSDF.

Input: ``(B, 1, R, R, R)`` (``kgn_bench.tsdf.TSDFVolume.network_input``, R = 40 for VGN). Output, at every voxel
of the same grid:

- ``quality`` ``(B, 1, R, R, R)``: the probability that a grasp centred at that voxel holds (a sigmoid);
- ``rotation`` ``(B, 4, R, R, R)``: the grasp's orientation as a unit quaternion ``(w, x, y, z)`` of
  ``R_grid_grasp`` (grid axes are the world's; grasp frame as everywhere in the project: +x approach, z the
  closing axis), L2-normalised over the channel axis; ``q`` and ``q · R_x(π)`` are the same grasp;
- ``width`` ``(B, 1, R, R, R)``: the opening, in voxels (linear).

Layers (Breyer et al., CoRL 2020): encoder conv 1→16 k5 s2, 16→32 k3 s2, 32→64 k3 s2 (R → R/8), decoder
conv 64→64 k3, ×2 nearest upsampling, conv 64→32 k3, ×2, conv 32→16 k5, ×2, every conv followed by a ReLU;
three k5 heads on the 16-channel map. No skip connections, no normalisation: 313,238 parameters, in VGN's
layout (``state_dict`` keys per layer and head).

**How it runs: polyphase convolutions.** Two of the k5 convolutions read a map that was just upsampled ×2 by
repetition (the last decoder layer and the heads, 92 % of the network's 1.39 G multiply-adds when run as
written). Such a convolution is computed exactly on the coarse map instead (``upsampled_conv``): output voxel
``f = 2c + p`` (parity ``p`` per axis) reads fine offsets ``o ∈ {−2..2}``, i.e. coarse cells
``c + ⌊(p + o − 2)/2⌋ ∈ {c − 1, c, c + 1}``, so for each of the 8 parities the five taps per axis fold into three
(``fold_kernel``), and one k3 convolution with 8× the output channels on the coarse map, its phases interleaved,
gives the fine output. The zero padding agrees: the fine padding cells are exactly the coarse padding cells.
Same maps to float rounding (``tests/test_vgn_network.py`` compares with the layers as written), 0.38 G
multiply-adds; the three heads run as one 16→6 convolution of their stacked kernels.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

__all__ = ["VGNNet", "VGNOutput", "conv3d", "fold_kernel", "upsampled_conv"]


@dataclass
class VGNOutput:
    """The three per-voxel maps (shapes in the module docstring)."""

    quality: torch.Tensor
    rotation: torch.Tensor
    width: torch.Tensor


def _conv(c_in: int, c_out: int, k: int, stride: int = 1) -> nn.Conv3d:
    return nn.Conv3d(c_in, c_out, k, stride=stride, padding=k // 2)


def conv3d(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor, stride: int = 1, padding: int = 0
           ) -> torch.Tensor:
    """``F.conv3d``, sent to oneDNN on the CPU. PyTorch's dispatch keeps a batch-1 k3 convolution of a small
    map (fewer than 20,480 values in its first four dimensions) on its im2col path, 1.5-5× slower at VGN's sizes
    than oneDNN's kernels; same function, gradients included."""
    if x.device.type == "cpu" and x.dtype == torch.float32 and torch.backends.mkldnn.is_available():
        return torch.ops.aten.mkldnn_convolution(x, weight, bias, [padding] * 3, [stride] * 3, [1, 1, 1], 1)
    return F.conv3d(x, weight, bias, stride=stride, padding=padding)


def _layer(conv: nn.Conv3d, x: torch.Tensor) -> torch.Tensor:
    return conv3d(x, conv.weight, conv.bias, conv.stride[0], conv.padding[0])


def _fold_matrices(device: torch.device, dtype: torch.dtype) -> torch.Tensor:
    """(2, 3, 5): ``M[p, d, o] = 1`` where fine tap ``o`` (offset ``o − 2``) of an output of parity ``p`` reads
    coarse cell ``d − 1`` relative to the output's own, ``d = ⌊(p + o − 2)/2⌋ + 1``."""
    m = torch.zeros(2, 3, 5, device=device, dtype=dtype)
    for p in range(2):
        for o in range(5):
            m[p, (p + o - 2) // 2 + 1, o] = 1.0
    return m


def fold_kernel(weight: torch.Tensor) -> torch.Tensor:
    """A k5 kernel ``(C_out, C_in, 5, 5, 5)`` applied after ×2 nearest upsampling, as the k3 kernel
    ``(8·C_out, C_in, 3, 3, 3)`` on the coarse map (module docstring): output channel ``φ·C_out + c`` is channel
    ``c`` at parity ``φ = 4 p_0 + 2 p_1 + p_2``."""
    m = _fold_matrices(weight.device, weight.dtype)
    folded = torch.einsum("xao,ybq,zcr,kioqr->xyzkiabc", m, m, m, weight)
    return folded.reshape(8 * weight.shape[0], *weight.shape[1:2], 3, 3, 3)


def upsampled_conv(x: torch.Tensor, weight: torch.Tensor, bias: torch.Tensor) -> torch.Tensor:
    """``conv3d(interpolate(x, ×2, nearest), weight, bias, padding=2)`` for a k5 ``weight``, computed on the coarse
    ``x`` (B, C_in, D, H, W) with ``fold_kernel``; returns (B, C_out, 2D, 2H, 2W), contiguous."""
    c_out = weight.shape[0]
    y = conv3d(x, fold_kernel(weight), bias.repeat(8), padding=1)
    b, _, d, h, w = y.shape
    y = y.reshape(b, 2, 2, 2, c_out, d, h, w).permute(0, 4, 5, 1, 6, 2, 7, 3)
    return y.reshape(b, c_out, 2 * d, 2 * h, 2 * w)


class VGNNet(nn.Module):
    """The network; ``forward`` needs R divisible by 8. ``use_channels_last()`` stores the weights (and feeds the
    input) in the channels-last 3D memory format, oneDNN's own (2.2× faster on the CPU when the network ran its
    layers as written; about even since the polyphase convolutions), results equal to float rounding; outputs
    are always returned contiguous."""

    def __init__(self) -> None:
        super().__init__()
        self.encoder = nn.ModuleList([_conv(1, 16, 5, 2), _conv(16, 32, 3, 2), _conv(32, 64, 3, 2)])
        self.decoder = nn.ModuleList([_conv(64, 64, 3), _conv(64, 32, 3), _conv(32, 16, 5)])
        self.quality = _conv(16, 1, 5)
        self.rotation = _conv(16, 4, 5)
        self.width = _conv(16, 1, 5)
        self.channels_last = False

    def use_channels_last(self, enabled: bool = True) -> VGNNet:
        """Store weights (and feed inputs) in channels-last 3D (``enabled``) or the default format; returns self."""
        self.channels_last = enabled
        return self.to(memory_format=torch.channels_last_3d if enabled else torch.contiguous_format)

    def forward(self, x: torch.Tensor) -> VGNOutput:
        if x.ndim != 5 or x.shape[1] != 1 or any(s % 8 for s in x.shape[2:]):
            raise ValueError(f"VGN needs (B, 1, R, R, R) with R divisible by 8, got {tuple(x.shape)}")
        if self.channels_last:
            x = x.contiguous(memory_format=torch.channels_last_3d)
        for conv in self.encoder:
            x = F.relu(_layer(conv, x))
        first, second, last = self.decoder
        x = F.interpolate(F.relu(_layer(first, x)), scale_factor=2, mode="nearest")
        x = F.relu(_layer(second, x))  # at R/4; the next layer reads it upsampled to R/2 (upsampled_conv)
        x = F.relu(upsampled_conv(x, last.weight, last.bias))  # at R/2; the heads read it upsampled to R
        if self.channels_last:
            x = x.contiguous(memory_format=torch.channels_last_3d)
        heads = (self.quality, self.rotation, self.width)
        weight = torch.cat([h.weight for h in heads])
        bias = torch.cat([h.bias for h in heads])
        y = upsampled_conv(x, weight, bias)
        q = y[:, 1:5]  # q / max(‖q‖, 1e-12), F.normalize's rule, in elementwise kernels (its norm is 30× slower here)
        return VGNOutput(
            quality=torch.sigmoid(y[:, :1]).contiguous(),
            rotation=(q * torch.rsqrt((q * q).sum(dim=1, keepdim=True).clamp_min(1e-24))).contiguous(),
            width=y[:, 5:].contiguous(),
        )
