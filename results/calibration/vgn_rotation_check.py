"""How well a VGN checkpoint predicts the approach of the positive grasps of scenes it was not trained on, beside
the error of always answering "straight down" (world −z): the check that showed the rotation head learning
only the mean.

    python results/calibration/vgn_rotation_check.py CHECKPOINT DATASET FIRST_ID LAST_ID
"""

import sys
from pathlib import Path

import numpy as np
import torch

from kgn_bench.data.vgn_format import list_scene_ids, read_scene
from kgn_bench.geometry import matrix_from_quat_wxyz
from kgn_bench.model.vgn_checkpoint import load_vgn_model


def approach_errors(net: torch.nn.Module, folder: Path, first: int, last: int) -> tuple[np.ndarray, np.ndarray]:
    """(network, straight down): the angles (°) between the labelled approach of every positive grasp of the
    scenes ``first`` ≤ id < ``last`` and the network's approach at its voxel, and world −z."""
    predicted, down = [], []
    for name in list_scene_ids(folder):
        if not first <= int(name) < last:
            continue
        scene = read_scene(folder, name)
        with torch.inference_mode():
            out = net(torch.from_numpy(scene.tsdf)[None, None])
        positive = scene.labels == 1
        i, j, k = np.rint(scene.voxels[positive]).astype(int).T
        approach = matrix_from_quat_wxyz(scene.quats[positive].astype(float))[:, :, 0]
        guess = matrix_from_quat_wxyz(out.rotation[0].numpy()[:, i, j, k].T.astype(float))[:, :, 0]
        predicted += list(np.degrees(np.arccos(np.clip(np.sum(approach * guess, axis=1), -1.0, 1.0))))
        down += list(np.degrees(np.arccos(np.clip(-approach[:, 2], -1.0, 1.0))))
    return np.array(predicted), np.array(down)


if __name__ == "__main__":
    checkpoint, folder, first, last = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
    for label, errors in zip(("network", "straight down"),
                             approach_errors(load_vgn_model(checkpoint).net, folder, first, last)):
        print(f"{label:>13}: approach error median {np.median(errors):.1f}°, 75th percentile "
              f"{np.percentile(errors, 75):.1f}°, under 20° {100 * np.mean(errors < 20):.0f} % "
              f"({len(errors)} positives)")
