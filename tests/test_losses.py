"""Focal loss, gathered masked L1 with per-bin channel selection, and the weighted KGN loss."""

from __future__ import annotations

import math

import pytest
import torch

from kgn_bench.model.losses import LossWeights, focal_loss, gather, kgn_loss, masked_l1, select_bin
from kgn_bench.model.network import NetworkConfig, build_network
from kgn_bench.model.variants import get_variant


@pytest.fixture(autouse=True, scope="module")
def _one_thread():
    """One intra-op thread: small convolutions gain nothing from two, and two threads stall badly when
    the machine's cores are busy with other work."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


def _sig(x: float) -> float:
    return 1.0 / (1.0 + math.exp(-x))


def test_focal_loss_hand_computed():
    logits = torch.tensor([[[[0.0, 1.0], [-1.0, 2.0]]]])
    gt = torch.tensor([[[[1.0, 0.5], [0.0, 0.0]]]])
    p = [_sig(0.0), _sig(1.0), _sig(-1.0), _sig(2.0)]
    pos = (1 - p[0]) ** 2 * math.log(p[0])
    neg = 0.5**4 * p[1] ** 2 * math.log(1 - p[1]) + p[2] ** 2 * math.log(1 - p[2]) + p[3] ** 2 * math.log(1 - p[3])
    assert focal_loss(logits, gt).item() == pytest.approx(-(pos + neg), rel=1e-6)
    # two positives (over batch and channels) halve the sum
    logits2 = torch.cat([logits, logits], dim=1)
    gt2 = torch.cat([gt, gt], dim=1)
    assert focal_loss(logits2, gt2).item() == pytest.approx(-(pos + neg), rel=1e-6)
    # no positive: the negative sum alone
    gt0 = gt.clone()
    gt0[0, 0, 0, 0] = 0.9
    neg0 = neg + 0.1**4 * p[0] ** 2 * math.log(1 - p[0])
    assert focal_loss(logits, gt0).item() == pytest.approx(-neg0, rel=1e-6)


def test_focal_loss_clamps_extreme_logits():
    logits = torch.tensor([[[[100.0, -100.0]]]], requires_grad=True)
    gt = torch.tensor([[[[0.0, 1.0]]]])
    loss = focal_loss(logits, gt)
    c = 1e-4
    expected = -((1 - c) ** 2 * math.log(c) + (1 - c) ** 2 * math.log(c))
    assert loss.item() == pytest.approx(expected, rel=1e-4)
    loss.backward()
    assert torch.all(torch.isfinite(logits.grad))
    with pytest.raises(ValueError, match="shape"):
        focal_loss(torch.zeros(1, 9, 4, 4), torch.zeros(1, 9, 4, 5))


def test_gather_reads_flat_cells():
    feat = torch.arange(2 * 3 * 2 * 4, dtype=torch.float32).reshape(2, 3, 2, 4)
    ind = torch.tensor([[0, 5], [7, 2]])  # cell 5 = (y 1, x 1)
    out = gather(feat, ind)
    assert out.shape == (2, 2, 3)
    assert out[0, 1].tolist() == [feat[0, c, 1, 1].item() for c in range(3)]
    assert out[1, 0].tolist() == [feat[1, c, 1, 3].item() for c in range(3)]


def test_masked_l1_selects_bins_and_ignores_masked_slots():
    h, w = 2, 3
    n = torch.arange(h * w, dtype=torch.float32).reshape(1, 1, h, w)
    width_map = 10.0 * torch.arange(9, dtype=torch.float32).reshape(1, 9, 1, 1) + n  # channel c at cell n: 10c + n
    ind = torch.tensor([[4, 1, 5]])
    bins = torch.tensor([[2, 7, 3]])
    mask = torch.tensor([[1.0, 1.0, 0.0]])
    target = torch.tensor([[20.5, 71.0, 1000.0]])
    pred = select_bin(gather(width_map, ind), bins, mask)
    assert pred[0, :2, 0].tolist() == [24.0, 71.0]
    loss = masked_l1(pred, target.unsqueeze(-1), mask)
    assert loss.item() == pytest.approx(3.5 / (2 + 1e-4), rel=1e-6)

    kpts_map = torch.arange(72, dtype=torch.float32).reshape(1, 72, 1, 1) + 100.0 * n  # channel k at cell n
    ind = torch.tensor([[2, 0]])
    bins = torch.tensor([[3, -1]])  # the unused slot's bin is ignored
    mask = torch.tensor([[1.0, 0.0]])
    sel = select_bin(gather(kpts_map, ind), bins, mask, per_bin=8)
    assert sel[0, 0].tolist() == [200.0 + k for k in range(24, 32)]
    loss = masked_l1(sel, torch.zeros(1, 2, 8), mask)
    assert loss.item() == pytest.approx(8 * 227.5 / (8 + 1e-4), rel=1e-6)


def _batch(variant_name: str, seed: int = 0, size: tuple[int, int] = (16, 16), slots: int = 6):
    """Random network-like outputs and consistent targets for a batch of 2."""
    g = torch.Generator().manual_seed(seed)
    b, (h, w) = 2, size
    variant = get_variant(variant_name)
    outputs = {k: torch.randn(b, c, h, w, generator=g) for k, c in
               {"hm": 9, "reg": 2, "kpts": 72, "width": 9, "scale": 9}.items()}
    if not variant.scale_branch:
        outputs.pop("scale")
    ind = torch.randint(0, h * w, (b, slots), generator=g)
    bins = torch.randint(0, 9, (b, slots), generator=g)
    mask = torch.zeros(b, slots)
    mask[:, : slots // 2] = 1.0
    hm = torch.zeros(b, 9, h, w)
    for i in range(b):
        for s in range(slots // 2):
            hm[i, bins[i, s], ind[i, s] // w, ind[i, s] % w] = 1.0
    targets = {
        "hm": hm, "ind": ind, "mask": mask, "bin": bins,
        "reg": torch.rand(b, slots, 2, generator=g), "kpts": 8 * torch.randn(b, slots, 8, generator=g),
        "width": 0.02 + 0.08 * torch.rand(b, slots, generator=g),
        "scale": 0.6 + 0.4 * torch.rand(b, slots, generator=g),
    }
    return variant, outputs, targets


@pytest.mark.parametrize("name", ["kgn", "kgnv2"])
def test_kgn_loss_weighted_sum_and_scale_term(name):
    variant, outputs, targets = _batch(name)
    weights = LossWeights(hm=2.0, reg=0.5, kpts=1.5, width=10.0, scale=7.0)
    total, parts = kgn_loss(outputs, targets, variant, weights)
    names = ["hm", "reg", "kpts", "width"] + (["scale"] if variant.scale_branch else [])
    assert set(parts) == {*names, "total"}
    expected = sum(getattr(weights, k) * parts[k] for k in names)
    assert total.item() == pytest.approx(expected, rel=1e-5) == pytest.approx(parts["total"], rel=1e-5)
    targets["scale"] = targets["scale"] + 1.0
    changed = kgn_loss(outputs, targets, variant, weights)[0].item()
    assert (changed != pytest.approx(total.item())) == variant.scale_branch
    # masked slots do not matter, whatever their index and targets
    targets["ind"][:, -1] = 10**6
    targets["kpts"][:, -1] = 1e6
    assert kgn_loss(outputs, targets, variant, weights)[0].item() == pytest.approx(changed, rel=1e-6)


def test_kgn_loss_missing_keys():
    variant, outputs, targets = _batch("kgnv2")
    outputs.pop("scale")
    with pytest.raises(ValueError, match="outputs lack scale"):
        kgn_loss(outputs, targets, variant)
    targets.pop("bin")
    with pytest.raises(ValueError, match="targets lack bin"):
        kgn_loss(outputs, targets, variant)


def test_a_few_steps_reduce_the_loss():
    torch.manual_seed(0)
    variant = get_variant("kgnv2")
    net = build_network(variant, NetworkConfig(width_mult=0.5)).train()
    _, _, targets = _batch("kgnv2", seed=1, size=(16, 16))
    x = torch.randn(2, 4, 64, 64, generator=torch.Generator().manual_seed(2))
    opt = torch.optim.Adam(net.parameters(), lr=2e-3)
    losses = []
    for _ in range(12):
        total, parts = kgn_loss(net(x), targets, variant)
        opt.zero_grad()
        total.backward()
        opt.step()
        losses.append(parts)
    assert losses[-1]["total"] < 0.7 * losses[0]["total"]
    assert losses[-1]["hm"] < losses[0]["hm"] and losses[-1]["width"] < losses[0]["width"]
