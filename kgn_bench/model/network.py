"""The KGN / KGNv2 network: a compact encoder-decoder at output stride 4 or 2 with the reference's head layout.

The paper's DLA-34 with deformable convolutions is too slow for 2 CPU cores, so the backbone is
a small ResNet-style encoder with an FPN-style decoder:

* encoder: stem Conv3×3/2 (4 → c₀) + BN + ReLU (stride 2), then four stages at strides 4, 8, 16, 32, each
  ``n`` basic residual blocks (two Conv3×3 + BN, ReLU after the sum; the first block of a stage has stride
  2 and a Conv1×1/2 + BN shortcut);
* decoder: a 1×1 lateral convolution of every stage output to ``neck_channels``; from stride 32 down to 4,
  ``p ← ConvBNReLU3×3(upsample₂ₓ,nearest(p) + lateral)``; the result is the stride-4 feature map. With
  ``output_stride = 2`` the same step runs once more with the stem's output as the lateral (``stem_lateral``,
  ``stem_smooth``), giving stride-2 features: on the half-resolution input one output cell is then 4 image
  pixels, the paper's cell (its DLA-34 sees the full frame at stride 4).

``KGNNet.backbone`` maps (B, 4, H, W) to features (B, ``backbone.out_channels``, H/s, W/s) at its ``stride``
s: any module with that interface (a bigger backbone for GPU users) drops in under the same heads.

Heads (the layout of the reference implementation), each Conv3×3(C → ``head_conv``, bias) → ReLU →
Conv1×1(→ channels): ``hm`` 9 (orientation-bin centre heatmaps, LOGITS; final bias −2.19 so the initial
sigmoid is ≈ 0.1), ``reg`` 2 (sub-pixel centre offset), ``kpts`` 72 (channel 8c + 2j + {0: x, 1: y}:
keypoint j ∈ (L, R, TL, TR) of bin c, offset from the integer cell in output px), ``width`` 9 (metres, per
bin), and ``scale`` 9 (‖t_cam‖ in metres, per bin) for variants with the scale branch. All other final
biases are 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import nn

from kgn_bench.model.targets import NUM_BINS, OUTPUT_STRIDE, OUTPUT_STRIDES
from kgn_bench.model.variants import Variant

__all__ = [
    "HM_BIAS",
    "INPUT_MULTIPLE",
    "KGNNet",
    "NetworkConfig",
    "ResNetFPN",
    "build_network",
    "count_parameters",
    "head_channels",
]

HM_BIAS = -2.19
"""Initial bias of the heatmap logits: sigmoid(−2.19) ≈ 0.10 (CenterNet's prior)."""
INPUT_MULTIPLE = 32
"""Network input height and width must be multiples of this (the encoder's total stride)."""


def head_channels(variant: Variant) -> dict[str, int]:
    """Output channels per head for ``variant``: hm 9, reg 2, kpts 72, width 9 and, with the scale branch, scale 9."""
    heads = {"hm": NUM_BINS, "reg": 2, "kpts": NUM_BINS * 4 * 2, "width": NUM_BINS}
    if variant.scale_branch:
        heads["scale"] = NUM_BINS
    return heads


@dataclass(frozen=True)
class NetworkConfig:
    """Sizes of the backbone and heads. Channel counts are multiplied by ``width_mult`` (rounded to ≥ 8).

    ``stem_channels``: stride-2 stem; ``stage_channels`` / ``stage_blocks``: the four stages at strides 4, 8,
    16, 32; ``neck_channels``: decoder width = output feature channels; ``head_conv``: hidden channels of
    each head; ``output_stride``: 4 (the reference's) or 2 (one more decoder level, module docstring). The
    defaults give ≈ 1.7 M parameters.
    """

    in_channels: int = 4
    stem_channels: int = 16
    stage_channels: tuple[int, int, int, int] = (32, 64, 128, 256)
    stage_blocks: tuple[int, int, int, int] = (1, 2, 2, 1)
    neck_channels: int = 32
    head_conv: int = 32
    width_mult: float = 1.0
    output_stride: int = OUTPUT_STRIDE

    def __post_init__(self) -> None:
        if self.output_stride not in OUTPUT_STRIDES:
            raise ValueError(f"output_stride must be one of {OUTPUT_STRIDES}, got {self.output_stride}")
        if len(self.stage_channels) != 4 or len(self.stage_blocks) != 4:
            raise ValueError("stage_channels and stage_blocks need 4 entries (strides 4, 8, 16, 32)")
        if min(self.stage_blocks) < 1:
            raise ValueError(f"every stage needs at least one block, got {self.stage_blocks}")
        sizes = (self.in_channels, self.stem_channels, *self.stage_channels, self.neck_channels, self.head_conv)
        if min(sizes) < 1:
            raise ValueError(f"channel counts must be positive, got {sizes}")
        if not self.width_mult > 0:
            raise ValueError(f"width_mult must be positive, got {self.width_mult}")

    def scaled(self, channels: int) -> int:
        """``channels · width_mult`` rounded to the nearest multiple of 8 (at least 8)."""
        return max(8, round(channels * self.width_mult / 8.0) * 8)


def _conv_bn_relu(c_in: int, c_out: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, stride, 1, bias=False), nn.BatchNorm2d(c_out), nn.ReLU(inplace=True)
    )


class BasicBlock(nn.Module):
    """ResNet basic block: ``relu(BN(conv3×3(relu(BN(conv3×3/s(x))))) + shortcut(x))``."""

    def __init__(self, c_in: int, c_out: int, stride: int) -> None:
        super().__init__()
        self.conv1 = _conv_bn_relu(c_in, c_out, stride)
        self.conv2 = nn.Conv2d(c_out, c_out, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(c_out)
        self.shortcut: nn.Module = nn.Identity()
        if stride != 1 or c_in != c_out:
            self.shortcut = nn.Sequential(nn.Conv2d(c_in, c_out, 1, stride, bias=False), nn.BatchNorm2d(c_out))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return F.relu(self.bn2(self.conv2(self.conv1(x))) + self.shortcut(x), inplace=True)


class ResNetFPN(nn.Module):
    """Residual encoder to stride 32 and top-down FPN decoder back to ``config.output_stride`` (module
    docstring). ``forward`` maps (B, in_channels, H, W) to (B, ``out_channels``, H/s, W/s), s = ``stride``;
    H, W multiples of 32.
    """

    def __init__(self, config: NetworkConfig) -> None:
        super().__init__()
        self.stride = config.output_stride
        stem = config.scaled(config.stem_channels)
        chans = [config.scaled(c) for c in config.stage_channels]
        neck = config.scaled(config.neck_channels)
        self.out_channels = neck
        self.stem = _conv_bn_relu(config.in_channels, stem, stride=2)
        stages, c_prev = [], stem
        for c, n in zip(chans, config.stage_blocks):
            blocks = [BasicBlock(c_prev, c, 2)] + [BasicBlock(c, c, 1) for _ in range(n - 1)]
            stages.append(nn.Sequential(*blocks))
            c_prev = c
        self.stages = nn.ModuleList(stages)
        self.laterals = nn.ModuleList([nn.Conv2d(c, neck, 1) for c in chans])
        self.smooth = nn.ModuleList([_conv_bn_relu(neck, neck) for _ in chans[:-1]])
        self.stem_lateral: nn.Module | None = None
        self.stem_smooth: nn.Module | None = None
        if self.stride == 2:
            self.stem_lateral = nn.Conv2d(stem, neck, 1)
            self.stem_smooth = _conv_bn_relu(neck, neck)
        self._init_weights()

    def _init_weights(self) -> None:
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
                if m.bias is not None:
                    nn.init.zeros_(m.bias)
            elif isinstance(m, nn.BatchNorm2d):
                nn.init.ones_(m.weight)
                nn.init.zeros_(m.bias)
        for m in self.modules():  # residual branches start as identity (zero-init of the last BN)
            if isinstance(m, BasicBlock):
                nn.init.zeros_(m.bn2.weight)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        stem = x = self.stem(x)
        feats = []
        for stage in self.stages:
            x = stage(x)
            feats.append(x)
        p = self.laterals[-1](feats[-1])
        for k in range(len(feats) - 2, -1, -1):
            p = F.interpolate(p, scale_factor=2.0, mode="nearest") + self.laterals[k](feats[k])
            p = self.smooth[k](p)
        if self.stem_lateral is not None and self.stem_smooth is not None:
            p = self.stem_smooth(F.interpolate(p, scale_factor=2.0, mode="nearest") + self.stem_lateral(stem))
        return p


class KGNNet(nn.Module):
    """Backbone + heads. ``forward(x (B, C_in, H, W))`` → dict of (B, C, H/s, W/s) tensors (s the backbone's
    ``stride``), ``hm`` as logits.

    ``ValueError`` if ``x`` is not 4-D with ``in_channels`` channels and H, W multiples of 32.
    ``use_channels_last()`` switches the weights and inputs to the channels-last memory format (same
    results; about 1.3× faster inference on CPU); outputs are always returned contiguous.
    """

    def __init__(self, backbone: nn.Module, heads: dict[str, int], head_conv: int, in_channels: int = 4) -> None:
        super().__init__()
        if getattr(backbone, "out_channels", None) is None:
            raise ValueError("backbone must expose out_channels (channels of its output features)")
        self.backbone = backbone
        self.in_channels = in_channels
        self.channels_last = False
        c = backbone.out_channels
        self.heads = nn.ModuleDict()
        for name, n_out in heads.items():
            head = nn.Sequential(
                nn.Conv2d(c, head_conv, 3, 1, 1), nn.ReLU(inplace=True), nn.Conv2d(head_conv, n_out, 1)
            )
            nn.init.normal_(head[2].weight, std=0.01)
            nn.init.constant_(head[2].bias, HM_BIAS if name == "hm" else 0.0)
            self.heads[name] = head

    def forward(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        if x.ndim != 4 or x.shape[1] != self.in_channels:
            raise ValueError(f"input must be (B, {self.in_channels}, H, W), got {tuple(x.shape)}")
        h, w = x.shape[-2:]
        if h % INPUT_MULTIPLE or w % INPUT_MULTIPLE or h == 0 or w == 0:
            raise ValueError(f"input height and width must be positive multiples of {INPUT_MULTIPLE}, got {h}×{w}")
        if self.channels_last:
            x = x.contiguous(memory_format=torch.channels_last)
        feat = self.backbone(x)
        return {name: head(feat).contiguous() for name, head in self.heads.items()}

    def use_channels_last(self, enabled: bool = True) -> KGNNet:
        """Store weights (and feed inputs) in channels-last (``enabled``) or the default format; returns self."""
        self.channels_last = enabled
        return self.to(memory_format=torch.channels_last if enabled else torch.contiguous_format)


def build_network(variant: Variant, config: NetworkConfig = NetworkConfig()) -> KGNNet:
    """The network for ``variant`` (the scale head only with ``variant.scale_branch``)."""
    return KGNNet(ResNetFPN(config), head_channels(variant), config.scaled(config.head_conv), config.in_channels)


def count_parameters(model: nn.Module, trainable_only: bool = False) -> int:
    """Number of parameters (all, or only those with ``requires_grad``)."""
    return sum(p.numel() for p in model.parameters() if p.requires_grad or not trainable_only)
