"""results/calibration/floating_grasp.png: one floating-hand grasp of GIGA's packed round (trial 3, the oracle's
best candidate) at four moments of GIGA's execution: the pre-grasp 5 cm back, the jaws closed, the 10 cm lift,
and the side view the detector saw. Frames are rendered from a camera closer than GIGA's (0.45 m, 25° up).

    MUJOCO_GL=egl python results/calibration/floating_grasp.py
"""

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from kgn_bench import giga
from kgn_bench.bench.trial import _build_scene, _observe, camera_pose
from kgn_bench.camera import orbit_pose
from kgn_bench.config import load_task
from kgn_bench.detectors.oracle import OracleDetector
from kgn_bench.sim.control import IK
from kgn_bench.sim.depth_noise import noise_model
from kgn_bench.sim.floating_hand import CONTROL_DT, execute_grasp
from kgn_bench.sim.render import SceneRenderer

task = load_task("tasks/giga_packed.toml")
scene, hand, members = _build_scene(task, 3, IK())
cam = camera_pose(task, 3)
close = orbit_pose(0.45, np.deg2rad(25.0), np.deg2rad(215.0))
close[:3, 3] += np.array([0.0, 0.0, 0.05])
frames: list[tuple[str, np.ndarray]] = []
with SceneRenderer(scene) as renderer:
    obs = _observe(renderer, scene, cam, noise_model("dex", 1.0), np.random.default_rng(0), task.camera.far)
    oracle = OracleDetector()
    oracle.configure(task.execution)
    oracle.attach(scene)
    cands = oracle.detect(obs)
    T = cands.world_poses(cam)[int(np.argmax(cands.confidences))]
    images: list[np.ndarray] = []
    hand.on_tick = lambda: images.append(renderer.render(close).rgb)
    outcome = execute_grasp(hand, T)
lift_ticks = round(giga.LIFT_DISTANCE / giga.APPROACH_SPEED / CONTROL_DT)
panels = [("what the detector saw (GIGA's side view)", obs.rgb), ("the pre-grasp, 5 cm back", images[0]),
          ("jaws closed", images[-lift_ticks - 1]),
          (f"lifted 10 cm: {'held' if outcome.reason is None else outcome.reason}", images[-1])]
fig, axes = plt.subplots(1, 4, figsize=(20, 4.4))
for ax, (title, image) in zip(axes, panels):
    ax.imshow(image)
    ax.set_title(title)
    ax.axis("off")
fig.suptitle(f"giga_packed trial 3: the floating Panda hand executes the oracle's best grasp ({len(members)} objects)")
fig.tight_layout()
fig.savefig("results/calibration/floating_grasp.png", dpi=70)
print(outcome)
