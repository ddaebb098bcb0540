"""The ``vgn`` detector: VGN's selection on synthetic volumes (threshold, forcing, NMS, width, surface and border
masks), the voxel → grasp pose convention, an end-to-end run of a (biased) random network on a real rendered
GIGA view, and the one-line refusal of missing or damaged weights."""

import numpy as np
import pytest
import torch
from scipy import ndimage

from kgn_bench.camera import GIGA, look_at
from kgn_bench.detectors import DETECTORS, Detector, make_detector
from kgn_bench.detectors.vgn import (
    GIGA_BORDER,
    GIGA_SELECTION,
    VGN_SELECTION,
    SelectionConfig,
    VGNDetector,
    VoxelGrasps,
    grid_poses,
    select_grasps,
)
from kgn_bench.geometry import make_pose, matrix_from_quat_wxyz
from kgn_bench.giga import (
    CAMERA_DISTANCE,
    CAMERA_TARGET,
    GRASP_REFERENCE_DEPTH,
    RESOLUTION,
    TRUNCATION_VOXELS,
    VOXEL_SIZE,
    WORKSPACE_ORIGIN,
    WORKSPACE_SIZE,
    in_workspace,
)
from kgn_bench.model.checkpoint import CheckpointError
from kgn_bench.model.vgn_checkpoint import save_vgn_checkpoint, vgn_payload
from kgn_bench.model.vgn_network import VGNNet
from kgn_bench.tsdf import VoxelGrid
from kgn_bench.types import Observation

R = 40
IDENTITY = np.zeros((4, R, R, R), np.float32)
IDENTITY[0] = 1.0


def _blob(centre, amplitude, spread=6.0):
    """A Gaussian bump of quality: smoothing with σ = 1 keeps ~96 % of its height and a unique maximum."""
    i, j, k = np.meshgrid(*(np.arange(R),) * 3, indexing="ij")
    d2 = (i - centre[0]) ** 2 + (j - centre[1]) ** 2 + (k - centre[2]) ** 2
    return amplitude * np.exp(-d2 / (2 * spread**2))


def _free():
    """A network input that is "outside" everywhere, so the surface mask keeps every voxel."""
    return np.full((R, R, R), 0.7, np.float32)


def _widths(value=4.0):
    return np.full((R, R, R), value, np.float32)


def test_nms_returns_the_peaks_best_first():
    quality = _blob((10, 12, 20), 0.97) + _blob((30, 28, 14), 0.99)
    got = select_grasps(quality, IDENTITY, _widths(), _free(), VGN_SELECTION)
    assert isinstance(got, VoxelGrasps) and len(got) == 2
    np.testing.assert_array_equal(got.index, [[30, 28, 14], [10, 12, 20]])
    assert got.score[0] > got.score[1] > 0.9
    np.testing.assert_allclose(got.quaternion, [[1, 0, 0, 0]] * 2)
    np.testing.assert_allclose(got.width, [4.0, 4.0])


def test_threshold_and_gigas_forcing():
    weak = _blob((20, 20, 20), 0.75)  # smoothed ≈ 0.72: below 0.9, above GIGA's 0.5 floor
    assert len(select_grasps(weak, IDENTITY, _widths(), _free(), VGN_SELECTION)) == 0
    forced = select_grasps(weak + _blob((8, 30, 30), 0.6), IDENTITY, _widths(), _free(), GIGA_SELECTION)
    np.testing.assert_array_equal(forced.index, [[20, 20, 20]])  # the single best one only
    # once any voxel reaches the threshold, forcing adds nothing below it
    both = select_grasps(weak + _blob((8, 30, 30), 0.99), IDENTITY, _widths(), _free(), GIGA_SELECTION)
    np.testing.assert_array_equal(both.index, [[8, 30, 30]])
    # below the floor even forcing finds nothing
    assert len(select_grasps(_blob((20, 20, 20), 0.4), IDENTITY, _widths(), _free(), GIGA_SELECTION)) == 0


def test_width_mask_drops_grasps_outside_1_to_7_cm():
    quality = _blob((10, 12, 20), 0.97) + _blob((30, 28, 14), 0.99)
    for bad in (1.0, 10.0):
        width = _widths()
        width[25:36, 23:34, 9:20] = bad  # around the better peak
        got = select_grasps(quality, IDENTITY, width, _free(), VGN_SELECTION)
        np.testing.assert_array_equal(got.index, [[10, 12, 20]])
    assert 1.33 * VOXEL_SIZE == pytest.approx(0.01, abs=1e-4) and 9.33 * VOXEL_SIZE == pytest.approx(0.07, abs=1e-4)


def test_surface_mask_keeps_the_band_and_two_voxels_of_free_space():
    """A horizontal surface seen from above: behind it (inside) and far from it nothing is kept."""
    tsdf = np.zeros((R, R, R), np.float32)
    tsdf[:, :, 10:15] = np.array([0.2, 0.4, 0.5, 0.7, 0.9])  # k = 10, 11 inside; 12 surface; 13, 14 outside
    quality = np.full((R, R, R), 0.95)
    got = select_grasps(quality, IDENTITY, _widths(), tsdf, VGN_SELECTION)
    # outside (13, 14), dilated twice into voxels not inside: 12 and 15, 16; 11 is inside and stops it
    assert set(got.index[:, 2].tolist()) == {12, 13, 14, 15, 16}
    # GIGA's outside threshold 0.1 counts every voxel of the band as outside
    giga = select_grasps(quality, IDENTITY, _widths(), tsdf, SelectionConfig(border=None, force_floor=None))
    assert set(giga.index[:, 2].tolist()) == set(range(8, 17))


def test_gigas_border_mask():
    """No grasp within 2 voxels of the x and y faces or in the 7 lowest layers (up to 5 mm above the table)."""
    assert GIGA_BORDER == (2, 2, 7)
    quality = np.full((R, R, R), 0.95)  # NMS keeps every voxel of a constant volume
    assert len(select_grasps(quality, IDENTITY, _widths(), _free(), VGN_SELECTION)) == R**3
    border_only = SelectionConfig(outside_threshold=0.5, force_floor=None, border=GIGA_BORDER)
    got = select_grasps(quality, IDENTITY, _widths(), _free(), border_only)
    assert len(got) == 36 * 36 * 33
    assert got.index.min(axis=0).tolist() == [2, 2, 7] and got.index.max(axis=0).tolist() == [37, 37, 39]
    assert (WORKSPACE_ORIGIN[2] + 7 * VOXEL_SIZE) > 0  # the lowest kept layer lies above the table (z = 0)


def test_select_grasps_leaves_its_inputs_alone_and_checks_shapes():
    quality = _blob((10, 12, 20), 0.97)
    before = quality.copy()
    select_grasps(quality, IDENTITY, _widths(), _free())
    np.testing.assert_array_equal(quality, before)
    with pytest.raises(ValueError, match="rotation"):
        select_grasps(quality, IDENTITY[:3], _widths(), _free())


def test_grid_poses_put_the_grasps_reference_point_at_index_times_voxel():
    q = np.array([[np.cos(0.3), 0.0, np.sin(0.3), 0.0]])
    poses = grid_poses(VoxelGrasps(np.array([[3, 4, 5]]), q, np.array([4.0]), np.array([0.9])), 0.0075)
    np.testing.assert_allclose(poses[0, :3, :3], matrix_from_quat_wxyz(q[0]))
    reference = poses[0, :3, 3] - 0.05 * poses[0, :3, 0]  # VGN's TCP, a finger depth behind the fingertips
    np.testing.assert_allclose(reference, [0.0225, 0.03, 0.0375])  # no half-voxel offset
    assert grid_poses(VoxelGrasps(np.zeros((0, 3), int), np.zeros((0, 4)), np.zeros(0), np.zeros(0)),
                      0.0075).shape == (0, 4, 4)


# -- end to end ----------------------------------------------------------------------------------------------


def _weights(path, quality_bias=3.0, width_bias=4.0):
    """A randomly initialised VGN whose quality (~0.95) and width (~4 voxels) heads are biased so that
    grasps pass the masks, saved as a weights file."""
    torch.manual_seed(0)
    net = VGNNet()
    with torch.no_grad():
        net.quality.bias.fill_(quality_bias)
        net.width.bias.fill_(width_bias)
    save_vgn_checkpoint(path, vgn_payload(net, VoxelGrid(WORKSPACE_SIZE, RESOLUTION, TRUNCATION_VOXELS)))
    return path


@pytest.fixture(scope="module")
def giga_view():
    """Two boxes and a ball on the table, rendered from GIGA's side camera with its 540 px intrinsics."""
    from kgn_bench.shapes.primitives import Cuboid, Sphere
    from kgn_bench.sim.render import SceneRenderer
    from kgn_bench.sim.scene import Scene, SceneObject

    objects = [SceneObject(Cuboid((0.05, 0.04, 0.06)), (0.8, 0.2, 0.2), make_pose(t=(0.03, 0.02, 0.03))),
               SceneObject(Cuboid((0.03, 0.08, 0.03)), (0.2, 0.8, 0.2), make_pose(t=(-0.05, -0.03, 0.015))),
               SceneObject(Sphere(0.025), (0.2, 0.2, 0.8), make_pose(t=(0.0, -0.07, 0.025)))]
    theta, phi = np.pi / 3, -np.pi / 2  # GIGA's camera_on_sphere angles
    target = np.array(CAMERA_TARGET)
    eye = target + CAMERA_DISTANCE * np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi),
                                               np.cos(theta)])
    cam = look_at(eye, target)
    with SceneRenderer(Scene(objects, GIGA)) as renderer:
        view = renderer.render(cam)
    depth = view.depth.copy()
    depth[200:210, 300:310] = np.nan  # NaN reads as no measurement
    return Observation(view.rgb, depth, GIGA, cam)


def test_end_to_end_on_a_rendered_view(tmp_path, giga_view):
    obs = giga_view
    det = make_detector("vgn", weights=_weights(tmp_path / "random_vgn.pt"))
    assert isinstance(det, VGNDetector) and isinstance(det, Detector)
    assert det.name == "vgn" and not det.privileged and "vgn" in DETECTORS
    det.reset([0, 0])
    cands = det.detect(obs)
    assert len(cands) > 0 and set(det.timing) == {"tsdf", "network", "select"}
    assert np.all(np.isnan(cands.reprojection_errors))
    assert np.all(np.diff(cands.confidences) <= 0) and cands.confidences.min() >= 0.9
    assert np.all((cands.widths >= 0.01 - 1e-4) & (cands.widths <= 0.07 + 1e-4))
    world = cands.world_poses(obs.camera_pose)
    reference = world[:, :3, 3] - GRASP_REFERENCE_DEPTH * world[:, :3, 0]
    assert np.all(in_workspace(reference))
    assert reference[:, 2].min() >= 7 * VOXEL_SIZE + WORKSPACE_ORIGIN[2] - 1e-9  # GIGA's border: k ≥ 7
    rotations = world[:, :3, :3]
    np.testing.assert_allclose(rotations @ np.swapaxes(rotations, 1, 2), np.broadcast_to(np.eye(3), rotations.shape),
                               atol=1e-6)
    # the camera-frame poses are the grid poses of the selected voxels, moved through the world
    vol = det.volume(obs)
    x = vol.network_input()
    assert 0 < np.count_nonzero(x) < x.size
    sel = select_grasps(*det.predict(x), x, GIGA_SELECTION)
    expected = make_pose(t=WORKSPACE_ORIGIN) @ grid_poses(sel, VOXEL_SIZE)
    np.testing.assert_allclose(world, expected, atol=1e-9)
    np.testing.assert_allclose(cands.widths, sel.width * VOXEL_SIZE)
    # every grasp lies within two voxels of the observed surface band (the surface mask)
    to_band = ndimage.distance_transform_edt(~(x > GIGA_SELECTION.outside_threshold))
    assert to_band[tuple(sel.index.T)].max() <= 2.0


def test_a_network_that_finds_nothing_returns_no_candidates(tmp_path, giga_view):
    det = VGNDetector(_weights(tmp_path / "narrow.pt", width_bias=0.0))  # every width under 1 cm
    assert len(det.detect(giga_view)) == 0


@pytest.mark.parametrize("content, message", [
    (None, "no VGN weights at"),
    (b"not a checkpoint at all", "not a readable VGN checkpoint"),
    ("other", "not a kgn-bench VGN checkpoint"),
])
def test_missing_or_damaged_weights_are_one_line(tmp_path, content, message):
    path = tmp_path / "vgn.pt"
    if isinstance(content, bytes):
        path.write_bytes(content)
    elif content == "other":
        torch.save({"format": "kgn-bench-checkpoint", "model": {}}, path)
    with pytest.raises(CheckpointError, match=message) as e:
        make_detector("vgn", weights=path)
    assert "\n" not in str(e.value) and str(path) in str(e.value)


def test_truncated_weights_are_refused(tmp_path):
    path = _weights(tmp_path / "vgn.pt")
    path.write_bytes(path.read_bytes()[:5000])
    with pytest.raises(CheckpointError, match="not a readable VGN checkpoint"):
        VGNDetector(path)
