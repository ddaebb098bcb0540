"""Sub-pixel refinement of the keypoints by a vote of the peak's neighbours (issue 43, item 2).

The network predicts, at every output cell (x, y) and orientation bin c, the four keypoints as offsets
o_j(c, y, x) from that cell, and the decoder reads them at the heatmap peak only: p_j = (x, y) + o_j(c, y, x).
The neighbouring cells of a peak predict the same grasp's keypoints too. The vote replaces each cell's
offsets by the heatmap-weighted mean of the keypoints its (2r+1)² neighbourhood predicts, expressed from
that cell:

    o'_j(c, y, x) = Σ_{|dx|,|dy| ≤ r} h(c, y+dy, x+dx) · (o_j(c, y+dy, x+dx) + (dx, dy)) / Σ h(c, y+dy, x+dx)

(h: the bin's heatmap probabilities, cells outside the map weigh 0), so that the unchanged decoder
(``kgn_bench.model.decode.decode``) reads the voted keypoints at the peak. If the per-cell errors were
independent jitter, the vote would shrink them by up to √9; if they are shared by the neighbours (a bias of
the whole blob), it changes nothing.

Usage (the first VIEWS views of the multi-object test split, both shipped multi-split models, base and vote):

    python results/fidelity/keypoint_vote.py data/ps_multi 250 > results/fidelity/keypoint_vote.md
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from kgn_bench.detectors.kgn import KGNDetector
from kgn_bench.eval.errors import decompose_dataset
from kgn_bench.eval.vision import evaluate_dataset
from kgn_bench.model.decode import decode
from kgn_bench.types import Candidates, Observation


def vote_offsets(hm: np.ndarray, kpts: np.ndarray, radius: int = 1) -> np.ndarray:
    """The voted offsets o' (72, Ho, Wo) of the module docstring from the heatmap ``hm`` (9, Ho, Wo) and the
    offsets ``kpts`` (72, Ho, Wo; channel 8c + 2j + {0: x, 1: y}), output pixels."""
    bins, ho, wo = hm.shape
    off = kpts.reshape(bins, 8, ho, wo).astype(np.float64)
    pad = radius
    hp = np.pad(hm.astype(np.float64), ((0, 0), (pad, pad), (pad, pad)))
    op = np.pad(off, ((0, 0), (0, 0), (pad, pad), (pad, pad)))
    num = np.zeros_like(off)
    den = np.zeros((bins, 1, ho, wo))
    shift = np.zeros((1, 8, 1, 1))
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            w = hp[:, None, pad + dy:pad + dy + ho, pad + dx:pad + dx + wo]
            shift[0, 0::2, 0, 0], shift[0, 1::2, 0, 0] = dx, dy
            num += w * (op[:, :, pad + dy:pad + dy + ho, pad + dx:pad + dx + wo] + shift)
            den += w
    voted = np.where(den > 0, num / np.maximum(den, 1e-12), off)
    return voted.reshape(8 * bins, ho, wo).astype(np.float32)


class VotingDetector:
    """A loaded KGN-family detector decoded with the voted offsets (``radius`` 0: the plain decoder)."""

    def __init__(self, inner: KGNDetector, radius: int) -> None:
        self.inner = inner
        self.variant = self.inner.variant
        self.radius = radius

    def __call__(self, observation: Observation) -> Candidates:
        maps, M = self.inner.maps(observation)
        if self.radius > 0:
            maps["kpts"] = vote_offsets(maps["hm"], maps["kpts"], self.radius)
        depth = observation.depth if self.variant.needs_depth else None
        return decode(maps, observation.intrinsics.K, M, self.variant, self.inner.decode_config, depth=depth)


def main(data: Path, views: int) -> None:
    print("# Keypoints voted by the peak's neighbours (issue 43, item 2)\n")
    print(f"`python results/fidelity/keypoint_vote.py {data} {views}`: the first {views} views of the "
          "multi-object test split, the shipped multi-split models; the vote over the 3×3 neighbourhood "
          "(`radius` 1) against the plain decoder (`radius` 0). Keypoint errors: median px in the 640×480 image, "
          "each against the nearest ground-truth grasp's keypoints (`kgn-bench eval errors`).\n")
    print("| model | decoder | L | R | TL | TR | ray error cm | rotation ° | GSR / GCR / OSR 1 cm / 20° "
          "| 2 cm / 30° | 3 cm / 45° |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for weights in ("kgn", "kgnv2"):
        inner = KGNDetector(weights)  # one load of the weights for both decoders
        for radius in (0, 1):
            detector = VotingDetector(inner, radius)
            table = decompose_dataset(detector, data, views=views, progress=False)
            kp = np.nanmedian(table.keypoint_arrays(), axis=0)
            rows, _, _ = table.arrays()
            ray, rot = np.median(np.abs(rows[:, 2])), np.median(rows[:, 3])
            metrics = evaluate_dataset(detector, data, views=views, progress=False).summarise()
            cells = [" / ".join(f"{100 * t[k]:.1f}" for k in ("gsr", "gcr", "osr")) for t in metrics["thresholds"]]
            print(f"| {weights} | {'vote 3×3' if radius else 'peak'} | " + " | ".join(f"{v:.2f}" for v in kp)
                  + f" | {ray:.2f} | {rot:.2f} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]), int(sys.argv[2]))
