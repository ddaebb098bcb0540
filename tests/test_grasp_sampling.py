"""Antipodal candidates on meshes: the contacts, closing axes and widths on shapes whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from kgn_bench.geometry import frame_from_xz, make_pose, rot_x
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.grasp_sampling import (
    SamplingConfig,
    antipodal_accepts,
    antipodal_pairs,
    diverse_subset,
    sample_antipodal_grasps,
)
from kgn_bench.shapes.household import PINCH_CLEARANCE


def test_box_pairs_close_across_faces():
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    p, q = antipodal_pairs(box, np.random.default_rng(0), SamplingConfig(points=300))
    assert len(p) > 200  # every point of a box face has its opposite face straight behind it
    axis = (q - p) / np.linalg.norm(q - p, axis=1, keepdims=True)
    assert np.allclose(np.abs(axis).max(axis=1), 1.0, atol=1e-6)  # along a box axis
    extents = np.sort(np.unique(np.linalg.norm(q - p, axis=1).round(4)))
    assert np.allclose(extents, [0.04, 0.06, 0.10])


def test_grasps_are_valid_frames_with_their_width():
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    poses, widths = sample_antipodal_grasps(box, np.random.default_rng(1), SamplingConfig(points=200))
    assert len(poses) > 0
    R = poses[:, :3, :3]
    assert np.allclose(np.einsum("nji,njk->nik", R, R), np.eye(3), atol=1e-9)
    assert np.allclose(np.linalg.det(R), 1.0)
    assert np.all(widths <= GRIPPER.max_width) and np.all(widths >= 0.04 + PINCH_CLEARANCE - 1e-6)
    along_closing = np.einsum("ni,ni->n", poses[:, :3, 3], poses[:, :3, 2])
    assert np.allclose(along_closing, 0.0, atol=1e-9)  # the contact midpoint: halfway between opposite faces


def test_gripper_sweep_keeps_the_palm_off_the_object():
    """A 12 cm cube, wider than the 7 cm fingers are long: many approaches would put the palm (its box at
    the grasp, ``GRIPPER.palm_box``) into the cube. Those are dropped; no kept grasp has a point of its palm
    more than 2 mm (the surface sampling's spacing) inside the cube."""
    cube = trimesh.creation.box((0.12, 0.12, 0.12))
    config = SamplingConfig(points=150, approaches=12)
    p, _ = antipodal_pairs(cube, np.random.default_rng(2), config)
    poses, _ = sample_antipodal_grasps(cube, np.random.default_rng(2), config)
    assert 0 < len(poses) < 0.9 * len(p) * config.approaches
    palm = GRIPPER.palm_box()
    grid = np.stack(np.meshgrid(*[np.linspace(-1, 1, 7)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    local = palm.centre + grid * palm.half
    world = np.einsum("nij,pj->npi", poses[:, :3, :3], local) + poses[:, None, :3, 3]
    assert np.all(np.abs(world).max(axis=2) > 0.06 - 0.002)


def test_nothing_to_span():
    big = trimesh.creation.box((0.3, 0.3, 0.3))  # 30 cm everywhere: wider than the 20 cm opening
    poses, widths = sample_antipodal_grasps(big, np.random.default_rng(0), SamplingConfig(points=100))
    assert len(poses) == 0 and len(widths) == 0


def test_a_hollow_box_is_spanned_across_its_cavity():
    """A closed 6 cm box shell with 2 mm walls: the first exit of an inward ray is 2 mm away (a wall thinner
    than the 3 mm ``min_extent``), the later exit across the cavity gives the 6 cm grasp."""
    outer, inner = trimesh.creation.box((0.06, 0.06, 0.06)), trimesh.creation.box((0.056, 0.056, 0.056))
    inner.invert()
    shell = trimesh.util.concatenate([outer, inner])
    p, q = antipodal_pairs(shell, np.random.default_rng(3), SamplingConfig(points=200))
    assert len(p) > 0
    assert np.allclose(np.linalg.norm(q - p, axis=1), 0.06, atol=1e-6)


def test_the_labellers_test_on_given_grasps():
    """``antipodal_accepts`` passes a grasp across a box and gives it the labeller's width; a grasp whose
    closing axis is 30° off the face normals, one beside the box and one closing on a 30 cm side fail."""
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    across = make_pose(frame_from_xz(np.array([0.0, 0.0, -1.0]), np.array([1.0, 0.0, 0.0])), np.zeros(3))
    tilted = make_pose(across[:3, :3] @ rot_x(np.deg2rad(30.0)), np.zeros(3))
    beside = make_pose(across[:3, :3], np.array([0.0, 0.15, 0.0]))
    ok, widths = antipodal_accepts(box, np.stack([across, tilted, beside]), np.full(3, 0.06))
    assert ok.tolist() == [True, False, False]
    assert widths[0] == pytest.approx(0.04 + PINCH_CLEARANCE)
    big = trimesh.creation.box((0.3, 0.05, 0.05))
    ok, _ = antipodal_accepts(big, across[None], np.array([GRIPPER.max_width]))
    assert not ok[0]


def test_diverse_subset_spreads_over_closing_axes():
    """On a 12 × 9 × 3 cm slab most antipodal pairs close across the 3 cm thickness (the large faces hold
    most of the surface); a uniform draw keeps that bias, the diverse subset draws every closing axis."""
    slab = trimesh.creation.box((0.12, 0.09, 0.03))
    poses, _ = sample_antipodal_grasps(slab, np.random.default_rng(4), SamplingConfig(points=400))
    vertical = np.abs(poses[:, 2, 2]) > 0.9
    assert vertical.mean() > 0.5
    pick = diverse_subset(poses, 60, np.random.default_rng(5))
    assert len(np.unique(pick)) == 60 and np.all(np.diff(pick) > 0)
    assert vertical[pick].mean() < 0.5
    axes = np.argmax(np.abs(poses[pick, :3, 2]), axis=1)
    assert set(axes.tolist()) == {0, 1, 2}


def test_aimed_approaches_stay_within_their_spread_of_the_direction():
    """Asked for approaches along −z of a box's frame (from above it), every grasp approaches within 30° of
    −z, no closing axis lies within 30° of it, and the box still gets grasps across both of its sides."""
    box = trimesh.creation.box((0.04, 0.06, 0.10))
    down = np.array([0.0, 0.0, -1.0])
    poses, widths = sample_antipodal_grasps(box, np.random.default_rng(2), SamplingConfig(points=300), toward=down)
    assert len(poses) > 50
    approach_deg = np.rad2deg(np.arccos(np.clip(poses[:, :3, 0] @ down, -1.0, 1.0)))
    assert approach_deg.max() <= 30.0 + 1e-6
    assert np.all(np.abs(poses[:, :3, 2] @ down) < np.cos(np.deg2rad(30.0)))
    assert set(np.round(widths - PINCH_CLEARANCE, 4)) == {0.04, 0.06}
    uniform, _ = sample_antipodal_grasps(box, np.random.default_rng(2), SamplingConfig(points=300))
    assert np.mean(uniform[:, :3, 0] @ down > np.cos(np.deg2rad(30.0))) < 0.2  # what aiming is for
