"""How well a VGN checkpoint predicts the rotation of the positive grasps of scenes it was not trained on: the
approach (beside the error of always answering "straight down", world −z: the check that showed the rotation
head learning only the mean) and the closing axis (the angle between the closing lines, 0-90°; a yaw drawn at
random about the labelled approach gives 45° in median). On data that stores every yaw's outcome (label rule v4)
it also gives the share of positives whose predicted rotation lies within 15° of one that held
(``vgn_train.HIT_ANGLE``), beside the share a random yaw about the labelled approach would hit.

    python results/calibration/vgn_rotation_check.py CHECKPOINT DATASET FIRST_ID LAST_ID
    python results/calibration/vgn_rotation_check.py CHECKPOINT DATASET held-out   # the run's held-out scenes
"""

import sys
from pathlib import Path

import numpy as np
import torch

from kgn_bench.data.vgn_format import list_scene_ids, read_manifest, read_scene
from kgn_bench.geometry import matrix_from_quat_wxyz
from kgn_bench.model.vgn_checkpoint import load_vgn_checkpoint, load_vgn_model
from kgn_bench.training.vgn_train import HIT_ANGLE, holding_hits, split_scenes


def approach_errors(net: torch.nn.Module, folder: Path, ids: set[str]
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(network, straight down, closing, hit, chance): the angles (°) between the labelled approach of every
    positive grasp of the scenes ``ids`` and the network's approach at its voxel, and world −z; between the
    labelled and the predicted closing lines (``arccos |c · ĉ|``); and, where the data stores every yaw's
    outcome, whether the prediction lies within ``HIT_ANGLE`` of a holding rotation and the share of a uniform
    yaw about the labelled approach that would (empty arrays otherwise)."""
    predicted, down, closing, hit, chance = [], [], [], [], []
    for name in list_scene_ids(folder):
        if name not in ids:
            continue
        scene = read_scene(folder, name)
        with torch.inference_mode():
            out = net(torch.from_numpy(scene.tsdf)[None, None])
        positive = scene.labels == 1
        i, j, k = np.rint(scene.voxels[positive]).astype(int).T
        label = matrix_from_quat_wxyz(scene.quats[positive].astype(float))
        pred = out.rotation[0].numpy()[:, i, j, k].T.astype(np.float64)
        net_rotation = matrix_from_quat_wxyz(pred)
        approach, guess = label[:, :, 0], net_rotation[:, :, 0]
        dots = np.abs(np.sum(label[:, :, 2] * net_rotation[:, :, 2], axis=1))
        closing += list(np.degrees(np.arccos(np.clip(dots, 0.0, 1.0))))
        predicted += list(np.degrees(np.arccos(np.clip(np.sum(approach * guess, axis=1), -1.0, 1.0))))
        down += list(np.degrees(np.arccos(np.clip(-approach[:, 2], -1.0, 1.0))))
        if scene.holds is not None:
            holds = torch.from_numpy(scene.holds[positive])
            hit += list(holding_hits(torch.from_numpy(pred), torch.from_numpy(scene.quats[positive].astype(np.float64)),
                                     holds).numpy())
            # a uniform yaw hits a holding turn when it lies within HIT_ANGLE of one: 2·HIT_ANGLE of every π/Y step
            chance += list(np.minimum(1.0, holds.sum(1).numpy() * 2 * HIT_ANGLE / np.pi))
    return np.array(predicted), np.array(down), np.array(closing), np.array(hit), np.array(chance)


if __name__ == "__main__":
    checkpoint, folder = Path(sys.argv[1]), Path(sys.argv[2])
    if sys.argv[3] == "held-out":  # the scenes the checkpoint's run held out (vgn_train.split_scenes)
        train = load_vgn_checkpoint(checkpoint)["train"]
        held = split_scenes(read_manifest(folder), train["held_out"], train["seed"], train.get("max_scenes", 0))[1]
        ids = {s.id for s in held}
    else:
        ids = {name for name in list_scene_ids(folder) if int(sys.argv[3]) <= int(name) < int(sys.argv[4])}
    predicted, down, closing, hit, chance = approach_errors(load_vgn_model(checkpoint).net, folder, ids)
    if len(hit):
        print(f"      network: within 15° of a holding rotation {100 * hit.mean():.1f} % "
              f"(a random yaw about the labelled approach: {100 * chance.mean():.1f} %)")
    print(f"      network: closing-line error median {np.median(closing):.1f}°, under 20° "
          f"{100 * np.mean(closing < 20):.0f} % (a random yaw: 45°, 22 %)")
    for label, errors in zip(("network", "straight down"), (predicted, down)):
        print(f"{label:>13}: approach error median {np.median(errors):.1f}°, 75th percentile "
              f"{np.percentile(errors, 75):.1f}°, under 20° {100 * np.mean(errors < 20):.0f} % "
              f"({len(errors)} positives)")
