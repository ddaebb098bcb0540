"""results/calibration/vgn_label_slices.png: six scenes of VGN's v2 data, one horizontal slice of the network
input each (the TSDF band, (t + 1)/2: 1 in front of a surface, 0 behind it or unobserved), the positive
grasps within one voxel of the slice as arrows (the x, y part of their approach) and the negatives as dots.

    python results/calibration/vgn_label_slices.py
"""

import matplotlib
import numpy as np

matplotlib.use("Agg")
from pathlib import Path

import matplotlib.pyplot as plt

from kgn_bench.data.vgn_format import read_scene
from kgn_bench.geometry import matrix_from_quat_wxyz

fig, axes = plt.subplots(2, 3, figsize=(15, 10))
for ax, sid in zip(axes.flat, range(100, 106)):
    sc = read_scene(Path('data/vgn'), sid)
    pos = sc.labels == 1
    v = sc.voxels[pos]
    R = matrix_from_quat_wxyz(sc.quats[pos].astype(float))
    k0 = int(np.median(np.rint(v[:, 2]))) if pos.any() else 10
    ax.imshow(sc.tsdf[:, :, k0].T, origin="lower", cmap="viridis", vmin=0, vmax=1)
    sel = np.abs(np.rint(v[:, 2]) - k0) <= 1
    a = R[sel, :, 0]
    ax.quiver(v[sel, 0], v[sel, 1], a[:, 0], a[:, 1], color="r", angles="xy", scale_units="xy", scale=0.25)
    neg = ~pos & (np.abs(np.rint(sc.voxels[:, 2]) - k0) <= 1)
    ax.plot(sc.voxels[neg, 0], sc.voxels[neg, 1], "w.", ms=2)
    ax.set_title(f"scene {sid}, slice k = {k0}: input; positives' approach (x, y) red")
fig.tight_layout()
fig.savefig("results/calibration/vgn_label_slices.png", dpi=60)
