"""Whether VGN's rotation labels are learnable at all: how much the labelled rotations of positive grasps that lie
close together in the grid differ (closing lines: ``arccos |c · c'|``, 0-90°; approaches: ``arccos(a · a')``).
Labels that were noise would differ like random angles (closing lines 45° in median).

    python results/calibration/vgn_label_consistency.py DATASET [SCENES] [RADIUS_VOXELS]
"""

import sys
from pathlib import Path

import numpy as np

from kgn_bench.data.vgn_format import list_scene_ids, read_scene
from kgn_bench.geometry import matrix_from_quat_wxyz


def neighbour_differences(folder: Path, scenes: int, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """(closing-line, approach) differences (°) over every pair of positives of the same scene, among the first
    ``scenes`` scenes, whose voxel positions lie at most ``radius`` voxels apart."""
    closing, approach = [], []
    for name in list_scene_ids(folder)[:scenes]:
        scene = read_scene(folder, name)
        positive = scene.labels == 1
        if positive.sum() < 2:
            continue
        voxels = scene.voxels[positive]
        rotations = matrix_from_quat_wxyz(scene.quats[positive].astype(float))
        distance = np.linalg.norm(voxels[:, None] - voxels[None], axis=2)
        i, j = np.nonzero(np.triu(distance <= radius, 1))
        c = np.abs(np.sum(rotations[i, :, 2] * rotations[j, :, 2], axis=1))
        a = np.sum(rotations[i, :, 0] * rotations[j, :, 0], axis=1)
        closing += list(np.degrees(np.arccos(np.clip(c, 0.0, 1.0))))
        approach += list(np.degrees(np.arccos(np.clip(a, -1.0, 1.0))))
    return np.array(closing), np.array(approach)


if __name__ == "__main__":
    folder = Path(sys.argv[1])
    scenes = int(sys.argv[2]) if len(sys.argv) > 2 else 200
    radius = float(sys.argv[3]) if len(sys.argv) > 3 else 1.5
    closing, approach = neighbour_differences(folder, scenes, radius)
    print(f"{len(closing)} pairs of positives within {radius} voxels in the first {scenes} scenes: closing lines "
          f"differ by {np.median(closing):.1f}° in median ({100 * np.mean(closing < 20):.0f} % under 20°; random "
          f"angles: 45°, 22 %), approaches by {np.median(approach):.1f}°")
