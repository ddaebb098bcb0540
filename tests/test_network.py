"""The encoder-decoder (output stride 4 or 2) and its heads."""

from __future__ import annotations

import pytest
import torch
from torch import nn

from kgn_bench.model.network import (
    HM_BIAS,
    KGNNet,
    NetworkConfig,
    build_network,
    count_parameters,
    head_channels,
)
from kgn_bench.model.variants import VARIANTS, get_variant


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """One intra-op thread: small convolutions gain nothing from two, and two threads stall badly when
    the machine's cores are busy with other work."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="module")
def net_v2():
    torch.manual_seed(0)
    return build_network(get_variant("kgnv2")).eval()


@pytest.mark.parametrize("name", list(VARIANTS))
def test_output_shapes_for_every_variant(name):
    variant = get_variant(name)
    torch.manual_seed(0)
    net = build_network(variant)
    with torch.no_grad():
        out = net(torch.randn(2, 4, 64, 96))
    expected = {"hm": 9, "reg": 2, "kpts": 72, "width": 9}
    if variant.scale_branch:
        expected["scale"] = 9
    assert {k: v.shape[1] for k, v in out.items()} == expected == head_channels(variant)
    for v in out.values():
        assert v.shape[0] == 2 and v.shape[2:] == (16, 24) and v.dtype == torch.float32


def test_output_stride_two_adds_one_decoder_level_and_keeps_the_stride_four_weights():
    torch.manual_seed(0)
    four = build_network(get_variant("kgnv2"))
    torch.manual_seed(0)
    two = build_network(get_variant("kgnv2"), NetworkConfig(output_stride=2)).eval()
    assert two.backbone.stride == 2 and four.backbone.stride == 4
    with torch.no_grad():
        out = two(torch.randn(1, 4, 64, 96))
    assert all(v.shape[2:] == (32, 48) for v in out.values())
    extra = set(two.state_dict()) - set(four.state_dict())
    assert extra and all(k.startswith(("backbone.stem_lateral", "backbone.stem_smooth")) for k in extra)
    assert set(four.state_dict()) <= set(two.state_dict())
    with pytest.raises(ValueError, match="output_stride"):
        NetworkConfig(output_stride=8)


def test_heatmap_prior_and_zero_biases(net_v2):
    for name, head in net_v2.heads.items():
        bias = head[-1].bias.detach()
        assert torch.all(bias == (HM_BIAS if name == "hm" else 0.0))
    with torch.no_grad():
        out = net_v2(torch.randn(1, 4, 64, 64))
    p = torch.sigmoid(out["hm"])
    assert abs(p.mean().item() - 0.1) < 0.01 and p.std().item() < 0.02


@pytest.mark.parametrize("shape", [(1, 4, 60, 64), (1, 4, 64, 100), (1, 3, 64, 64), (4, 64, 64)])
def test_rejects_bad_input_sizes(net_v2, shape):
    with pytest.raises(ValueError, match=r"multiples of 32|input must be"):
        net_v2(torch.zeros(shape))


def test_parameter_count_and_backbone_interface(net_v2):
    n = count_parameters(net_v2)
    assert n == sum(p.numel() for p in net_v2.parameters())
    assert 1_000_000 <= n <= 3_000_000
    feat = net_v2.backbone(torch.zeros(1, 4, 64, 128))
    assert feat.shape == (1, net_v2.backbone.out_channels, 16, 32)
    for p in net_v2.backbone.parameters():
        p.requires_grad_(False)
    assert count_parameters(net_v2, trainable_only=True) == sum(p.numel() for p in net_v2.heads.parameters())
    for p in net_v2.backbone.parameters():
        p.requires_grad_(True)


def test_other_backbone_drops_in():
    class Tiny(nn.Module):
        out_channels = 8

        def __init__(self):
            super().__init__()
            self.conv = nn.Conv2d(4, 8, 4, stride=4)

        def forward(self, x):
            return self.conv(x)

    net = KGNNet(Tiny(), head_channels(get_variant("kgn")), head_conv=16)
    out = net(torch.zeros(1, 4, 32, 64))
    assert out["kpts"].shape == (1, 72, 8, 16) and "scale" not in out
    with pytest.raises(ValueError, match="out_channels"):
        KGNNet(nn.Identity(), {"hm": 9}, head_conv=8)


def test_channels_last_gives_the_same_outputs(net_v2):
    x = torch.randn(1, 4, 64, 96)
    with torch.no_grad():
        ref = net_v2(x)
        net_v2.use_channels_last()
        out = net_v2(x)
        net_v2.use_channels_last(False)
    for k in ref:
        assert out[k].is_contiguous()
        torch.testing.assert_close(out[k], ref[k], atol=1e-4, rtol=1e-4)


def test_config_width_and_validation():
    half = NetworkConfig(width_mult=0.5)
    assert half.scaled(32) == 16 and half.scaled(8) == 8
    small = build_network(get_variant("kgn"), half)
    assert small.backbone.out_channels == 16
    assert count_parameters(small) < count_parameters(build_network(get_variant("kgn")))
    with pytest.raises(ValueError, match="4 entries"):
        NetworkConfig(stage_channels=(32, 64, 128))
    with pytest.raises(ValueError, match="at least one block"):
        NetworkConfig(stage_blocks=(1, 0, 1, 1))
    with pytest.raises(ValueError, match="width_mult"):
        NetworkConfig(width_mult=0.0)
