"""Grasp selection on a synthetic observed point cloud: a 4 cm box (5 cm tall) at the table centre, the table
around it, and a second box at the far edge of the table, out of the arm's reach. Real mink IK."""

from dataclasses import replace

import numpy as np
import pytest

from kgn_bench.bench.selector import (
    REJECTIONS,
    DepthView,
    centre_offset,
    level_poses,
    near_failed,
    score_candidates,
    search_offsets,
    select_grasp,
)
from kgn_bench.config import ExecutionConfig, SelectorConfig
from kgn_bench.geometry import make_pose, rot_y, rot_z
from kgn_bench.gripper import GRIPPER
from kgn_bench.sim.control import IK
from kgn_bench.sim.robot import READY_Q

HEIGHT = 0.05
FAR = np.array([0.38, 0.30])  # the second box: 0.98 m from the arm base, inside the workspace
EXEC = ExecutionConfig()
CFG = SelectorConfig(approach_search=0.0, closing_search=0.0, centre_range=0.0, level_deg=0.0, palm_margin=0.0,
                     reprojection_weight=0.02)  # every check at the candidate's own pose, the bare boxes
SEARCH = SelectorConfig()  # the default: shifted poses are tried too
# top-down grasp frame: approach x = world −z, closing z = world +y, y = z × x = world −x
DOWN = np.stack([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], axis=1)


def _grid(x0, x1, y0, y1, step):
    X, Y = np.meshgrid(np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step))
    return np.stack([X.ravel(), Y.ravel()], axis=1)


def _box_top(cx, cy):
    xy = _grid(cx - 0.02, cx + 0.02, cy - 0.02, cy + 0.02, 0.002)
    return np.c_[xy, np.full(len(xy), HEIGHT)]


@pytest.fixture(scope="module")
def points():
    table = _grid(-0.45, 0.45, -0.45, 0.45, 0.01)
    free = np.all(np.abs(table) > 0.021, axis=1) & np.any(np.abs(table - FAR) > 0.021, axis=1)
    table = np.c_[table[free], np.zeros(free.sum())]
    return np.concatenate([_box_top(0.0, 0.0), _box_top(*FAR), table])


@pytest.fixture(scope="module")
def ik():
    return IK()


def _pose(xyz, yaw=0.0):
    return make_pose(rot_z(yaw) @ DOWN, xyz)


def _select(poses, widths, points, ik, conf=None, errors=None, cfg=CFG):
    n = len(poses)
    conf = np.linspace(1.0, 0.5, n) if conf is None else np.asarray(conf, dtype=float)
    errors = np.full(n, np.nan) if errors is None else np.asarray(errors, dtype=float)
    return select_grasp(np.stack(poses), np.asarray(widths, dtype=float), conf, errors, points, ik, cfg, EXEC)


def test_down_frame_is_a_rotation():
    assert np.linalg.det(DOWN) == pytest.approx(1.0)
    np.testing.assert_allclose(np.cross(DOWN[:, 2], DOWN[:, 0]), DOWN[:, 1])


@pytest.mark.parametrize(
    "pose, width, rejection",
    [
        (_pose((0.0, 0.0, 0.02)), 0.25, "width"),  # wider than the jaws open
        (_pose((0.0, 0.0, 0.02)), 0.0, "width"),
        (_pose((0.0, 0.0, 0.02)), 0.02, "collision"),  # fingers would pass through the box top
        (_pose((0.0, 0.0, 0.02), np.pi / 2), 0.025, "collision"),  # same, closing along x
        (_pose((0.0, 0.05, 0.02)), 0.06, "collision"),  # a finger lands on the box top (y = 0.005 ... 0.015)
        (_pose((0.25, 0.2, 0.02)), 0.06, "enclosure"),  # empty space above the table
        (_pose((0.0, 0.0, 0.12)), 0.06, "enclosure"),  # above the box: fingertips do not reach it
        (_pose((0.25, -0.2, -0.015)), 0.06, "collision"),  # under the table top
        (_pose((0.25, -0.2, -0.03)), 0.06, "workspace"),  # further under it: not over the table
        (_pose((-0.6, 0.0, 0.1)), 0.06, "workspace"),  # beyond the table's edge (the pedestal, the parked arm)
        (_pose((0.0, 0.0, 0.45)), 0.06, "workspace"),  # high above it
        (_pose((*FAR, 0.02)), 0.06, "ik"),  # a fine grasp the arm cannot reach
    ],
)
def test_each_check_rejects_and_counts(points, ik, pose, width, rejection):
    sel = _select([pose], [width], points, ik)
    assert sel.index is None and sel.grasp is None and sel.q_grasp is None
    assert sel.rejected == {name: int(name == rejection) for name in REJECTIONS}
    assert sel.reason == ("unreachable" if rejection == "ik" else "no_candidate")


def test_good_top_down_grasp_is_selected(points, ik):
    sel = _select([_pose((0.0, 0.0, 0.02))], [0.06], points, ik)
    assert sel.index == 0 and sel.reason is None
    assert sel.width == pytest.approx(0.07)  # opened 1 cm wider than the candidate
    g = sel.grasp
    # the same grasp up to the 180° flip, pushed grasp_depth further along the approach (down)
    np.testing.assert_allclose(g[:3, 0], [0.0, 0.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(np.abs(g[:3, 2]), [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(g[:3, 3], [0.0, 0.0, 0.02 - EXEC.grasp_depth], atol=1e-12)
    # of the two symmetric forms, the one whose closing axis is nearer the ready wrist's
    assert g[:3, 2] @ ik.tcp_pose(READY_Q)[:3, 2] > 0
    np.testing.assert_allclose(sel.pregrasp[:3, :3], g[:3, :3])
    np.testing.assert_allclose(sel.pregrasp[:3, 3], g[:3, 3] + [0.0, 0.0, EXEC.pregrasp_distance], atol=1e-12)
    lo, hi = ik.index.arm_limits.T
    for q, T in ((sel.q_pregrasp, sel.pregrasp), (sel.q_grasp, g)):
        assert np.all(q >= lo) and np.all(q <= hi)
        reached = ik.tcp_pose(q)
        assert np.linalg.norm(reached[:3, 3] - T[:3, 3]) < 1e-3
        assert reached[:3, 0] @ T[:3, 0] > np.cos(np.deg2rad(1.0))


def test_grasp_depth_stops_above_the_table(points, ik):
    sel = _select([_pose((0.0, 0.0, 0.008))], [0.06], points, ik)
    assert sel.index == 0
    assert sel.grasp[2, 3] == pytest.approx(CFG.table_clearance)  # pushed only 5 mm, not 10


def test_rejections_accumulate_until_a_feasible_candidate(points, ik):
    poses = [
        _pose((0.0, 0.0, 0.02)),  # width
        _pose((0.0, 0.0, 0.02)),  # collision
        _pose((0.25, 0.2, 0.02)),  # enclosure
        _pose((0.0, 0.0, -0.015)),  # collision (table)
        _pose((*FAR, 0.02)),  # ik
        _pose((0.0, 0.0, 0.02), np.pi / 2),  # good
        _pose((0.0, 0.0, 0.02)),  # good too, but ranked last
    ]
    widths = [0.3, 0.02, 0.06, 0.06, 0.06, 0.06, 0.06]
    sel = _select(poses, widths, points, ik)
    assert sel.index == 5
    assert sel.rejected == {"workspace": 0, "repeat": 0, "width": 1, "collision": 2, "occluded": 0, "enclosure": 1,
                            "ik": 1}
    np.testing.assert_allclose(np.abs(sel.grasp[:3, 2]), [1.0, 0.0, 0.0], atol=1e-12)
    # max_candidates cuts the list: the good ones are never looked at
    cut = _select(poses, widths, points, ik, cfg=replace(CFG, max_candidates=5))
    assert cut.index is None and sum(cut.rejected.values()) == 5 and cut.reason == "unreachable"


def test_score_formulas():
    c = np.array([0.9, 0.5, 0.2])
    re = np.array([10.0, np.nan, 0.0])
    np.testing.assert_allclose(score_candidates(c, re, CFG), [0.9 - 0.2, 0.5, 0.2])
    np.testing.assert_allclose(score_candidates(c, re, replace(CFG, score="paper_literal")), [10.9, 0.5, 0.2])
    np.testing.assert_allclose(score_candidates(c, re, replace(CFG, reprojection_weight=0.0)), c)


def test_score_order_decides_between_feasible_grasps(points, ik):
    """Two feasible grasps; the reprojection error flips which one each score picks."""
    poses = [_pose((0.0, 0.0, 0.02)), _pose((0.0, 0.0, 0.02), np.pi / 2)]
    conf, errors = [0.5, 0.6], [0.0, 20.0]
    default = _select(poses, [0.06, 0.06], points, ik, conf, errors)
    np.testing.assert_allclose(default.scores, [0.5, 0.6 - 0.02 * 20.0])
    assert default.index == 0
    literal = _select(poses, [0.06, 0.06], points, ik, conf, errors, cfg=replace(CFG, score="paper_literal"))
    np.testing.assert_allclose(literal.scores, [0.5, 20.6])
    assert literal.index == 1
    # without errors the confidence alone decides
    assert _select(poses, [0.06, 0.06], points, ik, conf).index == 1
    assert sum(default.rejected.values()) == sum(literal.rejected.values()) == 0


def test_widths_up_to_the_maximum_opening_pass(points, ik):
    sel = _select([_pose((0.0, 0.0, 0.02))], [GRIPPER.max_width], points, ik)
    assert sel.rejected["width"] == 0
    assert sel.width == pytest.approx(GRIPPER.max_width)  # capped, not max_width + 1 cm


def test_a_grasp_that_failed_is_not_tried_again(points, ik):
    good, twin, other = _pose((0.0, 0.0, 0.02)), _pose((0.0, 0.0, 0.02), np.pi), _pose((0.0, 0.0, 0.02), np.pi / 2)
    first = _select([good, other], [0.06, 0.06], points, ik)
    assert first.index == 0
    failed = first.grasp[None]  # as executed: flipped form possible, pushed grasp_depth down
    n = 3
    sel = select_grasp(np.stack([good, twin, other]), np.full(n, 0.06), np.linspace(1.0, 0.5, n), np.full(n, np.nan),
                       points, ik, CFG, EXEC, failed)
    # the same grasp and its 180° twin are skipped; the grasp turned 90° is a different grasp
    assert sel.index == 2 and sel.rejected["repeat"] == 2
    # with the memory switched off, the failed grasp is chosen again
    off = replace(CFG, retry_distance=0.0)
    again = select_grasp(np.stack([good, twin, other]), np.full(n, 0.06), np.linspace(1.0, 0.5, n),
                         np.full(n, np.nan), points, ik, off, EXEC, failed)
    assert again.index == 0 and again.rejected["repeat"] == 0


def test_near_failed_compares_translation_and_rotation():
    base = _pose((0.0, 0.0, 0.02))
    shifted = _pose((0.0, 0.025, 0.02))
    tilted = _pose((0.0, 0.0, 0.02), np.deg2rad(35.0))
    close = _pose((0.005, 0.0, 0.02), np.deg2rad(10.0))
    got = near_failed(np.stack([base, shifted, tilted, close]), base[None], 0.02, np.deg2rad(30.0))
    assert got.tolist() == [True, False, False, True]
    assert near_failed(np.stack([base]), np.zeros((0, 4, 4)), 0.02, 1.0).tolist() == [False]


# a camera 1 m above the table centre looking straight down (OpenCV axes: x = world x, y = world −y)
DOWN_CAM = np.array([[1.0, 0, 0, 0], [0, -1.0, 0, 0], [0, 0, -1.0, 1.0], [0, 0, 0, 1.0]])
K = np.array([[500.0, 0, 320.0], [0, 500.0, 240.0], [0, 0, 1.0]])


def test_depth_view_hidden_points():
    depth = np.full((480, 640), 0.6, np.float32)  # a surface at world z = 0.4 everywhere
    depth[:, :100] = 0.0  # no return on the left strip
    view = DepthView(depth, K, DOWN_CAM)
    pts = np.array([
        [0.0, 0.0, 0.30],  # 0.7 m from the camera, 0.1 m behind the surface: hidden
        [0.0, 0.0, 0.395],  # 5 mm behind: within the margin
        [0.0, 0.0, 0.50],  # in front of the surface
        [-0.5, 0.0, 0.30],  # projects onto the no-return strip
        [3.0, 0.0, 0.30],  # outside the image
        [0.0, 0.0, 1.50],  # behind the camera
    ])
    assert view.hidden(pts, 0.01).tolist() == [True, False, False, False, False, False]


def test_palm_in_unseen_space_is_rejected(points, ik):
    good = _pose((0.0, 0.0, 0.02))
    n = 1
    args = (np.stack([good]), np.full(n, 0.06), np.ones(n), np.full(n, np.nan), points, ik, CFG, EXEC, None)
    assert select_grasp(*args, None).index == 0
    # the same grasp when the camera saw a surface 10 cm above the table: everything below it is unseen
    hidden = DepthView(np.full((480, 640), 0.9, np.float32), K, DOWN_CAM)
    sel = select_grasp(*args, hidden)
    assert sel.index is None and sel.rejected["occluded"] == 1
    # a surface at the table top hides nothing the gripper occupies
    seen = DepthView(np.full((480, 640), 1.0, np.float32), K, DOWN_CAM)
    assert select_grasp(*args, seen).index == 0


def test_search_offsets_are_a_grid_nearest_first():
    off = search_offsets(SEARCH)
    assert len(off) == 13 * 5 and tuple(off[0]) == (0.0, 0.0)
    norms = np.hypot(off[:, 0], off[:, 1])
    assert np.all(np.diff(norms) >= -1e-12)
    assert np.abs(off[:, 0]).max() == pytest.approx(0.03) and np.abs(off[:, 1]).max() == pytest.approx(0.01)
    assert len(search_offsets(CFG)) == 1
    assert len(search_offsets(replace(SEARCH, closing_search=0.0))) == 13


def test_a_grasp_too_deep_or_off_centre_is_shifted_to_a_feasible_pose(points, ik):
    # 2 cm too far along the approach: the fingertips would enter the table (a scale error of a detector)
    deep = _pose((0.0, 0.0, -0.02))
    assert _select([deep], [0.06], points, ik).rejected["collision"] == 1
    sel = _select([deep], [0.06], points, ik, cfg=SEARCH)
    assert sel.index == 0 and sel.rejected["collision"] == 0
    # moved back up along −x by the smallest feasible step (2.5 cm), then down to the fingertips' clearance
    assert sel.grasp[2, 3] == pytest.approx(SEARCH.table_clearance, abs=1e-9)
    np.testing.assert_allclose(sel.grasp[:3, 0], deep[:3, 0])  # same approach (either 180° form)
    # 1 cm off-centre along the closing axis with a tight opening: a finger lands on the box top
    side = _pose((0.0, 0.012, 0.02))
    assert _select([side], [0.045], points, ik).rejected["collision"] == 1
    sel = _select([side], [0.045], points, ik, cfg=SEARCH)
    assert sel.index == 0 and abs(sel.grasp[1, 3]) < 0.012 - 0.004
    # nothing to shift onto: empty space stays rejected, and is counted once
    empty = _pose((0.25, 0.2, 0.02))
    sel = _select([empty], [0.06], points, ik, cfg=SEARCH)
    assert sel.index is None and sel.rejected["enclosure"] == 1 and sum(sel.rejected.values()) == 1


def test_centre_offset_centres_the_points_between_the_jaws():
    # points of a 4 cm object spanning z ∈ [0.005, 0.045] in the grasp frame, 3 cm below the fingertips
    z = np.linspace(0.005, 0.045, 9)
    local = np.c_[np.full(9, -0.03), np.zeros(9), z]
    side, along = np.array([0.0, 1.0, 0.0]), np.array([1.0, 0.0, 0.0])  # closing axis ⟂ / ∥ to the ray
    assert centre_offset(local, 0.10, side, along, 0.03, 5) == pytest.approx(0.025)
    assert centre_offset(local, 0.10, side, along, 0.01, 5) == pytest.approx(0.01)  # clipped
    assert centre_offset(local, 0.10, along, along, 0.03, 5) == 0.0  # only the near face is seen
    assert centre_offset(local, 0.10, side, along, 0.03, 10) == 0.0  # too few points
    assert centre_offset(local, 0.06, side, along, 0.03, 5) == pytest.approx((0.005 + 0.025) / 2)  # inside jaws only


def test_an_off_centre_grasp_is_centred_on_the_box(points, ik):
    # 1.2 cm off-centre across a 4 cm box with a wide opening: feasible as it is, but one finger would hit first
    side = _pose((0.0, 0.012, 0.02))
    seen = DepthView(np.full((480, 640), 1.0, np.float32), K, DOWN_CAM)
    args = (np.stack([side]), np.array([0.08]), np.ones(1), np.full(1, np.nan), points, ik)
    plain = select_grasp(*args, CFG, EXEC, None, seen)
    assert plain.grasp[1, 3] == pytest.approx(0.012)
    centred = select_grasp(*args, replace(CFG, centre_range=0.02), EXEC, None, seen)
    assert abs(centred.grasp[1, 3]) < 0.002
    assert select_grasp(*args, replace(CFG, centre_range=0.005), EXEC, None, seen).grasp[1, 3] == pytest.approx(0.007)


def test_centring_onto_unseen_space_needs_the_object_seen_whole(points, ik):
    # 1.2 cm off-centre across the 4 cm box; the camera saw a surface 8 cm above the table beyond world y ≈ 3 cm,
    # so the +z (left) finger that the centring moves inwards would stand in unseen space
    side = _pose((0.0, 0.012, 0.02))
    depth = np.full((480, 640), 1.0, np.float32)
    depth[:225] = 0.92
    blind = DepthView(depth, K, DOWN_CAM)
    seen = DepthView(np.full((480, 640), 1.0, np.float32), K, DOWN_CAM)
    cfg = replace(CFG, centre_range=0.02)

    def centred_y(width, view):
        args = (np.stack([side]), np.array([width]), np.ones(1), np.full(1, np.nan), points, ik)
        return select_grasp(*args, cfg, EXEC, None, view).grasp[1, 3]

    # a 15 cm grasp that sees 4 cm between its jaws may be seeing one wall of a wider object: not centred
    # into the blind space, centred where that space was seen free
    assert centred_y(0.15, blind) == pytest.approx(0.012)
    assert abs(centred_y(0.15, seen)) < 0.002
    # a 6 cm grasp sees the whole of what it expects: centred although the finger goes into the object's shadow
    assert abs(centred_y(0.06, blind)) < 0.002


def test_level_poses_makes_near_top_down_closing_axes_horizontal():
    tilt = make_pose(DOWN, (0.0, 0.0, 0.02))
    # tip the grasp 8° about its own y axis: the closing axis rises, the approach leans
    b = np.deg2rad(8.0)
    x, z = DOWN[:, 0], DOWN[:, 2]
    tilt[:3, 0], tilt[:3, 2] = np.cos(b) * x + np.sin(b) * z, -np.sin(b) * x + np.cos(b) * z
    side = make_pose(np.stack([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]], axis=1), (0.0, 0.0, 0.02))  # approach +x
    out = level_poses(np.stack([tilt, side]), 30.0)
    np.testing.assert_allclose(out[0][:3, :3], DOWN, atol=1e-12)  # back to straight down, closing horizontal
    np.testing.assert_allclose(out[0][:3, 3], tilt[:3, 3])
    np.testing.assert_allclose(out[1], side)  # not near top-down: unchanged
    assert np.allclose(level_poses(tilt[None], 5.0)[0], tilt)  # 8° + leaning approach is outside a 5° cone
    R = out[0][:3, :3]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)


def test_palm_margin_keeps_the_palm_off_points_just_beside_it(points, ik):
    # nine points 5 mm beside the palm's face (world x = −0.03 is grasp y = +0.03; palm half breadth 0.025),
    # at the palm's height above the box: clear of the palm itself, inside it grown by 1 cm
    post = np.array([[-0.03, y, z] for y in (-0.01, 0.0, 0.01) for z in (0.09, 0.10, 0.11)])
    cloud = np.concatenate([points, post])
    grasp = [_pose((0.0, 0.0, 0.02))]
    assert _select(grasp, [0.06], cloud, ik).index == 0
    sel = _select(grasp, [0.06], cloud, ik, cfg=replace(CFG, palm_margin=0.01))
    assert sel.index is None and sel.rejected["collision"] == 1


def test_a_failed_grasp_that_was_shifted_is_not_tried_again(points, ik):
    # too deep by 2 cm: executed 2.5 cm up the approach from the candidate, beyond retry_distance of it
    deep = _pose((0.0, 0.0, -0.02))
    first = _select([deep], [0.06], points, ik, cfg=SEARCH)
    assert np.linalg.norm(first.grasp[:3, 3] - deep[:3, 3]) > SEARCH.retry_distance
    np.testing.assert_allclose(first.candidate, deep)
    assert first.tried.shape == (2, 4, 4)
    # remembering the executed pose alone would let the same candidate through again; with the candidate too
    # it is skipped
    only_executed = select_grasp(deep[None], np.array([0.06]), np.ones(1), np.full(1, np.nan), points, ik, SEARCH,
                                 EXEC, first.grasp[None])
    assert only_executed.index == 0
    again = select_grasp(deep[None], np.array([0.06]), np.ones(1), np.full(1, np.nan), points, ik, SEARCH, EXEC,
                         first.tried)
    assert again.index is None and again.rejected["repeat"] == 1
    assert _select([_pose((0.3, 0.3, 0.02))], [0.06], points, ik).tried.shape == (0, 4, 4)  # nothing selected


def test_a_grasp_pulled_back_to_clear_the_palm_must_still_bite(points, ik):
    # a shelf of points beside the box at a height the palm (bottom face at tip + finger_length) reaches
    # when the grasp is pushed grasp_depth down: only pulling the grasp back clears it
    def shelf_at(z):
        return np.concatenate([points, [[x, y, z] for x in (-0.01, 0.0, 0.01) for y in (0.06, 0.07, 0.08)]])

    grasp = [_pose((0.0, 0.0, 0.03))]
    tip = 0.03 - EXEC.grasp_depth
    cfg = replace(SEARCH, palm_margin=0.0, centre_range=0.0)
    assert _select(grasp, [0.06], points, ik, cfg=cfg).grasp[2, 3] == pytest.approx(tip)  # no shelf: as meant
    # 5 mm above the palm's bottom: pulled back 5 mm, the fingertips still 2.5 cm down the 5 cm box
    low = shelf_at(tip + GRIPPER.finger_length + 0.005)
    assert _select(grasp, [0.06], low, ik, cfg=replace(cfg, approach_search=0.0)).index is None
    sel = _select(grasp, [0.06], low, ik, cfg=cfg)
    assert sel.index == 0 and sel.grasp[2, 3] == pytest.approx(tip + 0.005)
    # 2.2 cm above it: clearing it takes the fingertips to 5 mm below the box top, less than min_bite
    high = shelf_at(tip + GRIPPER.finger_length + 0.022)
    sel = _select(grasp, [0.06], high, ik, cfg=cfg)
    assert sel.index is None and sel.rejected["collision"] == 1
    sel = _select(grasp, [0.06], high, ik, cfg=replace(cfg, min_bite=0.0))
    assert sel.index == 0 and sel.grasp[2, 3] == pytest.approx(HEIGHT - 0.005)


def test_a_shallow_grasp_is_pushed_until_the_fingers_bite(points, ik):
    # aimed 7 mm above the box top: pushed grasp_depth down, the fingertips close 3 mm below it
    shallow = _pose((0.0, 0.0, HEIGHT + 0.007))
    bare = replace(CFG, min_bite=0.0)
    assert _select([shallow], [0.06], points, ik, cfg=bare).grasp[2, 3] == pytest.approx(HEIGHT - 0.003)
    sel = _select([shallow], [0.06], points, ik)
    assert sel.index is None and sel.rejected["enclosure"] == 1
    # the search pushes it down in 5 mm steps until the box top is at least min_bite above the fingertips
    sel = _select([shallow], [0.06], points, ik, cfg=SEARCH)
    assert sel.index == 0 and sel.grasp[2, 3] == pytest.approx(HEIGHT - 0.013)
    # a flat object cannot give a 1 cm bite: fingertips stopped by the table are enough (the cloud's table
    # points lie outside the closing region, the box top 5 mm up is all there is)
    flat = np.concatenate([points[:, :2], np.where(points[:, 2:] > 0, 0.005, 0.0)], axis=1)
    sel = _select([_pose((0.0, 0.0, 0.003))], [0.06], flat, ik)
    assert sel.index == 0 and sel.grasp[2, 3] == pytest.approx(CFG.table_clearance)


def test_non_rigid_or_non_finite_candidates_are_never_executed(points, ik):
    good = _pose((0.0, 0.0, 0.02))
    scaled = good.copy()
    scaled[:3, :3] *= 3.0  # not a rotation: would pass every geometric check it is put through
    nan = good.copy()
    nan[0, 3] = np.nan
    mirrored = good.copy()
    mirrored[:3, 2] *= -1.0  # det −1
    sel = _select([scaled, nan, mirrored], [0.06] * 3, points, ik, conf=[1.0, 1.0, 1.0])
    assert sel.index is None and sel.rejected["invalid_pose"] == 3 and sel.reason == "no_candidate"
    sel = _select([scaled, good], [0.06, 0.06], points, ik, conf=[1.0, 0.1])
    assert sel.index == 1 and sel.rejected["invalid_pose"] == 1
    sel = _select([good, good], [np.inf, 0.06], points, ik, conf=[1.0, np.nan])
    assert sel.index is None and sel.rejected["invalid_pose"] == 2
    assert "invalid_pose" not in _select([good], [0.06], points, ik).rejected  # records unchanged otherwise


def test_valid_candidates():
    from kgn_bench.bench.selector import valid_candidates

    poses = np.stack([np.eye(4)] * 3)
    poses[1, 3, 0] = 1.0  # bottom row not [0 0 0 1]
    poses[2, :3, :3] = rot_z(0.3) @ np.diag([1.0, 1.0, 1.0 + 1e-3])  # slightly scaled
    assert valid_candidates(poses, np.ones(3), np.ones(3)).tolist() == [True, False, False]
    assert valid_candidates(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0)).shape == (0,)


RAW = SelectorConfig(mode="raw")  # detector-only execution, whatever the refinement settings say


def test_raw_mode_executes_the_candidate_exactly_as_predicted(points, ik):
    """Raw mode: what passes is executed at the predicted pose (no grasp_depth push, no levelling), and what
    only the pose search, levelling or centring would repair is rejected where it is."""
    grasp = _pose((0.0, 0.0, 0.03))
    sel = _select([grasp], [0.06], points, ik, cfg=RAW)
    assert sel.index == 0  # executed at the candidate, pushed by the executor's grasp_depth as in every mode
    np.testing.assert_allclose(sel.grasp[:3, 3], grasp[:3, 3] - [0.0, 0.0, EXEC.grasp_depth], atol=1e-12)
    # too deep by 2 cm: the assisted search pulls it back, raw counts the collision
    deep = _pose((0.0, 0.0, -0.02))
    assert _select([deep], [0.06], points, ik, cfg=SEARCH).index == 0
    sel = _select([deep], [0.06], points, ik, cfg=RAW)
    assert sel.index is None and sel.rejected["collision"] == 1
    # 2 cm above the box top: the push leaves the fingertips 1 cm above it, enclosing nothing
    assert _select([_pose((0.0, 0.0, HEIGHT + 0.02))], [0.06], points, ik, cfg=RAW).rejected["enclosure"] == 1
    # aimed 7 mm above it: pushed to 3 mm into the top, no bite asked for (assisted pushes it to 1.3 cm)
    sel = _select([_pose((0.0, 0.0, HEIGHT + 0.007))], [0.06], points, ik, cfg=RAW)
    assert sel.index == 0 and sel.grasp[2, 3] == pytest.approx(HEIGHT - 0.003)
    # a tilted top-down grasp is not levelled
    tilted = grasp.copy()
    tilted[:3, :3] = grasp[:3, :3] @ rot_y(0.2)
    sel = _select([tilted], [0.06], points, ik, cfg=RAW)
    assert sel.index == 0
    assert abs(sel.grasp[2, 2]) == pytest.approx(abs(tilted[2, 2]), abs=1e-9) and abs(tilted[2, 2]) > 0.1
    assert SelectorConfig(mode="raw", approach_search=0.05).effective() == RAW.effective()


FLOATING = ExecutionConfig(hand="floating", gripper="panda")


def test_top_mode_executes_the_best_candidate_with_no_check_but_the_width(points, ik):
    """GIGA's evaluation: the best-scoring candidate, as predicted (a deep grasp that collides with the observed
    box included, a width beyond the hand's too: GIGA's hand opens fully for every grasp); no retry memory."""
    top = SelectorConfig(mode="top")
    deep = _pose((0.0, 0.0, -0.02))
    wide = _pose((0.0, 0.0, 0.03))
    sel = select_grasp(np.stack([wide, deep]), np.array([0.0, 0.06]), np.array([0.9, 0.8]), np.full(2, np.nan),
                       points, None, top, FLOATING)
    assert sel.index == 1 and sel.rejected["width"] == 1  # a zero width is no grasp
    assert select_grasp(np.stack([wide, deep]), np.array([0.09, 0.06]), np.array([0.9, 0.8]), np.full(2, np.nan),
                        points, None, top, FLOATING).index == 0  # 9 cm: the fully open 8 cm hand tries it
    np.testing.assert_allclose(sel.grasp, deep, atol=1e-12)  # no grasp_depth push, no shift
    np.testing.assert_allclose(sel.pregrasp[:3, 3], deep[:3, 3] + [0.0, 0.0, 0.05], atol=1e-12)
    assert sel.q_pregrasp is None and sel.q_grasp is None
    again = select_grasp(np.stack([deep]), np.array([0.06]), np.ones(1), np.full(1, np.nan), points, None, top,
                         FLOATING, failed=sel.tried)
    assert again.index == 0
    # the same deep grasp under the raw selector, still floating: the observed box stops it
    raw = select_grasp(np.stack([deep]), np.array([0.06]), np.ones(1), np.full(1, np.nan), points, None, RAW,
                       FLOATING)
    assert raw.index is None and raw.rejected["collision"] == 1


def test_the_selector_takes_ik_exactly_for_the_arm(points, ik):
    with pytest.raises(ValueError, match="IK"):
        select_grasp(np.stack([_pose((0.0, 0.0, 0.03))]), np.array([0.06]), np.ones(1), np.full(1, np.nan), points,
                     ik, CFG, FLOATING)
    with pytest.raises(ValueError, match="IK"):
        select_grasp(np.stack([_pose((0.0, 0.0, 0.03))]), np.array([0.06]), np.ones(1), np.full(1, np.nan), points,
                     None, CFG, EXEC)


def test_gigas_protocols_take_grasps_in_their_workspace_cube_only(points):
    from kgn_bench.bench.selector import GIGA_WORKSPACE, GraspSelector

    inside, outside = _pose((0.0, 0.0, 0.03)), _pose((-0.3, 0.14, 0.03))  # the table beyond the 30 cm cube
    selector = GraspSelector(SelectorConfig(mode="top"), FLOATING, None, GIGA_WORKSPACE)
    sel = selector.select(np.stack([outside, inside]), np.array([0.05, 0.05]), np.array([0.9, 0.8]),
                          np.full(2, np.nan), points)
    assert sel.index == 1 and sel.rejected["workspace"] == 1
    arm = GraspSelector(SelectorConfig(mode="top"), FLOATING, None)  # the arm's workspace reaches 40 cm out
    assert arm.select(np.stack([outside, inside]), np.array([0.05, 0.05]), np.array([0.9, 0.8]), np.full(2, np.nan),
                      points).index == 0
