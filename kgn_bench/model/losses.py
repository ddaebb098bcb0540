"""Training losses of KGN / KGNv2 (those of the reference implementation).

Heatmap: CornerNet focal loss with α = 2, β = 4 on ``p = clamp(sigmoid(logits), 1e-4, 1 − 1e-4)``::

    L_hm = −(1/N_pos) · Σ [ 1{Y=1} (1 − p)^α log p  +  1{Y<1} (1 − Y)^β p^α log(1 − p) ]

with ``N_pos`` the number of entries with ``Y == 1`` over the batch and all 9 bins (only the negative
sum when ``N_pos = 0``).

Regression: the prediction maps are gathered at the target cells ``ind = y·Wo + x`` and compared by a
masked L1 averaged per supervised scalar, ``Σ m·|ŷ − y| / (Σ m + 1e-4)`` with the slot mask ``m`` broadcast
over the scalars of a slot. Only the target bin's slice of a per-bin head is supervised: channel ``c`` of
``width`` and ``scale`` (metres), channels ``8c … 8c + 7`` of ``kpts`` (output px). ``reg`` (output px) has
no bins. Total ``L = w_hm·L_hm + w_reg·L_reg + w_kpts·L_kpts + w_width·L_width [+ w_scale·L_scale]``, the scale
term only for variants with the scale branch.

Targets (the dict of ``kgn_bench.model.targets``, batched: B images, S slots): ``hm`` (B, 9, Ho, Wo);
``ind``, ``bin`` (B, S) int64; ``mask``, ``width``, ``scale`` (B, S); ``reg`` (B, S, 2); ``kpts`` (B, S, 8).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch

from kgn_bench.model.targets import NUM_BINS
from kgn_bench.model.variants import Variant

__all__ = [
    "HM_CLAMP",
    "LossWeights",
    "focal_loss",
    "gather",
    "kgn_loss",
    "masked_l1",
    "select_bin",
]

HM_CLAMP = 1e-4
"""Heatmap probabilities are clamped to [HM_CLAMP, 1 − HM_CLAMP] before the logarithms."""
_L1_EPS = 1e-4
_KPT_SCALARS = 8
"""Keypoint scalars per bin: 4 keypoints (L, R, TL, TR) × (x, y)."""


@dataclass(frozen=True)
class LossWeights:
    """Weights of the loss terms (reference defaults: hm 1, reg 1, keypoints 1, width 10, scale 10)."""

    hm: float = 1.0
    reg: float = 1.0
    kpts: float = 1.0
    width: float = 10.0
    scale: float = 10.0


def focal_loss(logits: torch.Tensor, gt: torch.Tensor, alpha: float = 2.0, beta: float = 4.0) -> torch.Tensor:
    """CornerNet focal loss (module docstring) of heatmap ``logits`` against ``gt`` in [0, 1], same shape."""
    if logits.shape != gt.shape:
        raise ValueError(f"heatmap logits {tuple(logits.shape)} and target {tuple(gt.shape)} differ in shape")
    p = torch.sigmoid(logits).clamp(HM_CLAMP, 1.0 - HM_CLAMP)
    gt = gt.to(p.dtype)
    pos = gt.eq(1.0)
    pos_term = torch.log(p) * (1.0 - p).pow(alpha)
    neg_term = torch.log(1.0 - p) * p.pow(alpha) * (1.0 - gt).pow(beta)
    total = torch.where(pos, pos_term, neg_term).sum()
    n_pos = pos.sum().clamp(min=1).to(p.dtype)  # N_pos = 0: the positive sum is 0, keep the negative sum
    return -total / n_pos


def gather(feature: torch.Tensor, ind: torch.Tensor) -> torch.Tensor:
    """Values of ``feature`` (B, C, H, W) at flat cells ``ind`` (B, M) = y·W + x: (B, M, C)."""
    if feature.ndim != 4 or ind.ndim != 2 or ind.shape[0] != feature.shape[0]:
        raise ValueError(f"gather needs feature (B, C, H, W) and ind (B, M), got {tuple(feature.shape)} "
                         f"and {tuple(ind.shape)}")
    b, c = feature.shape[:2]
    flat = feature.reshape(b, c, -1)
    idx = ind.long().unsqueeze(1).expand(b, c, ind.shape[1])
    return flat.gather(2, idx).transpose(1, 2)


def select_bin(values: torch.Tensor, bins: torch.Tensor, mask: torch.Tensor, per_bin: int = 1) -> torch.Tensor:
    """The bin's slice of gathered per-bin values (B, M, NUM_BINS·per_bin) → (B, M, per_bin).

    Channels ``per_bin·c … per_bin·c + per_bin − 1`` for bin ``c = bins[b, m]``. Unused slots (mask 0) read
    bin 0, whatever their stored bin, so only used slots need a valid bin in [0, 8].
    """
    b, m, k = values.shape
    if k != NUM_BINS * per_bin:
        raise ValueError(f"per-bin head must have {NUM_BINS * per_bin} channels, got {k}")
    safe = torch.where(mask > 0, bins.long(), torch.zeros_like(bins, dtype=torch.long))
    grouped = values.reshape(b, m, NUM_BINS, per_bin)
    idx = safe.reshape(b, m, 1, 1).expand(b, m, 1, per_bin)
    return grouped.gather(2, idx).squeeze(2)


def masked_l1(pred: torch.Tensor, target: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """``Σ m·|pred − target| / (Σ m + 1e-4)`` with the slot mask (B, M) broadcast over the trailing scalars of
    ``pred`` / ``target`` (B, M, K), i.e. the mean absolute error per supervised scalar."""
    if pred.shape != target.shape or pred.shape[:2] != mask.shape:
        raise ValueError(f"masked L1 shapes differ: pred {tuple(pred.shape)}, target {tuple(target.shape)}, "
                         f"mask {tuple(mask.shape)}")
    m = mask.to(pred.dtype).unsqueeze(-1).expand_as(pred)
    return (m * (pred - target.to(pred.dtype)).abs()).sum() / (m.sum() + _L1_EPS)


_TARGET_KEYS = ("hm", "ind", "mask", "bin", "reg", "kpts", "width", "scale")


def kgn_loss(
    outputs: dict[str, torch.Tensor],
    targets: dict[str, torch.Tensor],
    variant: Variant,
    weights: LossWeights = LossWeights(),
) -> tuple[torch.Tensor, dict[str, float]]:
    """Total training loss and its components (floats, unweighted, plus ``"total"``).

    ``outputs``: the network's dict (B, C, Ho, Wo) with ``hm`` as logits; ``targets``: batched tensors (module
    docstring). The ``scale`` term is used only when ``variant.scale_branch``. ``ValueError`` on missing keys.
    """
    missing = [k for k in _TARGET_KEYS if k not in targets]
    if missing:
        raise ValueError(f"targets lack {', '.join(missing)}")
    heads = ["hm", "reg", "kpts", "width"] + (["scale"] if variant.scale_branch else [])
    missing = [k for k in heads if k not in outputs]
    if missing:
        raise ValueError(f"outputs lack {', '.join(missing)} (variant {variant.name})")
    mask, bins = targets["mask"], targets["bin"]
    ind = torch.where(mask > 0, targets["ind"].long(), torch.zeros_like(targets["ind"], dtype=torch.long))

    terms = {"hm": focal_loss(outputs["hm"], targets["hm"])}
    terms["reg"] = masked_l1(gather(outputs["reg"], ind), targets["reg"], mask)
    kpts = select_bin(gather(outputs["kpts"], ind), bins, mask, per_bin=_KPT_SCALARS)
    terms["kpts"] = masked_l1(kpts, targets["kpts"], mask)
    for name in ("width", "scale") if variant.scale_branch else ("width",):
        pred = select_bin(gather(outputs[name], ind), bins, mask)
        terms[name] = masked_l1(pred, targets[name].unsqueeze(-1), mask)

    w = asdict(weights)
    total = sum(w[name] * value for name, value in terms.items())
    parts = {name: float(value.detach()) for name, value in terms.items()}
    parts["total"] = float(total.detach())
    return total, parts
