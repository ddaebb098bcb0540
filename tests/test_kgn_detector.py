"""The learned detector wrapper: weights lookup, variant checks, bad observations, a real forward pass."""

import numpy as np
import pytest
import torch

from kgn_bench.camera import REALSENSE
from kgn_bench.detectors import DetectorError, Observation, make_detector
from kgn_bench.detectors.kgn import WEIGHTS_DIR, KGNDetector, weights_path
from kgn_bench.model.checkpoint import CheckpointError


def _constant_maps(hm_bias):
    """Edit a network so every cell is a bin-4 peak of ``hm_bias`` with a horizontal box of keypoints."""

    def prepare(net):
        for name, bias in (("hm", -5.0), ("width", 0.05), ("scale", 0.8)):
            torch.nn.init.zeros_(net.heads[name][2].weight)
            torch.nn.init.constant_(net.heads[name][2].bias, bias)
        box = torch.tensor([-3.0, 0.0, 3.0, 0.0, -3.0, -6.0, 3.0, -6.0])  # L, R, TL, TR offsets (output px)
        torch.nn.init.zeros_(net.heads["kpts"][2].weight)
        with torch.no_grad():
            net.heads["hm"][2].bias[4] = hm_bias
            net.heads["kpts"][2].bias.copy_(box.repeat(9))

    return prepare


def _observation(depth_value=0.8):
    h, w = REALSENSE.height, REALSENSE.width
    rgb = np.random.default_rng(0).integers(0, 255, (h, w, 3), dtype=np.uint8)
    return Observation(rgb, np.full((h, w), depth_value, np.float32), REALSENSE, np.eye(4))


def test_weights_lookup():
    assert weights_path("kgn_depth") == WEIGHTS_DIR / "kgn.pt"
    assert weights_path("kgnv2") == WEIGHTS_DIR / "kgnv2.pt"
    assert weights_path("kgnv2", "mine") == WEIGHTS_DIR / "mine.pt"
    assert weights_path("kgnv2_mesh") == WEIGHTS_DIR / "kgnv2_mesh.pt"  # another model of kgnv2: its own file


def test_another_model_of_a_variant_decodes_as_it_under_its_own_name(tmp_path, small_model):
    small_model(tmp_path / "mesh.pt")
    small_model(tmp_path / "kgn.pt", variant="kgn")
    det = KGNDetector("kgnv2_mesh", tmp_path / "mesh.pt")
    assert det.name == "kgnv2_mesh" and det.variant.name == "kgnv2"
    assert make_detector("kgnv2_mesh", tmp_path / "mesh.pt").name == "kgnv2_mesh"
    with pytest.raises(CheckpointError, match="needs 'kgnv2' weights"):
        KGNDetector("kgnv2_mesh", tmp_path / "kgn.pt")


def test_forward_pass_gives_camera_frame_candidates(tmp_path, small_model):
    small_model(tmp_path / "peaks.pt", prepare=_constant_maps(3.0))  # every cell a peak: exercises decode fully
    det = KGNDetector("kgnv2", tmp_path / "peaks.pt")
    cands = det.detect(_observation())
    assert 0 < len(cands) <= 100
    assert np.all(np.isfinite(cands.poses)) and np.all(cands.poses[:, 2, 3] > 0)
    assert np.all(cands.confidences >= 0.3)
    np.testing.assert_allclose(np.linalg.norm(cands.poses[:, :3, 3], axis=1), 0.8, rtol=1e-5)  # ‖t‖ = ŝ
    np.testing.assert_allclose(cands.widths, 0.05, rtol=1e-5)
    assert {"network", "decode"} <= det.timing.keys()
    small_model(tmp_path / "kgnv2.pt")
    quiet = KGNDetector("kgnv2", tmp_path / "kgnv2.pt")  # initial bias −2.19: no peak reaches 0.3
    assert len(quiet.detect(_observation())) == 0


def test_bad_observations_raise_detector_errors(tmp_path, small_model):
    small_model(tmp_path / "kgnv2.pt")
    det = KGNDetector("kgnv2", tmp_path / "kgnv2.pt")
    obs = _observation()
    with pytest.raises(DetectorError, match="depth contains NaN"):
        det.detect(Observation(obs.rgb, np.full_like(obs.depth, np.nan), REALSENSE, np.eye(4)))
    with pytest.raises(DetectorError, match="depth is empty"):
        det.detect(_observation(0.0))
    with pytest.raises(DetectorError, match="rgb must be"):
        det.detect(Observation(obs.rgb[:100], obs.depth, REALSENSE, np.eye(4)))


def test_variant_mismatch_and_missing_weights(tmp_path, small_model):
    small_model(tmp_path / "kgnv2.pt")
    small_model(tmp_path / "kgn.pt", variant="kgn")
    with pytest.raises(CheckpointError, match="needs 'kgn' weights"):
        KGNDetector("kgn_depth", tmp_path / "kgnv2.pt")
    assert KGNDetector("kgn_depth", tmp_path / "kgn.pt").variant.translation == "depth"
    with pytest.raises(CheckpointError, match="no checkpoint at"):
        make_detector("kgnv2", tmp_path / "missing.pt")


def test_shipped_kgnv2_finds_grasps_near_the_ground_truth(tiny_dataset):
    """The committed weights on a freshly generated multi-object view: candidates exist, lie in front of the
    camera, and a good share of them match a collision-free ground-truth grasp at (3 cm, 45°)."""
    from kgn_bench.data.format import SceneAnnotation, read_split, read_view, scene_dir
    from kgn_bench.eval.vision import THRESHOLDS, evaluate_image

    root, _ = tiny_dataset
    det = make_detector("kgnv2")
    assert det.model.meta["epoch"] >= 1
    scene = read_split(root, "test")[0]
    ann = SceneAnnotation.load(scene_dir(root, scene) / "scene.json")
    rgbd = read_view(scene_dir(root, scene), 0)
    cands = det.detect(Observation(rgbd.rgb, rgbd.depth, ann.intrinsics, ann.camera_poses[0]))
    assert len(cands) > 10 and np.all(cands.poses[:, 2, 3] > 0.3)
    from kgn_bench.data.generate import relabel_grasps
    from kgn_bench.shapes.base import EVAL_DENSITY

    gt = [g.free() for g in relabel_grasps(ann, EVAL_DENSITY)]
    counts = evaluate_image(cands.world_poses(ann.camera_poses[0]), gt, [o.type for o in ann.objects], THRESHOLDS)
    assert counts.credited[-1].sum() / len(cands) > 0.4  # loose 3 cm / 45° GSR of one view
