"""What makes KGNv2's cylinder predictions fail at 1 cm / 20° (issue 43, "for the rotation term").

Every prediction of a detector on the first VIEWS test views whose nearest ground-truth grasp (as the vision
metrics pick it) belongs to a cylinder is taken against that cylinder's evaluation grasps (world frame,
``T_world_grasp``; 30 angles, 10 heights; collision-labelled in the scene) and sorted into one cause:

* ``matched``: within 1 cm and 20° of a collision-free grasp (a success);
* ``colliding``: within 1 cm and 20° only of grasps that collide in the scene (a right grasp the labels
  reject);
* ``rotation``: some grasp lies within 1 cm of its centre, none of those within 20°. Split by the family of
  the rotation-nearest of them (``rim``: approach along the tube's axis, closing across its wall; ``side``:
  approach across the tube, centre on its axis) and by how the rotation is off: ``tilt`` = the angle
  between the approach axes (+x), ``spin`` = the angle about the approach between the closing axes (+y,
  folded to [0°, 90°] by the 180° flip) once the approaches are aligned. It is also counted whether the
  predicted rotation is that of a grasp of the same family elsewhere on the tube (within 20°, farther than 1 cm):
  a right orientation at the wrong place;
* ``position``: no grasp within 1 cm.

The cylinder's grasp set is ordered as ``Cylinder.grasps`` builds it: the top rim's A angles, the bottom
rim's A, then the side family's T heights × A angles. Standing (axis within 25° of vertical) and lying
tubes are counted apart.

    python results/fidelity/cylinder_rotation.py [WEIGHTS] [VIEWS] > results/fidelity/cylinder_rotation.md
"""

from __future__ import annotations

import sys
from collections import Counter, defaultdict

import numpy as np

from kgn_bench.detectors.kgn import KGNDetector
from kgn_bench.eval.views import detector_call, iter_views
from kgn_bench.eval.vision import nearest_grasps, pose_errors, shape_column
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes import EVAL_DENSITY

T_MAX, R_MAX = 0.01, np.radians(20.0)
A, T = EVAL_DENSITY.angles, EVAL_DENSITY.translations


def family(index: int) -> str:
    return "rim" if index < 2 * A else "side"


def tilt_and_spin(Rp: np.ndarray, Rg: np.ndarray) -> tuple[float, float]:
    """Degrees: the angle between the approach axes (+x) and, after rotating the GT frame so its approach
    meets the prediction's, the angle between the closing axes (+y), folded by the 180° flip to [0, 90]."""
    xp, xg = Rp[:, 0], Rg[:, 0]
    tilt = np.degrees(np.arccos(np.clip(xp @ xg, -1.0, 1.0)))
    axis = np.cross(xg, xp)
    s = np.linalg.norm(axis)
    if s > 1e-9:
        k = axis / s
        c = xp @ xg
        K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
        align = np.eye(3) + s * K + (1 - c) * K @ K
        yg = align @ Rg[:, 1]
    else:
        yg = Rg[:, 1]
    spin = np.degrees(np.arccos(np.clip(abs(Rp[:, 1] @ yg), 0.0, 1.0)))
    return float(tilt), float(spin)


def main(weights: str = "kgnv2", views: int = 300) -> None:
    detect = detector_call(KGNDetector(None, weights) if weights.endswith(".pt") else KGNDetector(weights))
    total, items = iter_views("data/ps_multi", "test", views)
    causes: dict[str, Counter] = defaultdict(Counter)
    tilts: dict[str, list[float]] = defaultdict(list)
    spins: dict[str, list[float]] = defaultdict(list)
    elsewhere: Counter = Counter()
    ray_angles: dict[str, list[tuple[float, float]]] = defaultdict(list)
    down: dict[str, list[float]] = defaultdict(list)
    for item in items:
        cands = detect(item)
        pred = cands.world_poses(item.observation.camera_pose)
        if len(pred) == 0:
            continue
        all_gt = GraspSet.concatenate(list(item.gt))
        owner = np.repeat(np.arange(len(item.gt)), [len(g) for g in item.gt])
        _, _, nearest, _ = nearest_grasps(pred, all_gt)
        for n, obj in enumerate(owner[nearest]):
            if shape_column(item.types[obj]) != "cylinder":
                continue
            gt = item.gt[obj]
            assert len(gt) == 2 * A + T * A, len(gt)
            axis_z = item.objects[obj].pose[:3, 2]
            stance = "standing" if abs(axis_z[2]) > np.cos(np.radians(25.0)) else "lying"
            d_t, d_r = pose_errors(pred[n:n + 1], gt.poses)
            d_t, d_r = d_t[0], d_r[0]
            close = d_t < T_MAX
            hit = close & (d_r < R_MAX)
            if (hit & ~gt.collides).any():
                cause = "matched"
            elif hit.any():
                cause = "colliding"
            elif close.any():
                j = int(np.flatnonzero(close)[np.argmin(d_r[close])])
                fam = family(j)
                cause = f"rotation, {fam}"
                tilt, spin = tilt_and_spin(pred[n, :3, :3], gt.poses[j, :3, :3])
                tilts[f"{stance} {fam}"].append(tilt)
                down[f"{stance} {fam}"].append(float(np.degrees(np.arccos(np.clip(-pred[n, 2, 0], -1, 1)))))
                cam = item.observation.camera_pose[:3, 3]
                ray = pred[n, :3, 3] - cam
                ray /= np.linalg.norm(ray)
                ray_angles[f"{stance} {fam}"].append(
                    (float(np.degrees(np.arccos(np.clip(pred[n, :3, 0] @ ray, -1, 1)))),
                     float(np.degrees(np.arccos(np.clip(gt.poses[j, :3, 0] @ ray, -1, 1))))))
                spins[f"{stance} {fam}"].append(spin)
                same = np.array([family(i) == fam for i in range(len(gt))])
                if ((d_r < R_MAX) & ~close & same).any():
                    elsewhere[f"{stance} {fam}"] += 1
            else:
                cause = "position"
            causes[stance][cause] += 1
    order = ["matched", "colliding", "rotation, rim", "rotation, side", "position"]
    print(f"# Cylinder predictions of `{weights}` by cause (first {total} views of the ps_multi test split)\n")
    print("| tube | predictions | " + " | ".join(order) + " |")
    print("|---|---:|" + "---:|" * len(order))
    for stance in ("standing", "lying"):
        c = causes[stance]
        n = sum(c.values())
        print(f"| {stance} | {n} | " + " | ".join(f"{100 * c[k] / max(n, 1):.1f} % ({c[k]})" for k in order) + " |")
    print("\nRotation failures: the rotation-nearest grasp within 1 cm, median (90th percentile) of the tilt of the"
          " approach and of the spin about it, degrees; and how many carry the rotation of a grasp of the same family"
          " elsewhere on the tube.\n")
    print("| tube, family | failures | tilt ° | spin ° | spin ≥ 20° with tilt < 20° | rotation of a grasp elsewhere "
          "| approach to the camera ray °: predicted / nearest GT | predicted approach from straight down ° |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for key in sorted(tilts):
        t, s = np.array(tilts[key]), np.array(spins[key])
        only_spin = np.mean((s >= 20) & (t < 20))
        print(f"| {key} | {len(t)} | {np.median(t):.1f} ({np.percentile(t, 90):.1f}) | {np.median(s):.1f} "
              f"({np.percentile(s, 90):.1f}) | {100 * only_spin:.0f} % | {100 * elsewhere[key] / len(t):.0f} % | "
              f"{np.median([a for a, _ in ray_angles[key]]):.1f} / {np.median([b for _, b in ray_angles[key]]):.1f} | "
              f"{np.median(down[key]):.1f} ({np.percentile(down[key], 10):.1f}-{np.percentile(down[key], 90):.1f}) |")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "kgnv2", int(sys.argv[2]) if len(sys.argv) > 2 else 300)
