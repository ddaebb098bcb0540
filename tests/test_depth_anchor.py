"""The observed distance along an image point's ray (the depth anchor of the scale head)."""

import numpy as np

from kgn_bench.camera import REALSENSE
from kgn_bench.model.depth_anchor import depth_at, observed_distance

K = REALSENSE.K


def test_observed_distance_is_the_euclidean_distance_of_the_seen_point():
    """A fronto-parallel plane at z = 0.8 m: the ray through (u, v) meets it at ‖K⁻¹[u, v, 1]‖ · 0.8."""
    depth = np.full((REALSENSE.height, REALSENSE.width), 0.8, dtype=np.float32)
    uv = np.array([[REALSENSE.K[0, 2], REALSENSE.K[1, 2]], [0.0, 0.0], [639.0, 479.0]])
    d = observed_distance(depth, uv, K)
    assert abs(d[0] - 0.8) < 1e-6  # the principal point: distance = depth
    point = np.linalg.inv(K) @ np.array([639.0, 479.0, 1.0]) * 0.8
    assert abs(d[2] - np.linalg.norm(point)) < 1e-6
    assert np.all(d[1:] > 0.8 + 0.1)  # the corners see the plane further away


def test_holes_and_non_finite_points_give_nan():
    depth = np.zeros((REALSENSE.height, REALSENSE.width), dtype=np.float32)
    depth[100, 100] = 0.7
    d = observed_distance(depth, np.array([[101.0, 102.0], [300.0, 300.0], [np.nan, 5.0]]), K)
    assert np.isfinite(d[0]) and np.isnan(d[1]) and np.isnan(d[2])
    assert depth_at(depth, np.array([[101.0, 102.0]]))[0] == np.float32(0.7)
    assert observed_distance(depth, np.zeros((0, 2)), K).shape == (0,)
