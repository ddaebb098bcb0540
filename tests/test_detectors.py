"""The detector protocol: observation and candidate checks, the registry, the oracle against ground truth, and the
random detector's seeding — on a real rendered work-cell scene."""

import numpy as np
import pytest

from kgn_bench.camera import REALSENSE, orbit_pose
from kgn_bench.config import ExecutionConfig
from kgn_bench.detectors import DETECTORS, Candidates, Detector, DetectorError, Observation, make_detector
from kgn_bench.detectors.oracle import PINCH_MARGIN, TILT_DEG, OracleDetector, pinched_extent, tilted
from kgn_bench.detectors.random import RandomDetector
from kgn_bench.geometry import make_pose, rot_z
from kgn_bench.gripper import GRIPPER, PANDA_HAND, GripperBox, box_corners
from kgn_bench.shapes.base import EVAL_DENSITY
from kgn_bench.shapes.primitives import Cuboid, Sphere
from kgn_bench.sim.collision import proxy_hits_table
from kgn_bench.sim.control import IK, Executor
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.robot import BIN, PARK_Q, add_workcell, on_table
from kgn_bench.sim.scene import Scene, SceneObject

H, W = REALSENSE.height, REALSENSE.width
CAMERA = orbit_pose(0.8, np.deg2rad(60.0), np.deg2rad(90.0))  # the tasks' default camera
BOX = Cuboid((0.05, 0.06, 0.07))
BOX_POSE = make_pose(rot_z(0.4), (0.05, -0.03, 0.035))


def _valid(**changes):
    fields = dict(rgb=np.zeros((H, W, 3), np.uint8), depth=np.ones((H, W), np.float32), intrinsics=REALSENSE,
                  camera_pose=CAMERA)  # fmt: skip
    fields.update(changes)
    return Observation(**fields)


@pytest.fixture(scope="module")
def cell():
    """A cuboid on the table and a sphere already in the bin, the arm parked; one rendered observation."""
    objects = [
        SceneObject(BOX, (0.8, 0.2, 0.2), BOX_POSE),
        SceneObject(Sphere(0.03), (0.2, 0.8, 0.2), make_pose(t=(*BIN.centre, 0.03))),
    ]
    scene = Scene(objects, extend=add_workcell)
    Executor(scene, IK()).reset(PARK_Q)
    with SceneRenderer(scene) as r:
        view = r.render(CAMERA)
    return scene, Observation(view.rgb, view.depth, scene.intrinsics, CAMERA)


def test_a_valid_observation_passes(cell):
    _valid().validate()
    _, obs = cell
    obs.validate()
    assert obs.depth.dtype == np.float32 and np.count_nonzero(obs.depth) > 0.9 * H * W


@pytest.mark.parametrize(
    "changes, fragment",
    [
        (dict(rgb=np.zeros((H, W, 4), np.uint8)), "rgb must be"),
        (dict(rgb=np.zeros((H, W, 3), np.float32)), "rgb must be"),
        (dict(rgb=np.zeros((W, H, 3), np.uint8)), "rgb must be"),
        (dict(depth=np.ones((H, W, 1), np.float32)), "depth must be"),
        (dict(depth=np.ones((H, W), np.uint16)), "depth must be"),
        (dict(depth=np.ones((H - 1, W), np.float32)), "depth must be"),
        (dict(camera_pose=np.eye(3)), "camera_pose"),
        (dict(camera_pose=np.full((4, 4), np.inf)), "camera_pose"),
        (dict(depth=np.where(np.eye(H, W, dtype=bool), np.nan, 1.0).astype(np.float32)), "NaN"),
        (dict(depth=np.zeros((H, W), np.float32)), "empty"),
        (dict(depth=-np.ones((H, W), np.float32)), "empty"),
    ],
    ids=["rgb_channels", "rgb_dtype", "rgb_transposed", "depth_3d", "depth_int", "depth_rows", "pose_3x3",
         "pose_inf", "depth_nan", "depth_zero", "depth_negative"],
)  # fmt: skip
def test_validate_rejects_malformed_observations(changes, fragment):
    with pytest.raises(DetectorError, match=fragment):
        _valid(**changes).validate()


def test_candidates_shape_checks():
    n = 3
    poses = np.tile(np.eye(4), (n, 1, 1))
    ok = Candidates(poses, np.full(n, 0.05), np.ones(n), np.full(n, np.nan), np.zeros((n, 4, 2)))
    assert len(ok) == 3
    T = make_pose(rot_z(0.3), (1.0, 2.0, 3.0))
    np.testing.assert_allclose(ok.world_poses(T), np.tile(T, (n, 1, 1)))
    assert len(Candidates.empty()) == 0 and Candidates.empty().world_poses(T).shape == (0, 4, 4)
    bad = [
        dict(poses=np.zeros((n, 4, 3))),
        dict(poses=np.zeros((n, 3, 4))),
        dict(widths=np.zeros(n + 1)),
        dict(confidences=np.zeros((n, 1))),
        dict(reprojection_errors=np.zeros(n - 1)),
        dict(keypoints=np.zeros((n, 2, 4))),
    ]
    for change in bad:
        fields = dict(poses=poses, widths=np.zeros(n), confidences=np.zeros(n), reprojection_errors=np.zeros(n))
        fields.update(change)
        with pytest.raises(DetectorError, match="candidate"):
            Candidates(**fields)


def test_registry():
    assert set(DETECTORS) >= {"oracle", "random"}
    with pytest.raises(ValueError, match=r"unknown detector 'nope'; known: .*oracle.*random"):
        make_detector("nope")
    oracle, rand = make_detector("oracle"), make_detector("random")
    assert isinstance(oracle, OracleDetector) and oracle.privileged and oracle.name == "oracle"
    assert isinstance(rand, RandomDetector) and not rand.privileged and rand.name == "random"
    assert isinstance(oracle, Detector) and isinstance(rand, Detector)
    assert make_detector("oracle") is not oracle  # a fresh instance each time
    many = make_detector("kgn_bench.detectors.random:sample_and_filter")  # the selector with blind samples
    assert isinstance(many, RandomDetector) and many.count == 64 and many.name == "random64" and rand.count == 1


@pytest.mark.parametrize("name", sorted(DETECTORS))
def test_every_registered_detector_builds_from_what_ships(name):
    detector = make_detector(name)
    assert isinstance(detector, Detector) and detector.name == name


def test_oracle_needs_the_simulator(cell):
    _, obs = cell
    with pytest.raises(DetectorError, match="attach"):
        OracleDetector().detect(obs)


def test_oracle_returns_the_free_ground_truth_grasps(cell):
    scene, obs = cell
    assert on_table(scene, 0) and not on_table(scene, 1)  # the sphere in the bin is not a target
    oracle = OracleDetector()
    oracle.attach(scene)
    oracle.reset([0, 0])
    cands = oracle.detect(obs)
    world = cands.world_poses(obs.camera_pose)
    T = scene.object_pose(0)
    np.testing.assert_allclose(T, BOX_POSE, atol=1e-9)
    family = BOX.grasps(EVAL_DENSITY)
    gt = tilted(family, (0.0, np.deg2rad(TILT_DEG), -np.deg2rad(TILT_DEG))).transformed(T)
    # alone on the table, only the table can collide: with the proxy, or with the palm or wrist anywhere on
    # the straight approach from the pre-grasp (their boxes swept back by the pre-grasp distance)
    back = oracle.approach
    along = np.array([back / 2, 0.0, 0.0])
    swept = [GripperBox(b.name, b.centre - along, b.half + along)
             for b in (GRIPPER.palm_box(), GRIPPER.wrist_box())]
    body_low = np.any([box_corners(b, gt.poses)[..., 2].min(axis=1) < 0.0 for b in swept], axis=0)
    free = ~proxy_hits_table(gt.poses, gt.widths) & ~body_low
    assert body_low[~proxy_hits_table(gt.poses, gt.widths)].any()  # the body test removes grasps of its own
    assert 0 < len(cands) == free.sum() < len(gt) == 3 * len(family)
    # every candidate is one of the box's ground-truth grasps or their tilts (same pose and width), once each
    d = np.linalg.norm((world[:, None] - gt.poses[None]).reshape(len(world), len(gt), 16), axis=2)
    match = d.argmin(axis=1)
    assert np.all(d.min(axis=1) < 1e-9) and len(set(match.tolist())) == len(world)
    assert np.all(free[match])
    # the tilted copies keep the fingertip midpoint and the closing axis of their family grasp
    n = len(family)
    np.testing.assert_allclose(gt.poses[n:2 * n, :3, 3], gt.poses[:n, :3, 3], atol=1e-12)
    np.testing.assert_allclose(gt.poses[n:2 * n, :3, 2], gt.poses[:n, :3, 2], atol=1e-12)
    cos = np.einsum("ni,ni->n", gt.poses[n:2 * n, :3, 0], gt.poses[:n, :3, 0])
    np.testing.assert_allclose(cos, np.cos(np.deg2rad(TILT_DEG)), atol=1e-12)
    np.testing.assert_allclose(cands.widths, gt.widths[match])
    # positions on the box, none of the sphere's
    half_diagonal = np.linalg.norm(BOX.size) / 2.0
    assert np.all(np.linalg.norm(world[:, :3, 3] - T[:3, 3], axis=1) < half_diagonal)
    # confidence: top-down and central first; no reprojection error
    off = np.linalg.norm(world[:, :3, 3] - T[:3, 3], axis=1)
    np.testing.assert_allclose(cands.confidences, 0.5 * (1.0 - world[:, 2, 0]) - 2.0 * off)
    assert world[np.argmax(cands.confidences), 2, 0] == pytest.approx(-1.0)
    assert np.all(np.isnan(cands.reprojection_errors)) and cands.keypoints is None


def test_pinched_extent_measures_what_the_jaws_close_on():
    """A 5 × 6 × 7 cm box: jaws across x pinch 5 cm, across y 6 cm, also with only the pads' end on it; jaws
    above its top or beside it pinch nothing."""
    mesh = BOX.mesh()

    def frame(approach, closing, t):  # the grasp frame: x approach, z closing
        a, c = np.asarray(approach, float), np.asarray(closing, float)
        return make_pose(np.stack([a, np.cross(c, a), c], axis=1), t)

    poses = np.stack([frame((0, 0, -1), (1, 0, 0), (0, 0, 0.0)), frame((0, 0, -1), (0, 1, 0), (0, 0, 0.0)),
                      frame((0, 0, -1), (1, 0, 0), (0, 0, 0.02)),
                      frame((0, 0, -1), (1, 0, 0), (0, 0, 0.04)), frame((0, 0, -1), (1, 0, 0), (0.0, 0.2, 0.0))])
    extent = pinched_extent(mesh, poses, np.full(5, 0.08), finger_length=0.05)
    np.testing.assert_allclose(extent[:2], [0.05, 0.06], atol=1e-9)  # Cuboid((0.05, 0.06, 0.07))
    assert extent[2] == pytest.approx(0.05)  # fingertips 1.5 cm below the top (3.5 cm): the pads' end reaches it
    assert extent[3] == extent[4] == 0.0  # fingertips above the top; beside the box
    assert len(pinched_extent(mesh, np.zeros((0, 4, 4)), np.zeros(0), 0.05)) == 0
    assert pinched_extent(mesh, poses[4:], np.full(1, 0.08), 0.05)[0] == 0.0  # no ray hits at all


def test_oracle_takes_the_floating_hands_distances_gripper_and_held_floor():
    oracle = OracleDetector()
    arm = ExecutionConfig()
    oracle.configure(arm)
    assert (oracle.approach, oracle.depth, oracle.gripper, oracle.min_pinch, oracle.fingers_open) == (
        arm.pregrasp_distance, arm.grasp_depth, GRIPPER, 0.0, None)
    oracle.configure(ExecutionConfig(hand="floating", gripper="panda"))
    assert (oracle.approach, oracle.depth, oracle.gripper, oracle.fingers_open) == (0.05, 0.0, PANDA_HAND, 0.08)
    assert oracle.min_pinch == pytest.approx(0.008 + PINCH_MARGIN)


def test_oracle_sees_nothing_when_the_table_is_empty(cell):
    _, obs = cell
    lifted = Scene([SceneObject(BOX, (1, 0, 0), make_pose(t=(0.0, 0.0, 0.8)))])  # held high above the table
    oracle = OracleDetector()
    oracle.attach(lifted)
    assert len(oracle.detect(obs)) == 0


def test_random_detector_is_seeded(cell):
    _, obs = cell
    assert RandomDetector().count == 1  # the floor: one blind guess per attempt
    det = RandomDetector(count=16)
    det.reset([0, 1])
    a = det.detect(obs)
    b = det.detect(obs)  # the stream goes on
    det.reset([0, 1])
    a2 = det.detect(obs)
    det.reset([0, 2])
    c = det.detect(obs)
    assert len(a) == det.count
    np.testing.assert_array_equal(a.poses, a2.poses)
    np.testing.assert_array_equal(a.widths, a2.widths)
    np.testing.assert_array_equal(a.confidences, a2.confidences)
    assert not np.allclose(a.poses, b.poses) and not np.allclose(a.poses, c.poses)
    assert not np.allclose(a.widths, c.widths)


def test_random_detector_grasps_observed_points(cell):
    _, obs = cell
    det = RandomDetector(count=64)
    det.reset([3, 0])
    cands = det.detect(obs)
    world = cands.world_poses(obs.camera_pose)
    R = world[:, :3, :3]
    np.testing.assert_allclose(R.transpose(0, 2, 1) @ R, np.tile(np.eye(3), (len(R), 1, 1)), atol=1e-9)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-9)
    assert np.all(world[:, 2, 0] <= 0.0)  # approaching from above
    lo, hi = det.width_range
    assert np.all((cands.widths >= lo) & (cands.widths <= hi))
    assert np.all((cands.confidences >= 0) & (cands.confidences <= 1)) and np.all(np.isnan(cands.reprojection_errors))
    # each grasp sits `sink` behind an observed point above the table
    points = obs.points_world(stride=2)
    surface = world[:, :3, 3] - det.sink * world[:, :3, 0]
    nearest = np.min(np.linalg.norm(surface[:, None] - points[None], axis=2), axis=1)
    assert np.all(nearest < 1e-5) and np.all(surface[:, 2] > det.min_height)


def test_random_detector_on_a_bare_table_and_bad_input():
    down = orbit_pose(1.0, np.pi / 2, 0.0)  # straight down from 1 m: every pixel sees z = 0
    det = RandomDetector()
    det.reset([0, 0])
    assert len(det.detect(_valid(camera_pose=down))) == 0
    with pytest.raises(DetectorError):
        det.detect(_valid(depth=np.zeros((H, W), np.float32)))


def test_an_object_in_the_bin_near_the_table_edge_is_not_on_the_table():
    # the bin's inner side reaches under the table's footprint (|y| < 0.5): an object placed there is done
    x, y = BIN.centre[0], -0.49
    assert BIN.contains(np.array([x, y, 0.05]))
    scene = Scene([SceneObject(BOX, (1, 0, 0), make_pose(t=(x, y, 0.05))),
                   SceneObject(BOX, (1, 0, 0), make_pose(t=(x, -0.40, 0.05))),  # on the table beside the bin
                   SceneObject(BOX, (1, 0, 0), make_pose(t=(0.8, 0.0, 0.05)))])  # fallen off the table
    assert [on_table(scene, i) for i in range(3)] == [False, True, False]
