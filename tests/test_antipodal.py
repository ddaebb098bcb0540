"""The antipodal point-cloud detector on real rendered work-cell scenes (a standing box, a lying stick): where its
grasps are, how wide, which way they close, that they clear the observed cloud, its seeding, and its edge cases."""

import numpy as np
import pytest

from kgn_bench.bench.selector import score_candidates
from kgn_bench.camera import REALSENSE, orbit_pose
from kgn_bench.config import SelectorConfig
from kgn_bench.detectors import Candidates, Detector, DetectorError, Observation, make_detector
from kgn_bench.detectors.antipodal import (
    AntipodalConfig,
    AntipodalDetector,
    _extent,
    _lowest_box_z,
    estimate_normals,
)
from kgn_bench.geometry import backproject, make_pose, matrix_from_quat_wxyz, rot_z
from kgn_bench.gripper import GRIPPER, GripperBox, box_corners
from kgn_bench.shapes.primitives import Cuboid, Stick
from kgn_bench.sim.control import IK, Executor
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.robot import PARK_Q, add_workcell
from kgn_bench.sim.scene import Scene, SceneObject

H, W = REALSENSE.height, REALSENSE.width
CAMERA = orbit_pose(0.8, np.deg2rad(60.0), np.deg2rad(90.0))  # the tasks' default camera
BOX = Cuboid((0.05, 0.08, 0.07))
BOX_POSE = make_pose(rot_z(0.4), (0.05, -0.03, 0.035))
STICK = Stick(0.008, 0.09)
LYING = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # stick axis (object z) → world x
STICK_POSE = make_pose(rot_z(0.7) @ LYING, (-0.02, 0.04, 0.008))


def _observe(shape, pose):
    scene = Scene([SceneObject(shape, (0.8, 0.3, 0.2), pose)], extend=add_workcell)
    Executor(scene, IK()).reset(PARK_Q)
    with SceneRenderer(scene) as r:
        view = r.render(CAMERA)
    return Observation(view.rgb, view.depth, scene.intrinsics, CAMERA)


@pytest.fixture(scope="module")
def box_obs():
    return _observe(BOX, BOX_POSE)


@pytest.fixture(scope="module")
def stick_obs():
    return _observe(STICK, STICK_POSE)


def _detect(obs, seed=(0, 0), **kw):
    det = AntipodalDetector(AntipodalConfig(**kw))
    det.reset(list(seed))
    return det.detect(obs)


def _table_depth(camera_pose):
    """Planar depth of the bare table plane z = 0 seen from ``camera_pose``."""
    K = REALSENSE.K
    u, v = np.meshgrid(np.arange(W), np.arange(H))
    rays = np.stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones((H, W))], axis=-1)
    dz = rays @ camera_pose[2, :3]  # world z change per unit of camera depth
    return (-camera_pose[2, 3] / dz).astype(np.float32)


def test_registered_and_unprivileged():
    det = make_detector("antipodal")
    assert isinstance(det, AntipodalDetector) and isinstance(det, Detector)
    assert det.name == "antipodal" and det.privileged is False
    with pytest.raises(ValueError, match="takes no weights"):
        make_detector("antipodal", weights="x")


def test_box_grasps_straddle_the_box_across_opposite_faces(box_obs):
    cands = _detect(box_obs)
    assert len(cands) >= 20
    world = cands.world_poses(box_obs.camera_pose)
    R = world[:, :3, :3]
    np.testing.assert_allclose(R.transpose(0, 2, 1) @ R, np.tile(np.eye(3), (len(R), 1, 1)), atol=1e-6)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-6)
    top = slice(0, 10)
    axes = BOX_POSE[:3, :3]  # columns: the box's face normals
    align = np.abs(world[top, :3, 2] @ axes)  # (n, 3): |cos| between the closing axis and each face normal
    face = align.argmax(axis=1)
    assert np.all(align.max(axis=1) > np.cos(np.deg2rad(20.0)))  # closing roughly normal to a pair of faces
    thickness = np.asarray(BOX.size)[face]
    assert np.all(cands.widths[top] >= thickness) and np.all(cands.widths[top] <= thickness + 0.03)
    assert np.all((cands.widths > 0) & (cands.widths <= GRIPPER.max_width))
    # the best ones close across a side pair (not top-bottom) and come from above
    assert np.all(face != 2) and np.all(world[top, 2, 0] < -0.7)
    # grasp centres inside the box's bounding sphere, fingertips above the table
    local = (world[:, :3, 3] - BOX_POSE[:3, 3]) @ axes
    assert np.all(np.linalg.norm(local, axis=1) < np.linalg.norm(BOX.size) / 2)
    assert np.all(np.abs(local[top]) <= np.asarray(BOX.size) / 2 + 1e-3)
    assert np.all(world[:, 2, 3] > 0.0)


def test_box_grasps_clear_the_observed_cloud_and_enclose_it(box_obs):
    cands = _detect(box_obs)
    world = cands.world_poses(box_obs.camera_pose)
    points = box_obs.points_world(stride=2)
    points = points[points[:, 2] > 0.002]
    for pose, w in zip(world[:30], cands.widths[:30]):
        local = (points - pose[:3, 3]) @ pose[:3, :3]
        for box in (GRIPPER.finger_box(1, w + 0.01), GRIPPER.finger_box(-1, w + 0.01), GRIPPER.palm_box()):
            assert not np.any(np.all(np.abs(local - box.centre) < box.half, axis=1))
        fingers = np.concatenate([box_corners(GRIPPER.finger_box(side, w + 0.01), pose[None])[0] for side in (1, -1)])
        assert fingers[:, 2].min() >= 0.003  # the selector's table clearance
        region = GRIPPER.closing_region(w)
        assert np.count_nonzero(np.all(np.abs(local - region.centre) < region.half, axis=1)) >= 5


def test_confidences_rank_the_candidates(box_obs):
    cands = _detect(box_obs)
    c = cands.confidences
    assert np.all((c >= 0.0) & (c <= 1.0)) and np.all(np.diff(c) <= 0.0)
    assert np.all(np.isnan(cands.reprojection_errors)) and cands.keypoints is None
    for score in ("confidence_minus_error", "paper_literal"):  # NaN errors count as 0: the selector keeps our order
        s = score_candidates(c, cands.reprojection_errors, SelectorConfig(score=score))
        assert np.array_equal(np.argsort(-s, kind="stable"), np.arange(len(c)))


def test_stick_grasps_close_across_it_near_its_middle(stick_obs):
    cands = _detect(stick_obs)
    assert len(cands) >= 5
    world = cands.world_poses(stick_obs.camera_pose)
    axis = STICK_POSE[:3, 2]
    centre = STICK_POSE[:3, 3]
    top = slice(0, 5)
    assert np.all(np.abs(world[top, :3, 2] @ axis) < np.cos(np.deg2rad(60.0)))  # across, not along the stick
    assert np.all(cands.widths[top] >= 2 * STICK.r_in) and np.all(cands.widths[top] <= 2 * STICK.r_in + 0.03)
    along = (world[top, :3, 3] - centre) @ axis
    assert np.all(np.abs(along) < STICK.h / 2 - 0.01)
    radial = world[top, :3, 3] - centre - along[:, None] * axis
    assert np.all(np.linalg.norm(radial, axis=1) < 0.012)


def test_seeded(box_obs):
    det = AntipodalDetector()
    det.reset([0, 3])
    a = det.detect(box_obs)
    det.reset([0, 3])
    b = det.detect(box_obs)
    det.reset([0, 4])
    c = det.detect(box_obs)
    for name in ("poses", "widths", "confidences"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert len(a) != len(c) or not np.allclose(a.poses, c.poses)


def test_nothing_on_the_table_gives_no_candidates():
    depth = _table_depth(CAMERA)
    assert depth.min() > 0
    obs = Observation(np.zeros((H, W, 3), np.uint8), depth, REALSENSE, CAMERA)
    cands = _detect(obs)
    assert isinstance(cands, Candidates) and len(cands) == 0
    # a few scattered returns above the table are not enough to grasp
    depth = depth.copy()
    depth[::97, ::89] *= 0.95
    assert len(_detect(Observation(obs.rgb, depth, REALSENSE, CAMERA))) == 0


def test_bad_depth_is_rejected(box_obs):
    depth = box_obs.depth.copy()
    depth[100, 200] = np.nan
    with pytest.raises(DetectorError, match="NaN"):
        _detect(Observation(box_obs.rgb, depth, REALSENSE, CAMERA))
    with pytest.raises(DetectorError, match="empty"):
        _detect(Observation(box_obs.rgb, np.zeros((H, W), np.float32), REALSENSE, CAMERA))


def test_normals_of_tilted_planes_face_the_camera_and_do_not_mix_across_a_step():
    K = REALSENSE.K
    n_true = np.array([0.3, -0.2, -1.0])
    n_true /= np.linalg.norm(n_true)
    u, v = np.meshgrid(np.arange(64), np.arange(48))
    rays = np.stack([(u - 32) / K[0, 0], (v - 24) / K[1, 1], np.ones(u.shape)], axis=-1)
    # two parallel planes n·p = n·(0, 0, z0): the left 20 columns 0.2 m further away (a depth step)
    z0 = np.where(u < 20, 1.0, 0.8)
    depth = z0 * n_true[2] / (rays @ n_true)
    Kc = K.copy()
    Kc[0, 2], Kc[1, 2] = 32, 24
    pts = backproject(depth, Kc)
    n, ok = estimate_normals(pts, depth > 0)
    assert ok[:, 1:-1].all() and ok[:, [18, 19, 20, 21]].all()  # pixels at the step keep a normal
    np.testing.assert_allclose(n[ok], np.broadcast_to(n_true, n[ok].shape), atol=1e-6)
    assert np.all(np.sum(n[ok] * pts[ok], axis=1) < 0)  # towards the camera
    # a pixel with no valid neighbour on one axis has none
    lone = depth > 0
    lone[:, 40] = False
    lone[10, 42] = False  # pixel (10, 41): both horizontal neighbours missing
    _, ok2 = estimate_normals(pts, lone)
    assert not ok2[10, 41] and ok2[11, 41] and not ok2[:, 40].any()
    # nor does a one-pixel sliver standing 0.2 m off the surface on both sides
    sliver = depth.copy()
    sliver[:, 50] += 0.2
    _, ok3 = estimate_normals(backproject(sliver, Kc), sliver > 0)
    assert not ok3[:, 50].any() and ok3[:, 49].all() and ok3[:, 51].all()


def test_lowest_box_z_matches_the_swept_box_corners():
    rng = np.random.default_rng(5)
    q = rng.normal(size=(50, 4))
    R = np.stack([matrix_from_quat_wxyz(x) for x in q])
    oz = rng.uniform(0.0, 0.2, 50)
    w_open = rng.uniform(0.02, GRIPPER.max_width, 50)
    poses = np.tile(np.eye(4), (50, 1, 1))
    poses[:, :3, :3], poses[:, 2, 3] = R, oz
    want = np.empty(50)
    for k in range(50):
        boxes = [GRIPPER.finger_box(1, w_open[k]), GRIPPER.finger_box(-1, w_open[k]), GRIPPER.palm_box(),
                 GRIPPER.wrist_box()]
        back = np.array([0.05, 0.0, 0.0])  # half of the 0.1 m pre-grasp sweep
        swept = [GripperBox(b.name, b.centre - back, b.half + back) for b in boxes]
        want[k] = min(box_corners(b, poses[k:k + 1])[0, :, 2].min() for b in swept)
    np.testing.assert_allclose(_lowest_box_z(oz, R, w_open, 0.1), want, atol=1e-12)


def test_extent_stops_at_gaps_a_finger_fits_into():
    gap = GRIPPER.finger_thickness + 0.005
    near = np.array([-0.012, -0.006, 0.0, 0.004, 0.009])
    rows = [
        [0.009 + gap + 0.004, 0.05],  # a finger fits after 9 mm: stop there
        [0.009 + gap - 0.004, 0.05],  # too narrow a gap: carry on to the next one
        [-0.3, 0.3],  # out of reach: ignored
        list(np.arange(0.01, GRIPPER.max_width + 0.02, 0.002)),  # no gap up to the end of the range and on
    ]
    n = max(len(r) for r in rows)
    c = np.stack([np.concatenate([near, r, np.zeros(n - len(r))]) for r in rows])  # padding at the seed (0)
    lo, hi = _extent(c, np.ones(c.shape, dtype=bool), GRIPPER.max_width)
    np.testing.assert_allclose(lo[:3], -0.012)
    np.testing.assert_allclose(hi[:3], [0.009, 0.009 + gap - 0.004, 0.009])
    assert np.isnan(lo[3]) and np.isnan(hi[3])
