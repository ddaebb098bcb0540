import dataclasses
import time

import cv2
import numpy as np
import pytest

from kgn_bench.camera import REALSENSE
from kgn_bench.geometry import make_pose, matrix_from_quat_wxyz, rot_x, rot_y, rot_z, rotation_angle
from kgn_bench.grasp import keypoint_box
from kgn_bench.model.decode import DecodeConfig, decode, depth_at, solve_box_pnp
from kgn_bench.model.targets import (
    MAX_GRASPS,
    NUM_BINS,
    apply_affine,
    assign_grasps,
    encode_targets,
    project_keypoints,
    targets_to_maps,
)
from kgn_bench.model.variants import BOX_SIDE, VARIANTS, get_variant
from kgn_bench.shapes import TRAIN_DENSITY, Cuboid, Cylinder

K = REALSENSE.K
M_HALF = np.array([[0.125, 0.0, 0.0], [0.0, 0.125, 0.0]])  # input scale 0.5, stride 4: 640×480 → 80×60
OUT_HALF = (60, 80)
Z = 128.0 / 448.0  # a 448 px square crop centred at (330, 250) warped to 128², then mirrored
M_FLIP = np.array([[-Z, 0.0, 127.0 - 64.0 + 330.0 * Z], [0.0, Z, 64.0 - 250.0 * Z]])
OUT_CROP = (128, 128)
ALL = DecodeConfig(top_k=MAX_GRASPS)


def random_poses(rng, n, dist=(0.5, 1.2)):
    """Grasps with uniformly random orientations whose origins lie in the central part of the image."""
    uv = np.stack([rng.uniform(100, 540, n), rng.uniform(80, 400, n), np.ones(n)], axis=1)
    ray = uv @ np.linalg.inv(K).T
    t = ray / np.linalg.norm(ray, axis=1, keepdims=True) * rng.uniform(*dist, n)[:, None]
    return np.stack([make_pose(matrix_from_quat_wxyz(q), ti) for q, ti in zip(rng.normal(size=(n, 4)), t)])


def spaced(poses, min_px=16.0):
    """The first grasps, in order, whose image centres are ≥ ``min_px`` apart (Chebyshev)."""
    _, ct = project_keypoints(poses, K, np.full(len(poses), BOX_SIDE))
    kept = []
    for i in range(len(poses)):
        if all(np.max(np.abs(ct[i] - ct[j])) >= min_px for j in kept):
            kept.append(i)
    return poses[kept]


def depth_for(poses):
    """A depth image that is 0 except at rint(centre) of each grasp, where it is the grasp origin's planar z."""
    depth = np.zeros((REALSENSE.height, REALSENSE.width), dtype=np.float32)
    _, ct = project_keypoints(poses, K, np.full(len(poses), BOX_SIDE))
    uv = np.rint(ct).astype(int)
    ok = (uv[:, 0] >= 0) & (uv[:, 0] < REALSENSE.width) & (uv[:, 1] >= 0) & (uv[:, 1] < REALSENSE.height)
    depth[uv[ok, 1], uv[ok, 0]] = poses[ok, 2, 3]
    return depth


def round_trip(poses, widths, M, out_shape, variant, depth=None):
    """Encode ground truth, decode the target maps; assert every kept grasp comes back (canonical pose)."""
    kept = assign_grasps(poses, widths, K, M, out_shape, variant)
    targets = encode_targets(poses, widths, K, M, out_shape, variant, depth)
    cands = decode(targets_to_maps(targets, variant), K, M, variant, ALL, depth=depth)
    assert len(kept) > 0 and len(cands) == len(kept)
    kp_img = apply_affine(np.linalg.inv(np.vstack([M, [0, 0, 1]]))[:2], kept.keypoints)
    dist = np.abs(cands.keypoints[:, None] - kp_img[None]).max(axis=(2, 3))
    match = dist.argmin(axis=0)  # candidate of each kept grasp, found by its image keypoints
    assert len(set(match)) == len(kept) and dist[match, np.arange(len(kept))].max() < 1e-3
    got = cands.poses[match]
    t_err = np.linalg.norm(got[:, :3, 3] - kept.poses[:, :3, 3], axis=1)
    r_err = np.degrees(rotation_angle(got[:, :3, :3], kept.poses[:, :3, :3]))
    assert t_err.max() < 1e-3, f"{variant.name}: translation error {t_err.max():.2e} m"
    assert r_err.max() < 0.5, f"{variant.name}: rotation error {r_err.max():.3f}°"
    np.testing.assert_allclose(cands.widths[match], kept.widths, atol=1e-6)
    np.testing.assert_array_equal(cands.confidences, 1.0)
    assert np.all(cands.reprojection_errors < 1e-2)
    return len(kept)


@pytest.mark.parametrize("name", ["kgnv2", "kgnv2_sbranch", "kgn"])
def test_round_trip_random_poses(name):
    variant = get_variant(name)
    rng = np.random.default_rng(11)
    poses = random_poses(rng, 150)
    widths = rng.uniform(0.01, 0.08, 150)
    assert round_trip(poses, widths, M_HALF, OUT_HALF, variant) > 60
    assert round_trip(poses, widths, M_FLIP, OUT_CROP, variant) > 60


def test_round_trip_at_output_stride_two():
    """The finer maps of a stride-2 network (``M`` doubled) encode and decode the same poses."""
    variant = get_variant("kgnv2")
    rng = np.random.default_rng(13)
    poses = random_poses(rng, 150)
    widths = rng.uniform(0.01, 0.08, 150)
    assert round_trip(poses, widths, 2.0 * M_HALF, (120, 160), variant) > 100


def test_round_trip_depth_variant():
    variant = get_variant("kgn_depth")
    rng = np.random.default_rng(12)
    poses = spaced(random_poses(rng, 60))
    depth = depth_for(poses)
    widths = rng.uniform(0.01, 0.08, len(poses))
    assert round_trip(poses, widths, M_HALF, OUT_HALF, variant, depth) > 10
    assert round_trip(poses, widths, M_FLIP, OUT_CROP, variant, depth) > 10


def tilted_plane(z0=0.7, slope=0.0001):
    """A depth image of a plane tilted along v: z = z0 + slope · (v − 240) metres, holes at every 7th column."""
    v = np.arange(REALSENSE.height, dtype=np.float32)[:, None]
    depth = np.repeat(z0 + slope * (v - 240.0), REALSENSE.width, axis=1).astype(np.float32)
    depth[:, ::7] = 0.0
    return depth


@pytest.mark.parametrize("name", ["kgnv2", "kgnv2_sbranch"])
def test_round_trip_depth_anchored_scale(name):
    """A perfect residual map plus the observed distance at the decoded centre gives back ‖t‖ exactly,
    whatever the scene's depth: the anchor is read at the same pixel in encoding and decoding."""
    variant = get_variant(name).with_scale_anchor("depth")
    assert variant.needs_depth and not get_variant(name).needs_depth
    rng = np.random.default_rng(14)
    poses = random_poses(rng, 150)
    widths = rng.uniform(0.01, 0.08, 150)
    depth = tilted_plane()
    assert round_trip(poses, widths, M_HALF, OUT_HALF, variant, depth) > 60
    assert round_trip(poses, widths, M_FLIP, OUT_CROP, variant, depth) > 60
    with pytest.raises(ValueError, match="needs the depth"):
        encode_targets(poses, widths, K, M_HALF, OUT_HALF, variant)
    with pytest.raises(ValueError, match="needs the depth"):
        decode(targets_to_maps(encode_targets(poses, widths, K, M_HALF, OUT_HALF, variant, depth), variant),
               K, M_HALF, variant)


def test_depth_anchored_scale_residual_and_holes():
    """The scale target is ‖t‖ − z̃·‖K⁻¹[u, v, 1]‖ at the grasp centre; without valid depth near the centre
    the target is 0 and the decoder drops the detection."""
    variant = get_variant("kgnv2").with_scale_anchor("depth")
    T = make_pose(rot_x(-0.8) @ rot_y(-np.pi / 2), [0.02, 0.01, 0.8])
    _, ct = project_keypoints(T[None], K, np.full(1, BOX_SIDE))
    depth = np.full((REALSENSE.height, REALSENSE.width), 0.77, dtype=np.float32)
    t = encode_targets(T[None], np.array([0.04]), K, M_HALF, OUT_HALF, variant, depth)
    ray = np.linalg.inv(K) @ np.array([*np.rint(ct[0]), 1.0])
    expected = np.linalg.norm(T[:3, 3]) - 0.77 * np.linalg.norm(ray)
    assert t["mask"][0] == 1.0 and t["scale"][0] == pytest.approx(expected, abs=2e-5)
    assert 0.02 < expected < 0.04  # the origin lies a few cm behind the surface along the ray
    holes = np.zeros_like(depth)
    t0 = encode_targets(T[None], np.array([0.04]), K, M_HALF, OUT_HALF, variant, holes)
    assert t0["mask"][0] == 1.0 and t0["scale"][0] == 0.0
    assert len(decode(targets_to_maps(t, variant), K, M_HALF, variant, depth=depth)) == 1
    assert len(decode(targets_to_maps(t, variant), K, M_HALF, variant, depth=holes)) == 0


def test_scale_anchor_needs_a_scale_branch():
    with pytest.raises(ValueError, match="needs the scale branch"):
        dataclasses.replace(get_variant("kgn"), scale_anchor="depth")
    with pytest.raises(ValueError, match="unknown scale_anchor"):
        dataclasses.replace(get_variant("kgnv2"), scale_anchor="sonar")
    assert get_variant("kgn").with_scale_anchor("depth") == get_variant("kgn")


@pytest.mark.parametrize("shape", [Cuboid((0.06, 0.09, 0.05)), Cylinder(0.04, 0.08)])
def test_round_trip_shape_grasp_families(shape):
    rng = np.random.default_rng(13)
    grasps = shape.grasps(TRAIN_DENSITY)
    for _ in range(2):
        T_cam_obj = make_pose(matrix_from_quat_wxyz(rng.normal(size=4)), [rng.uniform(-0.1, 0.1), 0.02, 0.7])
        poses = T_cam_obj @ grasps.poses
        for name in ("kgnv2", "kgnv2_sbranch", "kgn"):
            for M, out in ((M_HALF, OUT_HALF), (M_FLIP, OUT_CROP)):
                round_trip(poses, grasps.widths, M, out, VARIANTS[name])
        sparse = spaced(poses)
        round_trip(sparse, np.full(len(sparse), 0.05), M_HALF, OUT_HALF, VARIANTS["kgn_depth"], depth_for(sparse))


def one_grasp_maps(variant, T=None, M=M_HALF, out=OUT_HALF):
    # approach tilted away from the camera, L→R horizontal in the image (bin 4)
    T = make_pose(rot_x(-0.8) @ rot_y(-np.pi / 2), [0.02, 0.01, 0.8]) if T is None else T
    return targets_to_maps(encode_targets(T[None], np.array([0.04]), K, M, out, variant), variant)


def test_top_k_threshold_and_order():
    variant = get_variant("kgnv2")
    maps = one_grasp_maps(variant)
    assert len(decode(maps, K, M_HALF, variant)) == 1  # the e^-2 neighbours are below 0.3
    # the e^-2 neighbours pass 0.1, but their keypoints (all offsets 0) coincide and PnP fails on them
    assert len(decode(maps, K, M_HALF, variant, DecodeConfig(score_threshold=0.1))) == 1
    rng = np.random.default_rng(2)
    poses = random_poses(rng, 40)
    maps = targets_to_maps(encode_targets(poses, np.full(40, 0.03), K, M_HALF, OUT_HALF, variant), variant)
    peaks = np.argwhere(maps["hm"] == 1.0)
    maps["hm"][tuple(peaks.T)] = np.linspace(0.99, 0.4, len(peaks), dtype=np.float32)
    c = decode(maps, K, M_HALF, variant, DecodeConfig(top_k=5))
    np.testing.assert_allclose(c.confidences, np.linspace(0.99, 0.4, len(peaks))[:5], rtol=1e-6)
    c = decode(maps, K, M_HALF, variant, DecodeConfig(score_threshold=0.7))
    assert len(c) > 0 and np.all(c.confidences >= 0.7) and np.all(np.diff(c.confidences) < 0)
    maps["hm"][:] = 0.2
    empty = decode(maps, K, M_HALF, variant)
    assert len(empty) == 0 and empty.poses.shape == (0, 4, 4)


def test_orientation_filter_drops_inconsistent_detections():
    variant = get_variant("kgn")
    maps = one_grasp_maps(variant)
    c, y, x = np.argwhere(maps["hm"] == 1.0)[0]
    assert c == 4
    # rotate the predicted box by 30° in the image: its L→R vector now says bin 5 or 6, not 4
    off = maps["kpts"][8 * c : 8 * c + 8, y, x].reshape(4, 2)
    centre = off[:2].mean(axis=0)
    R = np.array([[np.cos(0.52), -np.sin(0.52)], [np.sin(0.52), np.cos(0.52)]], dtype=np.float32)
    maps["kpts"][8 * c : 8 * c + 8, y, x] = ((off - centre) @ R.T + centre).reshape(8)
    assert len(decode(maps, K, M_HALF, variant)) == 0
    kept = decode(maps, K, M_HALF, variant, DecodeConfig(orientation_filter=False))
    assert len(kept) == 1 and np.all(np.isfinite(kept.poses))


def test_pnp_solutions_behind_the_camera_or_degenerate_are_rejected():
    # a configuration for which OpenCV's best IPPE solution has t_z < 0
    pts = np.array([[300.0, 240.0], [340.0, 240.0], [300.0, 200.0], [360.0, 260.0]])
    n, _, tvecs, _ = cv2.solvePnPGeneric(keypoint_box(BOX_SIDE), pts, K, np.zeros(4), flags=cv2.SOLVEPNP_IPPE)
    assert n >= 1 and np.all(np.isfinite(tvecs[0])) and tvecs[0][2, 0] < 0
    assert solve_box_pnp(pts, K) is None
    crossed = np.array([[300.0, 240.0], [340.0, 240.0], [340.0, 280.0], [300.0, 280.0]])  # NaN from OpenCV
    assert solve_box_pnp(crossed, K) is None
    assert solve_box_pnp(np.full((4, 2), 320.0), K) is None

    # the same points as a detection: dropped by decode
    variant = get_variant("kgn")
    maps = one_grasp_maps(variant)
    c, y, x = np.argwhere(maps["hm"] == 1.0)[0]
    cell = np.array([x, y], dtype=float)
    maps["kpts"][8 * c : 8 * c + 8, y, x] = (apply_affine(M_HALF, pts) - cell).reshape(8)
    assert len(decode(maps, K, M_HALF, variant)) == 0


def test_solve_box_pnp_recovers_a_pose_and_scales_with_the_box():
    T = make_pose(rot_z(0.4) @ rot_y(2.0), [0.05, -0.03, 0.9])
    kp, _ = project_keypoints(T[None], K, np.array([BOX_SIDE]))
    pose, err = solve_box_pnp(kp[0], K)
    np.testing.assert_allclose(pose, T, atol=1e-7)
    assert err < 1e-6
    half, _ = solve_box_pnp(kp[0], K, side=BOX_SIDE / 2)
    np.testing.assert_allclose(half[:3, 3], T[:3, 3] / 2, atol=1e-7)
    np.testing.assert_allclose(half[:3, :3], T[:3, :3], atol=1e-7)


def test_scale_and_depth_set_the_distance():
    T = make_pose(rot_z(0.3) @ rot_y(-2.0), [0.1, 0.05, 0.8])
    v2 = get_variant("kgnv2_sbranch")
    maps = one_grasp_maps(v2, T)
    maps["scale"] *= 1.5  # a wrong predicted distance moves the grasp along its ray
    c = decode(maps, K, M_HALF, v2)
    np.testing.assert_allclose(c.poses[0, :3, 3], 1.5 * T[:3, 3], rtol=1e-5)
    maps["scale"][:] = 0.0
    assert len(decode(maps, K, M_HALF, v2)) == 0  # ŝ ≤ 0

    vd = get_variant("kgn_depth")
    maps = one_grasp_maps(vd, T)
    depth = depth_for(T[None])
    c = decode(maps, K, M_HALF, vd, depth=depth * 1.25)
    np.testing.assert_allclose(c.poses[0, :3, 3], 1.25 * T[:3, 3], rtol=1e-5)
    assert len(decode(maps, K, M_HALF, vd, depth=np.zeros_like(depth))) == 0  # no valid depth
    assert len(decode(maps, K, M_HALF, get_variant("kgn"), depth=np.zeros_like(depth))) == 1  # depth unused


def test_depth_at_window_median_and_clamping():
    depth = np.zeros((10, 12), dtype=np.float32)
    depth[0, 0], depth[1, 1], depth[2, 2], depth[0, 3] = 1.0, 2.0, 4.0, np.nan
    uv = np.array([[-5.0, -7.0], [1.2, 0.6], [11.0, 9.0], [3.0, 0.0]])
    np.testing.assert_allclose(depth_at(depth, uv), [2.0, 2.0, np.nan, 3.0])


def test_bad_inputs_raise_value_errors():
    v2 = get_variant("kgnv2")
    maps = one_grasp_maps(v2)
    missing = {k: v for k, v in maps.items() if k != "scale"}
    with pytest.raises(ValueError, match="lack scale"):
        decode(missing, K, M_HALF, v2)
    decode(missing, K, M_HALF, get_variant("kgn"))  # the scale map is needed only by "scale" variants
    with pytest.raises(ValueError, match="hm must be"):
        decode({**maps, "hm": maps["hm"][:8]}, K, M_HALF, v2)
    with pytest.raises(ValueError, match="kpts must be"):
        decode({**maps, "kpts": maps["kpts"][None]}, K, M_HALF, v2)
    bad = maps["width"].copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError, match="width must be finite"):
        decode({**maps, "width": bad}, K, M_HALF, v2)
    with pytest.raises(ValueError, match="depth image"):
        decode(maps, K, M_HALF, get_variant("kgn_depth"))
    with pytest.raises(ValueError, match="depth must be"):
        decode(maps, K, M_HALF, get_variant("kgn_depth"), depth=np.zeros(5))
    with pytest.raises(ValueError, match="singular"):
        decode(maps, K, np.zeros((2, 3)), v2)
    with pytest.raises(ValueError, match="K must be"):
        decode(maps, np.eye(2), M_HALF, v2)
    with pytest.raises(ValueError, match="top_k"):
        DecodeConfig(top_k=0)
    with pytest.raises(ValueError, match="score_threshold"):
        DecodeConfig(score_threshold=1.5)


def test_decoding_100_detections_is_fast():
    variant = get_variant("kgnv2")
    rng = np.random.default_rng(4)
    poses = random_poses(rng, 400, dist=(0.8, 1.2))
    maps = targets_to_maps(encode_targets(poses, np.full(400, 0.04), K, M_FLIP, OUT_CROP, variant), variant)
    assert np.count_nonzero(maps["hm"] == 1.0) >= 100
    decode(maps, K, M_FLIP, variant)
    start = time.perf_counter()
    for _ in range(5):
        c = decode(maps, K, M_FLIP, variant)
    assert len(c) == 100 and maps["hm"].shape[0] == NUM_BINS
    assert (time.perf_counter() - start) / 5 < 0.1  # ~5 ms on the development machine; loose for shared CPUs
