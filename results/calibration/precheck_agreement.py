"""How often the VGN generator's kinematic pre-check (``sim.floating_hand.precheck_grasp``) rejects a grasp that
execution would hold: every (position, yaw) of the given scenes is both pre-checked and executed in physics.

    MUJOCO_GL=egl python results/calibration/precheck_agreement.py 0 1 2 3 5 6

Prints the (pre-check verdict, execution outcome) counts, the seconds per grasp of each, and the disagreements.
Scenes are built as ``kgn-bench data vgn`` builds them (default settings, ``VGN_OBJECTS``), origins unsnapped.
"""

import sys
import time
from collections import Counter

import mujoco
import numpy as np

from kgn_bench.data import vgn_generate as G
from kgn_bench.gripper import PANDA_HAND
from kgn_bench.sim.floating_hand import execute_grasp, precheck_grasp
from kgn_bench.sim.render import SceneRenderer

config = G.VGNDataConfig()
counts: Counter = Counter()
seconds: Counter = Counter()
for index in map(int, sys.argv[1:]):
    rng = np.random.default_rng([config.seed, index])
    scene, hand, _ = G._arranged_scene(config, index, rng)
    with SceneRenderer(scene) as renderer:
        views = [(renderer.render(T).depth, T) for T in G.grasp_views(rng)]
    points, normals = G.sample_surface_points(scene, 120, rng, views=views)
    d = PANDA_HAND.finger_length
    frames = G.grasp_frames(points, normals, rng.uniform(-0.1 * d, 1.1 * d, len(points)), 6).reshape(-1, 4, 4)
    m, data = scene.model, scene.data
    saved = np.empty(mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION))
    mujoco.mj_getState(m, data, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
    for T in frames:
        mujoco.mj_setState(m, data, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
        scene.forward()
        t = time.perf_counter()
        verdict = precheck_grasp(hand, T) or "pass"
        seconds["precheck"] += time.perf_counter() - t
        mujoco.mj_setState(m, data, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
        scene.forward()
        t = time.perf_counter()
        outcome = execute_grasp(hand, T, allow_contact=False).reason or "held"
        seconds["execute"] += time.perf_counter() - t
        counts[verdict, outcome] += 1
n = sum(counts.values())
for key, value in sorted(counts.items()):
    print(f"{key[0]:>10} {key[1]:>13} {value:6d}")
rejected = sum(v for (a, _), v in counts.items() if a != "pass")
wrong = sum(v for (a, b), v in counts.items() if a != "pass" and b == "held")
print(f"grasps {n}, pre-check rejects {rejected} ({100 * rejected / n:.1f} %), of which execution holds {wrong} "
      f"({100 * wrong / max(rejected, 1):.2f} %)")
print(f"ms per grasp: pre-check {1e3 * seconds['precheck'] / n:.2f}, execution {1e3 * seconds['execute'] / n:.2f}")
