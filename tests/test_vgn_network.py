"""VGN's network: its published size, its output maps, and that it learns a voxel's label."""

import pytest
import torch

from kgn_bench.model.vgn_network import VGNNet, conv3d, fold_kernel, upsampled_conv


def test_parameter_count_is_vgns():
    assert sum(p.numel() for p in VGNNet().parameters()) == 313_238


def test_outputs_cover_the_grid():
    torch.manual_seed(0)
    out = VGNNet()(torch.rand(2, 1, 40, 40, 40))
    assert out.quality.shape == out.width.shape == (2, 1, 40, 40, 40)
    assert out.rotation.shape == (2, 4, 40, 40, 40)
    assert 0 <= out.quality.min() and out.quality.max() <= 1
    torch.testing.assert_close(out.rotation.norm(dim=1), torch.ones(2, 40, 40, 40))


def test_a_grid_not_divisible_by_eight_is_refused():
    with pytest.raises(ValueError, match="divisible by 8"):
        VGNNet()(torch.rand(1, 1, 20, 20, 20))


def test_it_learns_which_voxel_holds():
    """Fifty Adam steps on one 16³ grid separate a positive voxel from a negative one."""
    torch.manual_seed(0)
    net = VGNNet()
    x = torch.zeros(1, 1, 16, 16, 16)
    x[0, 0, 4:8, 4:8, 0:4] = 0.5  # a block of surface in one corner
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    for _ in range(50):
        q = net(x).quality[0, 0]
        loss = torch.nn.functional.binary_cross_entropy(torch.stack([q[5, 5, 2], q[12, 12, 12]]),
                                                        torch.tensor([1.0, 0.0]))
        opt.zero_grad()
        loss.backward()
        opt.step()
    q = net(x).quality[0, 0].detach()
    assert q[5, 5, 2] > 0.8 and q[12, 12, 12] < 0.2


def test_channels_last_gives_the_same_maps_in_the_default_layout():
    torch.manual_seed(0)
    net = VGNNet()
    x = torch.rand(1, 1, 16, 16, 16)
    ref = net(x)
    out = net.use_channels_last()(x)
    assert net.encoder[0].weight.is_contiguous(memory_format=torch.channels_last_3d)
    for a, b in ((ref.quality, out.quality), (ref.rotation, out.rotation), (ref.width, out.width)):
        assert b.is_contiguous()
        torch.testing.assert_close(a, b, atol=1e-5, rtol=1e-4)
    assert net.use_channels_last(False).encoder[0].weight.is_contiguous()


def test_the_stacked_heads_compute_each_head_as_its_own_convolution():
    torch.manual_seed(1)
    net = VGNNet()
    x = torch.rand(1, 1, 16, 16, 16)
    out = net(x)
    h = x
    for conv in net.encoder:
        h = torch.relu(conv(h))
    for conv in net.decoder:
        h = torch.nn.functional.interpolate(torch.relu(conv(h)), scale_factor=2, mode="nearest")
    torch.testing.assert_close(out.quality, torch.sigmoid(net.quality(h)))
    torch.testing.assert_close(out.rotation, torch.nn.functional.normalize(net.rotation(h), dim=1))
    torch.testing.assert_close(out.width, net.width(h))


@pytest.mark.parametrize("shape", [(2, 3, 4, 5, 6), (1, 16, 10, 10, 10)])
def test_a_k5_convolution_of_an_upsampled_map_is_computed_on_the_coarse_map(shape):
    """``upsampled_conv`` against the convolution of the ×2 nearest-upsampled map, borders included, on maps
    that are not cubes and with a batch of two."""
    torch.manual_seed(2)
    x = torch.rand(*shape)
    weight, bias = torch.randn(7, shape[1], 5, 5, 5), torch.randn(7)
    fine = torch.nn.functional.interpolate(x, scale_factor=2, mode="nearest")
    expected = torch.nn.functional.conv3d(fine, weight, bias, padding=2)
    out = upsampled_conv(x, weight, bias)
    assert out.shape == expected.shape and out.is_contiguous()
    torch.testing.assert_close(out, expected, atol=1e-4, rtol=1e-5)
    assert fold_kernel(weight).shape == (56, shape[1], 3, 3, 3)


def test_the_cpu_convolution_has_pytorchs_values_and_gradients():
    torch.manual_seed(3)
    x = torch.rand(1, 4, 6, 6, 6, requires_grad=True)
    w, b = torch.randn(5, 4, 3, 3, 3, requires_grad=True), torch.randn(5, requires_grad=True)
    for stride in (1, 2):
        ours = conv3d(x, w, b, stride=stride, padding=1)
        grads = torch.autograd.grad(ours.square().sum(), (x, w, b))
        ref = torch.nn.functional.conv3d(x, w, b, stride=stride, padding=1)
        ref_grads = torch.autograd.grad(ref.square().sum(), (x, w, b))
        torch.testing.assert_close(ours, ref, atol=1e-5, rtol=1e-5)
        for g, r in zip(grads, ref_grads, strict=True):
            torch.testing.assert_close(g, r, atol=1e-3, rtol=1e-4)
