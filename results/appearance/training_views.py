"""Rendered training views with randomised appearance (issue 44, item 3): primitives and pybullet train-split
meshes, procedural textures per object and for the table, the benchmark camera's depth noise.

    kgn-bench data generate --mode multi --scenes 3 --views 2 --seed 1 --appearance random --depth-noise 1 \
        --objects cuboid cylinder ring pb_001 pb_002 pb_003 pb_004 pb_005 pb_006 pb_007 --out runs/textured_demo
    python results/appearance/training_views.py runs/textured_demo

writes training_views.png beside this script: the RGB of each view over its noisy depth.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from kgn_bench.data.format import read_view, scene_dir


def main(root: Path) -> None:
    scenes = sorted(int(p.name.split("_")[-1]) for p in (root / "scenes").iterdir() if p.is_dir())[:3]
    fig, axes = plt.subplots(2, len(scenes) * 2, figsize=(4.2 * len(scenes) * 2, 6.6))
    for c, s in enumerate(scenes):
        for v in range(2):
            rgbd = read_view(scene_dir(root, s), v)
            ax = axes[0, 2 * c + v]
            ax.imshow(rgbd.rgb)
            ax.set_title(f"scene {s}, view {v}", fontsize=9)
            d = axes[1, 2 * c + v].imshow(rgbd.depth, cmap="turbo", vmin=0.45, vmax=1.3)
            d.cmap.set_under("black")
            axes[1, 2 * c + v].set_title("depth, D435 noise (black: no return)", fontsize=9)
    for ax in axes.ravel():
        ax.set_axis_off()
    fig.tight_layout()
    out = Path(__file__).parent / "training_views.png"
    fig.savefig(out, dpi=70)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(Path(sys.argv[1]))
