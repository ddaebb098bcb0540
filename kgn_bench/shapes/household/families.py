"""Grasp families of the household objects' parts, and the filter that drops the grasps whose gripper would
run into another part of the same object (the module doc of ``shapes.household`` states the math).

Every pose is a grasp pose in the object frame (``T_obj_grasp``, grasp frame of ``kgn_bench.grasp``: +x
approach, z closing axis, y = z × x); widths in metres. The gripper's opening and the approach's distances
are read from their one source: ``gripper.GRIPPER`` (``open_margin``, the fingers, palm and wrist) and
``kgn_bench.execution`` (``PREGRASP_DISTANCE``, ``GRASP_DEPTH``).
"""

from __future__ import annotations

import numpy as np

from kgn_bench.execution import GRASP_DEPTH, PREGRASP_DISTANCE
from kgn_bench.geometry import frame_from_xz, make_pose
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.base import GraspDensity
from kgn_bench.shapes.household.parts import AXES, unit

__all__ = ["MIN_APPROACH_EXTENT", "PINCH_CLEARANCE", "SURFACE_SPACING", "box_family", "gripper_sweep_free",
           "on_axis", "tube_family"]

PINCH_CLEARANCE = 0.015
"""Grasp width = the pinched extent + this (7.5 mm each side)."""
MIN_APPROACH_EXTENT = 0.01
"""A box part is approached along an axis only if its extent along it is at least this (1 cm)."""
BOX_SINK_IN = 0.02
SURFACE_SPACING = 0.005
"""Mean spacing (m) of the surface sample points used by the self-collision filter."""
CLOSING_MARGIN = 0.003
"""While closing, a finger sweeps from its open position in to this far outside the pinched extent (3 mm: a
curved wall may meet the finger a little before its nominal extent)."""


def _frames(approach: np.ndarray, closing: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """Grasp poses (M, 4, 4) with x = approach, z = closing (made orthogonal to x), y = z × x."""
    x = unit(approach)
    z = unit(closing - np.sum(closing * x, axis=-1, keepdims=True) * x)
    poses = np.zeros((len(x), 4, 4))
    poses[:, :3, :3] = frame_from_xz(x, z)
    poses[:, :3, 3], poses[:, 3, 3] = origins, 1.0
    return poses


def tube_family(centres: np.ndarray, tangents: np.ndarray, refs: np.ndarray, radii: np.ndarray,
                 angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pinch grasps across a round part (see the module doc): every centre-line point × every angle β.

    ``centres``, ``tangents``, ``refs`` (M, 3) and local ``radii`` (M,); returns poses (M·A, 4, 4) and widths
    ``2·radius + PINCH_CLEARANCE``.
    """
    t = unit(tangents)
    u = unit(refs - np.sum(refs * t, axis=1, keepdims=True) * t)
    v = np.cross(t, u)
    cb, sb = np.cos(angles)[None, :, None], np.sin(angles)[None, :, None]
    normal = (cb * u[:, None] + sb * v[:, None]).reshape(-1, 3)
    tt = np.repeat(t, len(angles), axis=0)
    approach = -normal
    poses = _frames(approach, np.cross(tt, approach), np.repeat(centres, len(angles), axis=0))
    return poses, np.repeat(2.0 * np.asarray(radii) + PINCH_CLEARANCE, len(angles))


def box_family(T_part: np.ndarray, size, density: GraspDensity) -> tuple[np.ndarray, np.ndarray]:
    """The cuboid's family on a box part at ``T_part`` (object frame) with full extents ``size``.

    Approach ``x = ±e_a`` for every axis a with ``d_a ≥ MIN_APPROACH_EXTENT``, closing ``z = e_c`` (c ≠ a),
    ``y = z × x``; origin ``−sign·(d_a/2 − min(2 cm, d_a/2))·e_a + (−½ + (i+1)/(N+1))·d_y·y``; width
    ``d_c + PINCH_CLEARANCE``.
    """
    d = np.asarray(size, dtype=float)
    n = density.translations
    fractions = -0.5 + (np.arange(n) + 1.0) / (n + 1.0)
    poses, widths = [], []
    for app in range(3):
        if d[app] < MIN_APPROACH_EXTENT:
            continue
        sink = min(BOX_SINK_IN, d[app] / 2.0)
        for sign in (1.0, -1.0):
            x_g = sign * AXES[app]
            for close in (a for a in range(3) if a != app):
                z_g = AXES[close]
                R = frame_from_xz(x_g, z_g)
                y_g = R[:, 1]
                y_axis = int(np.argmax(np.abs(y_g)))
                for f in fractions:
                    t = -sign * (d[app] / 2.0 - sink) * AXES[app] + f * d[y_axis] * y_g
                    poses.append(T_part @ make_pose(R, t))
                    widths.append(d[close] + PINCH_CLEARANCE)
    return np.stack(poses), np.array(widths)


def on_axis(poses: np.ndarray, z: float) -> np.ndarray:
    """``poses`` moved by ``z`` along the object's z axis."""
    out = poses.copy()
    out[:, 2, 3] += z
    return out


def gripper_sweep_free(points: np.ndarray, poses: np.ndarray, widths: np.ndarray,
                         chunk: int = 48) -> np.ndarray:
    """(N,) bool: the gripper of each grasp, swept over its approach and its closing, contains none of the
    object ``points``.

    In the grasp frame: each finger ``|y| < b/2`` and ``d/2 + 3 mm < |z| < w'/2 + thickness``, where
    ``d = w − PINCH_CLEARANCE`` is the pinched extent and ``w' = GRIPPER.opening(w) = min(w + open_margin, max
    opening)`` the opening (the finger from where it opens to where it closes on the part), from
    ``x = −finger_length − PREGRASP_DISTANCE`` (the pre-grasp) to ``x = +GRASP_DEPTH`` (the push past the
    origin); palm and wrist ``GRIPPER.palm_box``/``wrist_box`` extended ``PREGRASP_DISTANCE`` back. 1 mm of
    tolerance.
    """
    g, m = GRIPPER, 1e-3
    palm, wrist = g.palm_box(), g.wrist_box()
    keep = np.ones(len(poses), dtype=bool)
    for s in range(0, len(poses), chunk):
        P = poses[s : s + chunk]
        local = np.einsum("npj,nji->npi", points[None] - P[:, None, :3, 3], P[:, :3, :3])
        lx, ay, az = local[..., 0], np.abs(local[..., 1]), np.abs(local[..., 2])
        w = widths[s : s + chunk, None]
        half_open = g.opening(w) / 2.0
        closed = np.minimum((w - PINCH_CLEARANCE) / 2.0 + CLOSING_MARGIN, half_open)
        finger = ((lx > -g.finger_length - PREGRASP_DISTANCE) & (lx < GRASP_DEPTH)
                  & (ay < g.finger_breadth / 2.0 - m) & (az > closed + m) & (az < half_open + g.finger_thickness - m))
        hit = finger
        for box in (palm, wrist):
            lo = box.centre - box.half - np.array([PREGRASP_DISTANCE, 0.0, 0.0])
            hi = box.centre + box.half
            hit = hit | ((lx > lo[0] + m) & (lx < hi[0] - m) & (ay < box.half[1] - m) & (az < box.half[2] - m))
        keep[s : s + chunk] = ~np.any(hit, axis=1)
    return keep

