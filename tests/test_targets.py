import numpy as np
import pytest

from kgn_bench.camera import REALSENSE
from kgn_bench.geometry import make_pose, matrix_from_quat_wxyz, rot_x, rot_y, rot_z
from kgn_bench.grasp import flip_180
from kgn_bench.model.targets import (
    MAX_GRASPS,
    NUM_BINS,
    apply_affine,
    assign_grasps,
    encode_targets,
    invert_affine,
    orientation_bins,
    project_keypoints,
    render_heatmap,
    targets_to_maps,
)
from kgn_bench.model.variants import BOX_SIDE, get_variant

K = REALSENSE.K
M_HALF = np.array([[0.125, 0.0, 0.0], [0.0, 0.125, 0.0]])  # input scale 0.5, stride 4: 640×480 → 80×60
OUT_HALF = (60, 80)
Z = 128.0 / 448.0  # a 448 px square crop centred at (330, 250) warped to 128², then mirrored
M_FLIP = np.array([[-Z, 0.0, 127.0 - 64.0 + 330.0 * Z], [0.0, Z, 64.0 - 250.0 * Z]])
OUT_CROP = (128, 128)
FIXED = get_variant("kgn")
SNORM = get_variant("kgnv2")


def random_poses(rng, n, dist=(0.5, 1.2)):
    """Grasps with uniformly random orientations whose origins lie in the central part of the image."""
    uv = np.stack([rng.uniform(100, 540, n), rng.uniform(80, 400, n), np.ones(n)], axis=1)
    ray = uv @ np.linalg.inv(K).T
    t = ray / np.linalg.norm(ray, axis=1, keepdims=True) * rng.uniform(*dist, n)[:, None]
    return np.stack([make_pose(matrix_from_quat_wxyz(q), ti) for q, ti in zip(rng.normal(size=(n, 4)), t)])


def test_orientation_bins_match_the_reference_examples():
    left = np.zeros((6, 2))
    right = np.array([[1.0, 0.0], [1.0, 1.0], [1.0, -1.0], [0.0, 1.0], [0.0, -1.0], [1.0, np.tan(np.radians(-10))]])
    # image y points down: +45° goes right-down
    np.testing.assert_array_equal(orientation_bins(left, right), [4, 6, 2, 8, 0, 4])
    # angles beyond ±90° clamp to the end bins
    np.testing.assert_array_equal(orientation_bins(left[:2], [[-1.0, 1.0], [-1.0, -1.0]]), [8, 0])


def test_affine_inverse_and_validation():
    pts = np.array([[10.0, 20.0], [300.0, 400.0]])
    np.testing.assert_allclose(apply_affine(invert_affine(M_FLIP), apply_affine(M_FLIP, pts)), pts, atol=1e-9)
    with pytest.raises(ValueError, match="singular"):
        invert_affine(np.zeros((2, 3)))
    with pytest.raises(ValueError, match="2×3"):
        invert_affine(np.eye(3))


def test_project_keypoints_box_geometry_and_behind_camera():
    T = make_pose(np.eye(3), [0.0, 0.0, 1.0])  # approach along camera x, closing along camera z
    T2 = make_pose(rot_y(np.pi / 2), [0.0, 0.0, 1.0])  # grasp z → camera x: L to the right of R
    kp, ct = project_keypoints(np.stack([T, T2, make_pose(t=[0, 0, -1.0])]), K, np.full(3, BOX_SIDE))
    np.testing.assert_allclose(ct[0], K[:2, 2])
    np.testing.assert_allclose(kp[1, 0], [K[0, 2] + K[0, 0] * 0.05, K[1, 2]])
    np.testing.assert_allclose(kp[1, 1], [K[0, 2] - K[0, 0] * 0.05, K[1, 2]])
    assert np.all(np.isnan(kp[2])) and np.all(np.isnan(ct[2]))


def test_heatmap_is_a_clipped_3x3_gaussian_combined_by_max():
    hm = render_heatmap(np.array([[5, 4], [6, 4], [0, 0]]), np.array([3, 3, 7]), (10, 12))
    assert hm.shape == (NUM_BINS, 10, 12) and hm.dtype == np.float32
    e2, e4 = np.float32(np.exp(-2.0)), np.float32(np.exp(-4.0))
    np.testing.assert_array_equal(hm[3, 3:6, 4:8], [[e4, e2, e2, e4], [e2, 1, 1, e2], [e4, e2, e2, e4]])
    assert np.count_nonzero(hm[3]) == 12
    np.testing.assert_array_equal(hm[7, :2, :2], [[1, e2], [e2, e4]])  # clipped at the corner
    assert np.count_nonzero(hm[7]) == 4 and np.count_nonzero(hm) == 16


def test_a_wider_heatmap_gaussian_keeps_its_peak_and_follows_centernets_sigma():
    """Radius 2: 5×5 cells, σ = 5/6; its half-maximum contour spans about the image pixels of radius 1 at
    twice the stride."""
    hm = render_heatmap(np.array([[5, 5]]), np.array([0]), (11, 11), radius=2)
    sigma = 5.0 / 6.0
    assert np.count_nonzero(hm) == 25 and hm[0, 5, 5] == 1.0
    assert hm[0, 5, 7] == np.float32(np.exp(-4.0 / (2.0 * sigma**2))) and hm[0, 5, 8] == 0.0
    assert np.array_equal(render_heatmap(np.array([[5, 5]]), np.array([0]), (11, 11), radius=1),
                          render_heatmap(np.array([[5, 5]]), np.array([0]), (11, 11)))
    with pytest.raises(ValueError, match="at least 1"):
        render_heatmap(np.array([[5, 5]]), np.array([0]), (11, 11), radius=0)


def test_targets_of_one_grasp():
    T = make_pose(rot_x(0.3) @ rot_y(-np.pi / 2), [0.02, -0.01, 0.8])
    t = encode_targets(T[None], np.array([0.05]), K, M_HALF, OUT_HALF, FIXED)
    kp, ct = project_keypoints(T[None], K, np.array([BOX_SIDE]))
    kp_o, ct_o = apply_affine(M_HALF, kp[0]), apply_affine(M_HALF, ct[0])
    if kp_o[0, 0] > kp_o[1, 0]:
        kp_o = kp_o[[1, 0, 3, 2]]
    cell = np.floor(ct_o).astype(int)
    assert t["mask"].shape == (MAX_GRASPS,) and t["mask"].sum() == 1
    assert t["ind"][0] == cell[1] * OUT_HALF[1] + cell[0]
    assert t["bin"][0] == orientation_bins(kp_o[None, 0], kp_o[None, 1])[0]
    assert t["hm"][t["bin"][0], cell[1], cell[0]] == 1.0 and t["hm"].max() == 1.0
    np.testing.assert_allclose(t["reg"][0], ct_o - cell, atol=1e-6)
    np.testing.assert_allclose(t["kpts"][0], (kp_o - cell).reshape(8), atol=1e-5)
    np.testing.assert_allclose([t["width"][0], t["scale"][0]], [0.05, np.linalg.norm(T[:3, 3])], rtol=1e-6)
    assert {k: v.dtype for k, v in t.items()} == {
        "hm": np.float32, "ind": np.int64, "mask": np.float32, "bin": np.int64,
        "reg": np.float32, "kpts": np.float32, "width": np.float32, "scale": np.float32,
    }  # fmt: skip


def test_canonicalisation_is_the_projection_of_the_turned_pose():
    rng = np.random.default_rng(3)
    poses = random_poses(rng, 40, dist=(0.9, 1.2))
    for M, shape in ((M_HALF, OUT_HALF), (M_FLIP, OUT_CROP)):
        for variant in (FIXED, SNORM):
            a = assign_grasps(poses, np.full(40, 0.04), K, M, shape, variant)
            assert 0 < a.flipped.sum() < len(a)
            src = poses[a.indices]
            np.testing.assert_allclose(a.poses, np.where(a.flipped[:, None, None], flip_180(src), src))
            kp, ct = project_keypoints(a.poses, K, variant.box_sides(np.linalg.norm(src[:, :3, 3], axis=1)))
            np.testing.assert_allclose(a.keypoints, apply_affine(M, kp), atol=1e-9)
            np.testing.assert_allclose(a.centres, apply_affine(M, ct), atol=1e-9)
            assert np.all(a.keypoints[:, 0, 0] <= a.keypoints[:, 1, 0])
    # a horizontal flip of the map re-canonicalises: each grasp is turned in exactly one of the two maps
    M_mirror = np.array([[-0.125, 0.0, 79.0], [0.0, 0.125, 0.0]])
    a1 = assign_grasps(poses, np.full(40, 0.04), K, M_HALF, OUT_HALF, FIXED)
    a2 = assign_grasps(poses, np.full(40, 0.04), K, M_mirror, OUT_HALF, FIXED)
    common, i1, i2 = np.intersect1d(a1.indices, a2.indices, return_indices=True)
    assert len(common) > 10 and np.all(a1.flipped[i1] != a2.flipped[i2])


def test_duplicates_first_wins_and_slot_limit():
    T = make_pose(rot_y(-np.pi / 2), [0.0, 0.0, 0.8])
    T_near = T.copy()
    T_near[0, 3] += 0.001  # same output cell and bin
    T_other_bin = make_pose(rot_z(np.pi / 4) @ rot_y(-np.pi / 2), [0.0, 0.0, 0.8])  # same cell, +45°: bin 6
    poses = np.stack([T, T_near, T_other_bin])
    a = assign_grasps(poses, np.array([0.01, 0.02, 0.03]), K, M_HALF, OUT_HALF, FIXED)
    np.testing.assert_array_equal(a.indices, [0, 2])
    np.testing.assert_array_equal(a.cells[0], a.cells[1])
    assert a.bins[0] == 4 and a.bins[1] == 6 and a.widths[0] == 0.01

    rng = np.random.default_rng(0)
    many = random_poses(rng, 1200, dist=(0.9, 1.2))
    a = assign_grasps(many, np.full(1200, 0.04), K, M_FLIP, OUT_CROP, FIXED)
    t = encode_targets(many, np.full(1200, 0.04), K, M_FLIP, OUT_CROP, FIXED)
    assert len(a) == MAX_GRASPS and t["mask"].sum() == MAX_GRASPS and np.all(np.diff(a.indices) > 0)
    # grasps without a slot draw nothing
    assert np.count_nonzero(t["hm"] == 1.0) == MAX_GRASPS


def test_out_of_map_and_behind_camera_grasps_are_dropped():
    inside = make_pose(rot_y(-np.pi / 2), [0.0, 0.0, 0.8])
    # the origin projects inside but TL/TR (0.1 m behind along the approach) leave the left image border
    u = 20.0
    edge = make_pose(np.eye(3), [(u - K[0, 2]) / K[0, 0] * 0.8, 0.0, 0.8])
    behind = make_pose(rot_y(-np.pi / 2), [0.0, 0.0, -0.8])
    straddling = make_pose(rot_y(-np.pi / 2), [0.0, 0.0, 0.05])  # TL/TR behind the camera plane
    poses = np.stack([edge, inside, behind, straddling])
    a = assign_grasps(poses, np.full(4, 0.04), K, M_HALF, OUT_HALF, FIXED)
    np.testing.assert_array_equal(a.indices, [1])
    empty = encode_targets(poses[2:], np.full(2, 0.04), K, M_HALF, OUT_HALF, FIXED)
    assert empty["mask"].sum() == 0 and not empty["hm"].any()
    none = encode_targets(np.zeros((0, 4, 4)), np.zeros(0), K, M_HALF, OUT_HALF, SNORM)
    assert none["hm"].shape == (NUM_BINS, *OUT_HALF) and none["mask"].sum() == 0


def test_scale_normalised_box_keeps_the_image_size():
    near = make_pose(rot_y(-np.pi / 2), [0.0, 0.0, 0.5])
    far = make_pose(rot_y(-np.pi / 2), [0.1, 0.0, 1.0])
    a = assign_grasps(np.stack([near, far]), np.full(2, 0.04), K, M_HALF, OUT_HALF, SNORM)
    span = a.keypoints[:, 1, 0] - a.keypoints[:, 0, 0]
    # a = ‖t‖ · BOX_SIDE, at depth t_z: the span is fx · BOX_SIDE · ‖t‖ / t_z in image px
    np.testing.assert_allclose(span, K[0, 0] * BOX_SIDE * np.array([1.0, np.hypot(0.1, 1.0)]) / 8.0)
    np.testing.assert_allclose(a.sides, [0.05, 0.1 * np.hypot(0.1, 1.0)])


def test_targets_to_maps_writes_the_bin_channels_at_the_cells():
    rng = np.random.default_rng(5)
    poses = random_poses(rng, 30)
    widths = rng.uniform(0.01, 0.08, 30)
    t = encode_targets(poses, widths, K, M_HALF, OUT_HALF, SNORM)
    maps = targets_to_maps(t, SNORM)
    assert set(maps) == {"hm", "reg", "kpts", "width", "scale"}
    assert set(targets_to_maps(t, FIXED)) == {"hm", "reg", "kpts", "width"}
    assert maps["kpts"].shape == (72, *OUT_HALF) and all(m.dtype == np.float32 for m in maps.values())
    for k in np.flatnonzero(t["mask"]):
        y, x, c = t["ind"][k] // 80, t["ind"][k] % 80, t["bin"][k]
        np.testing.assert_array_equal(maps["kpts"][8 * c : 8 * c + 8, y, x], t["kpts"][k])
        assert maps["width"][c, y, x] == t["width"][k] and maps["scale"][c, y, x] == t["scale"][k]
    assert np.count_nonzero(maps["width"]) == t["mask"].sum()


def test_bad_inputs_raise_value_errors():
    T = make_pose(t=[0, 0, 1.0])[None]
    with pytest.raises(ValueError, match="poses"):
        encode_targets(T[0], np.ones(1), K, M_HALF, OUT_HALF, FIXED)
    with pytest.raises(ValueError, match="widths"):
        encode_targets(T, np.ones(2), K, M_HALF, OUT_HALF, FIXED)
    with pytest.raises(ValueError, match="finite"):
        encode_targets(T * np.nan, np.ones(1), K, M_HALF, OUT_HALF, FIXED)
    with pytest.raises(ValueError, match="K"):
        encode_targets(T, np.ones(1), K[:2], M_HALF, OUT_HALF, FIXED)
    with pytest.raises(ValueError, match="out_shape"):
        encode_targets(T, np.ones(1), K, M_HALF, (60, 0), FIXED)
    with pytest.raises(ValueError, match="affine"):
        encode_targets(T, np.ones(1), K, M_HALF[:, :2], OUT_HALF, FIXED)
    with pytest.raises(ValueError, match="hm"):
        targets_to_maps({"hm": np.zeros((3, 4, 4))}, FIXED)


def test_frontal_assignment_keeps_the_grasp_approached_from_the_camera():
    """Two grasps share a centre and an image orientation; "first" keeps the one listed first, "frontal"
    the one whose approach axis is closer to the viewing ray, whatever the input order."""
    t = np.array([0.05, 0.02, 0.8])
    ray = t / np.linalg.norm(t)
    z = np.cross(ray, [0.0, 1.0, 0.0])  # the closing axis of both, in the image plane
    z /= np.linalg.norm(z)
    def frame(x):  # right-handed (x, z × x, z)
        return make_pose(np.stack([x, np.cross(z, x), z], axis=1), t)
    front = frame(ray)  # approached along the viewing ray
    side = frame(np.cross(z, ray))  # approached at right angles to it
    poses = np.stack([side, front])
    cos = np.einsum("ni,i->n", poses[:, :3, 0], ray)
    assert cos[1] > 0.99 and abs(cos[0]) < 0.01
    first = assign_grasps(poses, np.full(2, 0.04), K, M_HALF, OUT_HALF, SNORM, "first")
    frontal = assign_grasps(poses, np.full(2, 0.04), K, M_HALF, OUT_HALF, SNORM, "frontal")
    assert len(first) == len(frontal) == 1  # same cell, same bin: one target
    assert first.indices.tolist() == [0] and frontal.indices.tolist() == [1]
    swapped = assign_grasps(poses[::-1], np.full(2, 0.04), K, M_HALF, OUT_HALF, SNORM, "frontal")
    assert swapped.indices.tolist() == [0]
    with pytest.raises(ValueError, match="unknown assignment"):
        assign_grasps(poses, np.full(2, 0.04), K, M_HALF, OUT_HALF, SNORM, "random")
