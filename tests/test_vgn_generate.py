"""VGN's data generator: grasp frames, the yaw rule, physics labels with the floating Panda hand, and whole
scenes written resumably."""

from __future__ import annotations

import numpy as np
import pytest

from kgn_bench import giga
from kgn_bench.data.format import DatasetError
from kgn_bench.data.vgn_format import read_manifest, read_scene
from kgn_bench.data.vgn_generate import (
    GraspLabels,
    VGNDataConfig,
    generate_scene,
    generate_vgn_dataset,
    grasp_frames,
    grasp_views,
    label_grasps,
    snap_references,
    to_voxels,
    widest_run_centre,
)
from kgn_bench.geometry import make_pose, rot_x
from kgn_bench.gripper import PANDA_HAND
from kgn_bench.shapes.primitives import Cuboid
from kgn_bench.sim.floating_hand import FloatingHand, add_floating_cell, execute_grasp, precheck_grasp
from kgn_bench.sim.placement import settle
from kgn_bench.sim.scene import Scene, SceneObject


def test_widest_run_centre_is_circular():
    assert widest_run_centre(np.array([0, 0, 0, 0, 0, 0], bool)) == -1
    assert widest_run_centre(np.array([1, 1, 1, 1, 1, 1], bool)) == 0
    assert widest_run_centre(np.array([0, 1, 1, 1, 0, 0], bool)) == 2
    assert widest_run_centre(np.array([1, 1, 0, 0, 0, 1], bool)) == 0  # the run 5, 0, 1 wraps past yaw π
    assert widest_run_centre(np.array([1, 0, 0, 1, 1, 0], bool)) == 3


def test_turns_start_at_the_chosen_yaw_and_are_turns_about_the_approach():
    """``GraspLabels.turns`` column j is the yaw j steps past the stored one, and that grasp is the stored pose
    turned by ``j π / Y`` about its own approach axis (+x): the frame ``data.vgn_format`` documents."""
    frames = grasp_frames(np.array([[0.1, 0.0, 0.05]]), np.array([[0.2, -0.3, 0.9]]), np.array([0.02]), 6)
    holds = np.array([[0, 1, 1, 1, 0, 0]], bool)
    chosen = np.array([widest_run_centre(holds[0])])
    labels = GraspLabels(frames[np.arange(1), chosen], np.array([0.04]), np.array([True]), holds, chosen)
    assert chosen[0] == 2 and labels.turns()[0].tolist() == [True, True, False, False, False, True]
    for j in range(6):
        turned = labels.poses[0, :3, :3] @ rot_x(j * np.pi / 6)
        np.testing.assert_allclose(turned, frames[0, (2 + j) % 6, :3, :3] * (1 if 2 + j < 6 else [1, -1, -1]),
                                   atol=1e-12)


def test_grasp_frames_approach_into_the_surface_and_sweep_the_closing_axis():
    n = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 0.6, 0.8]])
    p = np.array([[0.0, 0.0, 0.05], [0.02, 0.0, 0.03], [0.0, 0.01, 0.04]])
    F = grasp_frames(p, n, np.array([0.01, 0.02, 0.0]), 6)
    assert F.shape == (3, 6, 4, 4)
    R = F[..., :3, :3]
    np.testing.assert_allclose(np.swapaxes(R, -1, -2) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0)
    np.testing.assert_allclose(F[:, :, :3, 0], np.broadcast_to(-n[:, None], (3, 6, 3)), atol=1e-12)
    np.testing.assert_allclose(F[0, 0, :3, 3], [0.0, 0.0, 0.04])  # the fingertips 1 cm past the top face
    np.testing.assert_allclose(F[0, 0, :3, 2], [1.0, 0.0, 0.0], atol=1e-12)  # yaw 0: world x
    np.testing.assert_allclose(F[1, 0, :3, 2], [0.0, 1.0, 0.0], atol=1e-12)  # approach along x: world y
    angles = np.degrees(np.arccos(np.clip(F[0, :, :3, 2] @ F[0, 0, :3, 2], -1, 1)))
    np.testing.assert_allclose(angles, [0, 30, 60, 90, 120, 150], atol=1e-9)


def _standing_box() -> tuple[Scene, FloatingHand]:
    """A 4 × 10 × 8 cm box settled upright on the table of the floating hand's cell, the hand parked."""
    box = Cuboid((0.04, 0.10, 0.08))
    scene = Scene([SceneObject(box, (0.5, 0.5, 0.5), make_pose(t=np.array([0.0, 0.0, 0.041])))],
                  extend=lambda root: add_floating_cell(root, PANDA_HAND))
    hand = FloatingHand(scene, PANDA_HAND)
    hand.park()
    settle(scene)
    return scene, hand


def test_labels_hold_across_the_narrow_side_only():
    """A 4 × 10 cm box standing on the table, grasped from above 3 cm deep: the 8 cm Panda hand closes on the
    4 cm side (yaws near 0, closing along x) and not across the 10 cm one (yaw 90°)."""
    scene, hand = _standing_box()
    top = np.array([[0.0, 0.0, scene.object_pose(0)[2, 3] + 0.04]])
    frames = grasp_frames(top, np.array([[0.0, 0.0, 1.0]]), np.array([0.03]), 6)
    before = scene.data.qpos.copy()
    labels = label_grasps(scene, hand, frames)
    np.testing.assert_array_equal(scene.data.qpos, before)  # the scene is restored after labelling
    assert labels.holds[0, 0] and not labels.holds[0, 3]
    assert labels.labels[0] and widest_run_centre(labels.holds[0]) == 0
    assert labels.chosen[0] == 0 and labels.turns()[0, 0]
    assert labels.widths[0] == pytest.approx(0.04, abs=0.004)
    voxels, quats, widths, keep = to_voxels(labels.poses, labels.widths)
    reference = labels.poses[0, :3, 3] - giga.GRASP_REFERENCE_DEPTH * labels.poses[0, :3, 0]  # 5 cm behind the tips
    np.testing.assert_allclose(voxels[0] * giga.VOXEL_SIZE + giga.WORKSPACE_ORIGIN, reference)
    assert keep[0] and widths[0] == pytest.approx(labels.widths[0] / giga.VOXEL_SIZE)
    np.testing.assert_allclose(np.linalg.norm(quats, axis=1), 1.0)


def test_the_precheck_rejects_only_grasps_that_execution_fails():
    """The standing box of the test above: from above 3 cm deep closing across 4 cm passes and holds; across
    the 10 cm side the fingers land on the box on the way in; beside the box the jaws close on air; with
    the pre-grasp inside the box the hand starts in collision. Each rejected grasp also fails when executed, and
    labelling gives the same labels with and without the pre-check."""
    scene, hand = _standing_box()
    z = scene.object_pose(0)[2, 3] + 0.04
    frames = grasp_frames(np.array([[0.0, 0.0, z], [0.09, 0.0, z]]), np.array([[0.0, 0.0, 1.0]] * 2),
                          np.array([0.03, 0.03]), 6)
    inside = frames[0, 0].copy()
    inside[2, 3] -= 0.09  # the pre-grasp (5 cm back, up) still inside the box
    cases = {"pass": frames[0, 0], "approach": frames[0, 3], "empty": frames[1, 0], "pre-grasp": inside}
    before = scene.data.qpos.copy()
    for expected, T in cases.items():
        assert (precheck_grasp(hand, T) or "pass") == expected
        np.testing.assert_array_equal(scene.data.qpos[:7], before[:7])  # the object never moved
        outcome = execute_grasp(hand, T, allow_contact=False)
        assert (outcome.reason is None) == (expected == "pass"), expected
        scene.data.qpos[:] = before
        scene.data.qvel[:] = 0.0
        scene.forward()
    a, b = label_grasps(scene, hand, frames, precheck=True), label_grasps(scene, hand, frames, precheck=False)
    np.testing.assert_array_equal(a.holds, b.holds)
    assert a.holds[0, 0] and not a.holds[1].any()


def test_snapped_reference_points_lie_on_the_grid_lattice():
    frames = grasp_frames(np.array([[0.0123, -0.0456, 0.0311]]), np.array([[0.3, 0.1, 0.9]]), np.array([0.02]), 3)
    snapped = snap_references(frames)
    reference = snapped[..., :3, 3] - giga.GRASP_REFERENCE_DEPTH * snapped[..., :3, 0]
    voxels = (reference - giga.WORKSPACE_ORIGIN) / giga.VOXEL_SIZE
    np.testing.assert_allclose(voxels, np.rint(voxels), atol=1e-9)
    assert np.abs(snapped[..., :3, 3] - frames[..., :3, 3]).max() <= giga.VOXEL_SIZE / 2 + 1e-12
    np.testing.assert_array_equal(snapped[..., :3, :3], frames[..., :3, :3])


def test_grasp_views_look_down_at_the_workspace():
    views = grasp_views(np.random.default_rng(3))
    assert 1 <= len(views) <= 6
    for T in views:
        assert T[2, 3] > 0.3 and T[2, 2] < -np.cos(np.pi / 4) - 1e-9  # above, looking down within 45° of vertical


def test_a_scene_is_reproducible_and_a_dataset_resumes_and_grows(tmp_path):
    config = VGNDataConfig(scenes=1, objects=("cuboid", "stick"), grasps_per_scene=12)
    a, b = generate_scene(config, 1), generate_scene(config, 1)
    for key in ("tsdf", "voxels", "quats", "widths", "labels", "holds"):
        np.testing.assert_array_equal(a[key], b[key])
    assert a["holds"].shape == (len(a["labels"]), 6)
    np.testing.assert_array_equal(a["holds"][:, 0], a["labels"])  # the stored yaw is one that held
    assert a["meta"]["arrangement"] == "packed" and a["tsdf"].shape == (40, 40, 40)
    assert 0.0 < a["tsdf"].max() < 1.0 and len(a["labels"]) > 0
    grid = a["voxels"] * giga.VOXEL_SIZE
    assert np.all((grid >= 0.02 - 1e-9) & (grid <= 0.28 + 1e-9))
    np.testing.assert_allclose(a["voxels"], np.rint(a["voxels"]), atol=1e-4)  # snapped to the lattice
    out = tmp_path / "vgn"
    first = generate_vgn_dataset(config, out, progress=False)
    assert first["scenes"] == 1 and read_manifest(out).sha256
    grown = generate_vgn_dataset(VGNDataConfig(scenes=2, objects=("cuboid", "stick"), grasps_per_scene=12), out,
                                 progress=False)
    assert grown["scenes"] == 1 and len(read_manifest(out).scenes) == 2
    np.testing.assert_array_equal(read_scene(out, 1).labels, a["labels"])
    np.testing.assert_array_equal(read_scene(out, 1).holds, a["holds"])
    with pytest.raises(DatasetError, match="grasps_per_scene"):
        generate_vgn_dataset(VGNDataConfig(scenes=2, objects=("cuboid", "stick"), grasps_per_scene=13), out,
                             progress=False)
