"""The error decomposition: exact terms for constructed predictions, real detections on a real dataset."""

import numpy as np
import pytest

from kgn_bench.camera import REALSENSE
from kgn_bench.eval.errors import TERMS, ErrorTable, decompose_image
from kgn_bench.geometry import make_pose, rot_x
from kgn_bench.grasp import GraspSet
from kgn_bench.types import Observation


def _obs():
    cam = make_pose(rot_x(np.pi), [0.0, 0.0, 0.8])  # looking straight down from 0.8 m
    return Observation(np.zeros((480, 640, 3), np.uint8), np.full((480, 640), 0.8, np.float32), REALSENSE, cam)


def test_each_term_is_measured_alone():
    obs = _obs()
    g = make_pose(np.eye(3), [0.0, 0.0, 0.0])  # on the optical axis, 0.8 m away
    gt = [GraspSet(g[None], np.array([0.05]), np.array([False]))]
    lateral = make_pose(np.eye(3), [0.02, 0.0, 0.0])  # 2 cm sideways: image plane only (to first order)
    deeper = make_pose(np.eye(3), [0.0, 0.0, -0.015])  # 1.5 cm further along the ray
    turned = make_pose(rot_x(np.radians(30.0)), [0.0, 0.0, 0.0])
    pred = np.stack([lateral, deeper, turned])
    errors, matched, shapes, keypoints = decompose_image(pred, np.array([0.05, 0.05, 0.07]), gt, ["cuboid"], obs)
    assert keypoints.shape == (3, 4) and np.isnan(keypoints).all()  # no keypoints given
    col = {t: errors[:, TERMS.index(t)] for t in TERMS}
    assert col["centre_cm"][0] == pytest.approx(2.0, rel=1e-6) and col["ray_cm"][0] == pytest.approx(0.025, abs=1e-3)
    assert col["centre_px"][0] == pytest.approx(0.02 * REALSENSE.fx / 0.8, rel=1e-6)
    assert col["centre_cm"][1] == pytest.approx(0.0, abs=1e-9) and col["ray_cm"][1] == pytest.approx(1.5)
    assert col["rotation_deg"][2] == pytest.approx(30.0) and col["width_cm"][2] == pytest.approx(2.0)
    assert matched.tolist() == [False, False, False] and shapes.tolist() == ["cuboid"] * 3
    table = ErrorTable()
    table.add(errors, matched, shapes)
    s = table.summary()["cuboid"]
    assert s["centre_cm"]["fails_alone"] == pytest.approx(1 / 3) and s["ray_cm"]["fails_alone"] == pytest.approx(1 / 3)
    assert s["rotation_deg"]["share_of_failures"] == pytest.approx(1 / 3) and s["gsr_1cm"] == 0.0


def test_keypoint_errors_in_pixels_respect_the_flip():
    """The GT grasp's own box keypoints score 0, and so do its flipped ones (L↔R, TL↔TR); shifted by 3 px in u
    every keypoint is 3 px off."""
    from kgn_bench.eval.errors import keypoint_errors
    from kgn_bench.geometry import invert_pose, project
    from kgn_bench.grasp import keypoints_in_frame

    obs = _obs()
    g = make_pose(rot_x(np.radians(20.0)), [0.01, -0.02, 0.05])[None]
    cam = keypoints_in_frame(invert_pose(obs.camera_pose) @ g, 0.1)
    kp = project(cam.reshape(-1, 3), REALSENSE.K).reshape(1, 4, 2)
    np.testing.assert_allclose(keypoint_errors(kp, g, np.array([0.1]), obs), 0.0, atol=1e-9)
    np.testing.assert_allclose(keypoint_errors(kp[:, [1, 0, 3, 2]], g, np.array([0.1]), obs), 0.0, atol=1e-9)
    np.testing.assert_allclose(keypoint_errors(kp + np.array([3.0, 0.0]), g, np.array([0.1]), obs), 3.0, atol=1e-9)
    # a box twice as large is not the GT's: its keypoints are off
    assert keypoint_errors(kp, g, np.array([0.2]), obs).min() > 5.0


def test_decomposition_of_a_real_detector(tiny_dataset, tmp_path):
    from kgn_bench.detectors.kgn import KGNDetector
    from kgn_bench.eval.errors import decompose_dataset, write_errors

    root, _ = tiny_dataset
    table = decompose_dataset(KGNDetector("kgnv2"), root, views=2, progress=False)
    errors, _, shapes = table.arrays()
    assert len(errors) > 0 and np.all(np.isfinite(errors)) and set(shapes) <= {"cuboid", "cylinder", "ring", "stick",
                                                                               "sphere", "semi_sphere"}
    keypoints = table.keypoint_arrays()
    assert keypoints.shape == (len(errors), 4) and np.all(np.isfinite(keypoints)) and np.all(keypoints >= 0)
    paths = write_errors(table, tmp_path / "e", "test", {"views": 2})
    assert all(p.is_file() for p in paths) and "| all |" in paths[1].read_text()
    assert "Keypoint error before PnP" in paths[1].read_text()
    assert "keypoints_px" in table.summary()["all"]
