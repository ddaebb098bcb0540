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
three k5 heads on the 16-channel map. No skip connections, no normalisation: 313,238 parameters. The three
heads keep their own parameters (VGN's layout) but run as one 16→6 convolution of their stacked kernels: the
same maps, and on the CPU a third of the time of three convolutions over the full-resolution grid, which is
where most of the network's time goes.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import nn
from torch.nn import functional as F

__all__ = ["VGNNet", "VGNOutput"]


@dataclass
class VGNOutput:
    """The three per-voxel maps (shapes in the module docstring)."""

    quality: torch.Tensor
    rotation: torch.Tensor
    width: torch.Tensor


def _conv(c_in: int, c_out: int, k: int, stride: int = 1) -> nn.Conv3d:
    return nn.Conv3d(c_in, c_out, k, stride=stride, padding=k // 2)


class VGNNet(nn.Module):
    """The network; ``forward`` needs R divisible by 8. ``use_channels_last()`` stores the weights (and feeds the
    input) in the channels-last 3D memory format: about 2.2× faster training and inference on CPU (oneDNN's
    AVX2 kernels), results equal to float rounding; outputs are always returned contiguous."""

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
            x = F.relu(conv(x))
        for conv in self.decoder:
            x = F.interpolate(F.relu(conv(x)), scale_factor=2, mode="nearest")
        heads = (self.quality, self.rotation, self.width)
        weight = torch.cat([h.weight for h in heads])
        bias = torch.cat([h.bias for h in heads])
        y = F.conv3d(x, weight, bias, padding=self.quality.padding)
        return VGNOutput(
            quality=torch.sigmoid(y[:, :1]).contiguous(),
            rotation=F.normalize(y[:, 1:5], dim=1).contiguous(),
            width=y[:, 5:].contiguous(),
        )
