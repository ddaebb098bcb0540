"""GIGA's simulated setting, every number of it in one place, in this harness's world frame.

GIGA (Jiang et al., RSS 2021) and VGN (Breyer et al., CoRL 2020) evaluate grasp detectors in one shared
protocol: a free-floating Panda hand over a 30 cm workspace cube, one depth camera, clutter rounds of 5
objects. The numbers below are read from their public code (``ethz-asl/vgn``, ``UT-Austin-RPL/GIGA``);
``docs/protocols.md`` states where this harness differs.

**Frames.** Their workspace is the cube ``[0, 0.3]³`` with the table top at ``z = 0.05`` (the finger depth).
Here the table top is the world's ``z = 0`` and the table is centred on the world origin, so the cube's
corner, which is the origin of the voxel grid frame of ``kgn_bench.tsdf`` (world axes, a pure translation),
lies at ``WORKSPACE_ORIGIN = (−0.15, −0.15, −0.05)``: a point ``p_grid`` of their cube is the world point
``p_world = p_grid + WORKSPACE_ORIGIN``.

**Camera.** ``camera_on_sphere(origin, r, θ, φ)`` with origin ``(0.15, 0.15, 0.10)`` (a third of the cube's
height), ``r = 2 × 0.3``, polar angle ``θ = π/3`` and ``φ = −π/2``: the eye at ``origin + r (sin θ cos φ,
sin θ sin φ, cos θ)``, on the cube's −y side, 30° above the table plane, looking at the origin. In this
harness's ``camera.orbit_pose`` terms that is distance 0.6 m, elevation 30°, azimuth 180° about the world
point ``(0, 0, 0.05)``.

Foundation level: this module imports nothing from the project.
"""

from __future__ import annotations

import numpy as np

from kgn_bench.gripper import PANDA_HAND

__all__ = [
    "APPROACH_SPEED", "CAMERA_AZIMUTH_DEG", "CAMERA_DISTANCE", "CAMERA_ELEVATION_DEG", "CAMERA_FAR", "CAMERA_TARGET",
    "CLOSE_TIME", "GRASP_REFERENCE_DEPTH", "LIFT_DISTANCE", "MAX_CONSECUTIVE_FAILURES", "MAX_EXTENT", "MIN_HELD_WIDTH",
    "OBJECTS_PER_ROUND", "PACKED_HALF", "PACKED_SCALE", "PACKED_TRIES", "PILE_DROP_HALF", "PILE_DROP_HEIGHT",
    "PILE_SCALE", "PREGRASP_DISTANCE", "RESOLUTION", "SIDE_GRASP_DEG", "TABLE_HEIGHT", "TRUNCATION_VOXELS",
    "VOXEL_SIZE", "WORKSPACE_ORIGIN", "WORKSPACE_SIZE", "in_workspace",
]

# -- workspace ------------------------------------------------------------------------------------------
WORKSPACE_SIZE = 0.30
"""Side (m) of the workspace cube: six finger depths."""
TABLE_HEIGHT = 0.05
"""Height (m) of the table top above the cube's floor (one finger depth)."""
WORKSPACE_ORIGIN = np.array([-WORKSPACE_SIZE / 2.0, -WORKSPACE_SIZE / 2.0, -TABLE_HEIGHT])
"""World position (m) of the cube's corner, the origin of the voxel grid frame (world axes)."""
RESOLUTION = 40
"""Voxels per side of the TSDF the network sees (VGN's 40³)."""
VOXEL_SIZE = WORKSPACE_SIZE / RESOLUTION
"""Side (m) of one voxel: 7.5 mm."""
TRUNCATION_VOXELS = 4
"""TSDF truncation distance in voxels (3 cm)."""
GRASP_REFERENCE_DEPTH = PANDA_HAND.finger_length
"""Where VGN puts a grasp's position (m behind the fingertips along the approach): its TCP sits VGN's finger
depth (5 cm, the Panda hand's finger length, ``gripper.PANDA_HAND``) behind the fingertips, so a grasp sampled
``d`` in front of a surface point (VGN: ``p + d·n``, ``d ~ U(−0.5, 5.5)`` cm) has its position in the observed
band in front of that surface and its fingertips ``5 cm − d`` past it. This project's grasp frame has its
origin at the fingertips: ``position = origin − GRASP_REFERENCE_DEPTH · approach``."""


def in_workspace(points: np.ndarray) -> np.ndarray:
    """(...,) bool: which world points (..., 3) lie in the workspace cube (boundary included). GIGA deletes
    every object whose origin leaves the cube, at set-up and after every attempt."""
    p = np.asarray(points, dtype=float) - WORKSPACE_ORIGIN
    return np.all((p >= 0.0) & (p <= WORKSPACE_SIZE), axis=-1)


# -- camera -----------------------------------------------------------------------------------------------
CAMERA_DISTANCE = 2.0 * WORKSPACE_SIZE
"""Camera distance (m) from its target: twice the cube's side."""
CAMERA_ELEVATION_DEG = 30.0
"""Camera elevation above the table plane (their polar angle θ = π/3)."""
CAMERA_AZIMUTH_DEG = 180.0
"""Camera azimuth in ``camera.orbit_pose`` terms (180° = the −y side; their φ = −π/2)."""
CAMERA_FAR = 2.0
"""The camera's far clipping plane (m): the background and anything beyond read 2 m (their near plane, 0.1 m,
is nearer than anything the camera sees)."""
CAMERA_TARGET = (0.0, 0.0, WORKSPACE_SIZE / 3.0 - TABLE_HEIGHT)
"""The point (world, m) the camera looks at: the cube's centre line, a third of its height up (5 cm above
the table)."""

# -- execution (the free-floating hand) -------------------------------------------------------------------
PREGRASP_DISTANCE = 0.05
"""The hand appears this far (m) back along the approach from the grasp, and moves in from there."""
APPROACH_SPEED = 0.10
"""Speed (m/s) of the straight moves in and out."""
CLOSE_TIME = 0.5
"""How long (s) the fingers are driven shut before the lift."""
LIFT_DISTANCE = 0.10
"""How far (m) the hand moves after closing: straight up, or back along the approach (``SIDE_GRASP_DEG``)."""
SIDE_GRASP_DEG = 60.0
"""A grasp whose approach is more than this far from straight down is lifted straight up; any other backs
out along its approach."""
MIN_HELD_WIDTH = 0.1
"""Success: after the lift the hand touches an object and its jaws are more than this fraction of their
maximum opening apart (8 mm for the Panda hand)."""

# -- clutter rounds -----------------------------------------------------------------------------------------
OBJECTS_PER_ROUND = 5
MAX_CONSECUTIVE_FAILURES = 2
"""A round ends when the table is clear, after this many failed grasps in a row, or when the detector
offers no grasp."""

# -- object placement ------------------------------------------------------------------------------------------
MAX_EXTENT = 0.07
"""Every object is first scaled down, if needed, so that its second-largest extent is at most this (m), so
that it fits the Panda hand's 8 cm opening one way; then by the arrangement's factor."""
PILE_SCALE = (0.8, 1.0)
"""Pile: each object's scale factor is drawn from U(0.8, 1.0)."""
PILE_DROP_HALF = WORKSPACE_SIZE / 6.0
"""Pile: objects drop at xy ~ U(−0.05, 0.05)² about the cube's centre line (their U(size/3, 2 size/3))."""
PILE_DROP_HEIGHT = 0.2
"""Pile: each object's origin starts this high (m) above the table, in a uniformly random orientation."""
PACKED_SCALE = (0.7, 0.9)
"""Packed: each object's scale factor is drawn from U(0.7, 0.9)."""
PACKED_HALF = 0.07
"""Packed: objects stand upright at xy ~ U(−0.07, 0.07)² (their U(0.08, 0.22))."""
PACKED_TRIES = 12
"""Packed: at most this many objects are tried; one that touches another when placed is taken away, so a
round may hold fewer than ``OBJECTS_PER_ROUND``."""
