"""results/calibration/giga_views.png: trial 3 of GIGA's pile and packed tasks as the side view sees them, the
RGB image beside the depth with GIGA's dex noise."""

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from kgn_bench.bench.trial import _build_scene, _observe, camera_pose
from kgn_bench.config import load_task
from kgn_bench.sim.control import IK
from kgn_bench.sim.depth_noise import noise_model
from kgn_bench.sim.render import SceneRenderer

fig, axes = plt.subplots(2, 2, figsize=(12, 9))
for row, kind in enumerate(("pile", "packed")):
    task = load_task(f"tasks/giga_{kind}.toml")
    scene, _, members = _build_scene(task, 3, IK())
    with SceneRenderer(scene) as renderer:
        obs = _observe(renderer, scene, camera_pose(task, 3), noise_model("dex", 1.0), np.random.default_rng(0),
                       task.camera.far)
    axes[row, 0].imshow(obs.rgb)
    axes[row, 0].set_title(f"giga_{kind}, trial 3: {len(members)} objects, side view (540 px)")
    shown = axes[row, 1].imshow(np.where(obs.depth > 0, obs.depth, np.nan), cmap="viridis", vmin=0.4, vmax=0.9)
    axes[row, 1].set_title("depth with dex noise (m)")
    plt.colorbar(shown, ax=axes[row, 1])
    for ax in axes[row]:
        ax.axis("off")
fig.tight_layout()
fig.savefig("results/calibration/giga_views.png", dpi=80)
