"""Household objects for the closed-loop benchmark: not in the training data, built from pieces.

Each object is a frozen dataclass of sizes in metres, sampled uniformly from ``RANGES``; its object frame is
documented on the class. The pieces are the primitives' own: boxes, cylinders, spheres, the hollow rings of
boxes of the tube (``_annulus_boxes``) and the bowl's shell of boxes (``SemiSphere``), and small convex meshes
(tapered capsules: the convex hull of two spheres; a frustum). Hollow parts are hollow in the collision
geometry. The visual mesh is the concatenation of watertight part meshes (overlapping where parts join), smooth
solids of revolution where a part is one.

Grasp families (only the oracle uses them) are the families of the parts, in the object frame:

* **tube pinch** (``_tube_family``): across a round part at a point ``c`` of its centre line with unit tangent
  ``t``: for each angle β, outward normal ``n = cos β·u + sin β·(t × u)`` (``u`` a reference normal), approach
  ``−n`` (towards the centre line), closing axis ``t × approach``, origin at ``c``;
  ``_side_family`` of the PS shapes is this family for a vertical axis;
* **box pinch** (``_box_family``): the cuboid's family on a box part: approach along ±each axis whose extent is
  at least ``MIN_APPROACH_EXTENT`` (the fingers need something to close on), closing along one of the two
  others, the origin ``min(2 cm, d/2)`` inside the entry face, at N positions along the remaining axis;
* **rim pinch**: the tube's rim family (``_revolved_family`` of the top or bottom orientation) on a thin wall.

Width = the part's extent across the closing axis + ``PINCH_CLEARANCE`` (1.5 cm), so every width fits the
gripper. The labelling proxy ignores the grasped object itself, so grasps whose gripper would run into
another part of the same object are dropped here (``gripper_sweep_free``): the fingers (from the opening the
executor uses, width + 1 cm, in to 3 mm outside the pinched extent, and reaching 1 cm past the grasp origin as
the executor pushes on) and the palm and wrist, swept back along the approach over the 10 cm pre-grasp
distance, must contain no sample point of the object's surface.

Rest poses are chosen to exercise every natural resting state of each object (these are not the quasi-static
estimates of the PS shapes: the objects are not training data); gravity then settles them.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import trimesh

from kgn_bench.geometry import frame_from_xz, make_pose, quat_wxyz_from_matrix, rot_x, rot_y
from kgn_bench.grasp import GraspSet
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.base import GeomSpec, GraspDensity, RestPose, Shape
from kgn_bench.shapes.meshes import arc, revolve_profile
from kgn_bench.shapes.primitives import (
    _BOTTOM,
    _TOP,
    SemiSphere,
    _annulus_boxes,
    _positive,
    _revolved_family,
    _side_family,
    _uniform,
)

__all__ = [
    "HOUSEHOLD_CLASSES",
    "MIN_APPROACH_EXTENT",
    "PINCH_CLEARANCE",
    "Banana",
    "Bottle",
    "CClamp",
    "Can",
    "FootedBowl",
    "Hammer",
    "HouseholdShape",
    "LBracket",
    "Mug",
    "gripper_sweep_free",
]

PINCH_CLEARANCE = 0.015
"""Grasp width = the pinched extent + this (7.5 mm each side)."""
MIN_APPROACH_EXTENT = 0.01
"""A box part is approached along an axis only if its extent along it is at least this (1 cm)."""
BOX_SINK_IN = 0.02
OPENING_MARGIN = 0.01
"""The executor opens the jaws this much wider than the grasp width (``bench/selector.py``)."""
APPROACH_DEPTH = 0.01
"""How far the executor pushes past the grasp origin (``ExecutionConfig.grasp_depth``)."""
PREGRASP_DISTANCE = 0.10
"""The straight approach starts this far back along the approach axis (``ExecutionConfig.pregrasp_distance``)."""
SURFACE_SPACING = 0.005
"""Mean spacing (m) of the surface sample points used by the self-collision filter."""
CLOSING_MARGIN = 0.003
"""While closing, a finger sweeps from its open position in to this far outside the pinched extent (3 mm: a
curved wall may meet the finger a little before its nominal extent)."""

_E = np.eye(3)
_CAPSULE_SECTIONS = 20


# -- geometry helpers ------------------------------------------------------------------------------------------
def _unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _z_to(direction: np.ndarray) -> np.ndarray:
    """A rotation taking +z to ``direction`` (any twist about it)."""
    z = _unit(direction)
    helper = _E[0] if abs(z[0]) < 0.9 else _E[1]
    x = _unit(np.cross(helper, z))
    return frame_from_xz(x, z)


def _box(centre, size, R: np.ndarray | None = None) -> GeomSpec:
    """A box of full extents ``size`` at ``centre``, rotated by ``R``."""
    q = (1.0, 0.0, 0.0, 0.0) if R is None else tuple(float(v) for v in quat_wxyz_from_matrix(R))
    return GeomSpec("box", tuple(float(s) / 2.0 for s in size), pos=tuple(float(c) for c in centre), quat=q)


def _box_mesh(centre, size, R: np.ndarray | None = None) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=size, transform=make_pose(R, np.asarray(centre, dtype=float)))


def _cylinder(p0, p1, r: float) -> GeomSpec:
    """A solid cylinder of radius ``r`` from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    R = _z_to(p1 - p0)
    return GeomSpec("cylinder", (r, float(np.linalg.norm(p1 - p0)) / 2.0), pos=tuple(0.5 * (p0 + p1)),
                    quat=tuple(float(v) for v in quat_wxyz_from_matrix(R)))


def _cylinder_mesh(p0, p1, r: float, sections: int = 32) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=r, segment=np.array([p0, p1], dtype=float), sections=sections)


def _tapered_capsule(p0, r0: float, p1, r1: float) -> trimesh.Trimesh:
    """Watertight convex hull of the spheres (p0, r0) and (p1, r1): a capsule whose radius tapers linearly.

    Built as a solid of revolution about the segment: the cone tangent to both spheres has its outward
    normal at ``ψ = asin((r0 − r1)/L)`` above the radial direction, so the profile is the arc of sphere 0
    from its pole to polar angle π/2 + ψ (measured from the −axis), then the arc of sphere 1 from there to
    its far pole.
    """
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    length = float(np.linalg.norm(p1 - p0))
    psi = float(np.arcsin(np.clip((r0 - r1) / length, -0.99, 0.99)))
    cap0 = arc(r0, 0.0, np.pi / 2.0 + psi, 7)
    cap1 = arc(r1, np.pi / 2.0 + psi, np.pi, 7) + np.array([0.0, length])
    mesh = revolve_profile(np.concatenate([cap0, cap1]), _CAPSULE_SECTIONS)
    mesh.apply_transform(make_pose(_z_to(p1 - p0), p0))
    return mesh


def _concatenate(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The parts as one mesh (not merged: each part stays closed, so the whole is watertight)."""
    return trimesh.util.concatenate(meshes)


# -- grasp-family helpers --------------------------------------------------------------------------------------
def _frames(approach: np.ndarray, closing: np.ndarray, origins: np.ndarray) -> np.ndarray:
    """Grasp poses (M, 4, 4) with x = approach, z = closing (made orthogonal to x), y = z × x."""
    x = _unit(approach)
    z = _unit(closing - np.sum(closing * x, axis=-1, keepdims=True) * x)
    poses = np.zeros((len(x), 4, 4))
    poses[:, :3, :3] = frame_from_xz(x, z)
    poses[:, :3, 3], poses[:, 3, 3] = origins, 1.0
    return poses


def _tube_family(centres: np.ndarray, tangents: np.ndarray, refs: np.ndarray, radii: np.ndarray,
                 angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pinch grasps across a round part (see the module doc): every centre-line point × every angle β.

    ``centres``, ``tangents``, ``refs`` (M, 3) and local ``radii`` (M,); returns poses (M·A, 4, 4) and widths
    ``2·radius + PINCH_CLEARANCE``.
    """
    t = _unit(tangents)
    u = _unit(refs - np.sum(refs * t, axis=1, keepdims=True) * t)
    v = np.cross(t, u)
    cb, sb = np.cos(angles)[None, :, None], np.sin(angles)[None, :, None]
    normal = (cb * u[:, None] + sb * v[:, None]).reshape(-1, 3)
    tt = np.repeat(t, len(angles), axis=0)
    approach = -normal
    poses = _frames(approach, np.cross(tt, approach), np.repeat(centres, len(angles), axis=0))
    return poses, np.repeat(2.0 * np.asarray(radii) + PINCH_CLEARANCE, len(angles))


def _box_family(T_part: np.ndarray, size, density: GraspDensity) -> tuple[np.ndarray, np.ndarray]:
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
            x_g = sign * _E[app]
            for close in (a for a in range(3) if a != app):
                z_g = _E[close]
                R = frame_from_xz(x_g, z_g)
                y_g = R[:, 1]
                y_axis = int(np.argmax(np.abs(y_g)))
                for f in fractions:
                    t = -sign * (d[app] / 2.0 - sink) * _E[app] + f * d[y_axis] * y_g
                    poses.append(T_part @ make_pose(R, t))
                    widths.append(d[close] + PINCH_CLEARANCE)
    return np.stack(poses), np.array(widths)


def _on_axis(poses: np.ndarray, z: float) -> np.ndarray:
    """``poses`` moved by ``z`` along the object's z axis."""
    out = poses.copy()
    out[:, 2, 3] += z
    return out


def gripper_sweep_free(points: np.ndarray, poses: np.ndarray, widths: np.ndarray,
                         chunk: int = 48) -> np.ndarray:
    """(N,) bool: the gripper of each grasp, swept over its approach and its closing, contains none of the
    object ``points``.

    In the grasp frame: each finger ``|y| < b/2`` and ``d/2 + 3 mm < |z| < w'/2 + thickness``, where
    ``d = w − PINCH_CLEARANCE`` is the pinched extent and ``w' = min(w + 1 cm, max opening)`` the opening (the
    finger from where it opens to where it closes on the part), from ``x = −finger_length − 10 cm`` (the
    pre-grasp) to ``x = +1 cm`` (the push past the origin); palm and wrist ``GRIPPER.palm_box``/``wrist_box``
    extended 10 cm back. 1 mm of tolerance.
    """
    g, m = GRIPPER, 1e-3
    palm, wrist = g.palm_box(), g.wrist_box()
    keep = np.ones(len(poses), dtype=bool)
    for s in range(0, len(poses), chunk):
        P = poses[s : s + chunk]
        local = np.einsum("npj,nji->npi", points[None] - P[:, None, :3, 3], P[:, :3, :3])
        lx, ay, az = local[..., 0], np.abs(local[..., 1]), np.abs(local[..., 2])
        w = widths[s : s + chunk, None]
        half_open = np.minimum(w + OPENING_MARGIN, g.max_width) / 2.0
        closed = np.minimum((w - PINCH_CLEARANCE) / 2.0 + CLOSING_MARGIN, half_open)
        finger = ((lx > -g.finger_length - PREGRASP_DISTANCE) & (lx < APPROACH_DEPTH)
                  & (ay < g.finger_breadth / 2.0 - m) & (az > closed + m) & (az < half_open + g.finger_thickness - m))
        hit = finger
        for box in (palm, wrist):
            lo = box.centre - box.half - np.array([PREGRASP_DISTANCE, 0.0, 0.0])
            hi = box.centre + box.half
            hit = hit | ((lx > lo[0] + m) & (lx < hi[0] - m) & (ay < box.half[1] - m) & (az < box.half[2] - m))
        keep[s : s + chunk] = ~np.any(hit, axis=1)
    return keep


# -- the common base -------------------------------------------------------------------------------------------
class HouseholdShape(Shape):
    """A household object: sizes named by ``RANGES`` (sampled uniformly), a visual mesh made of part meshes,
    and grasp families built from its parts (``_families``), filtered for collisions with its own parts."""

    RANGES: ClassVar[dict[str, tuple[float, float]]]

    @classmethod
    def sample(cls, rng: np.random.Generator):
        return cls(**{k: _uniform(rng, lo, hi) for k, (lo, hi) in cls.RANGES.items()})

    @classmethod
    def from_dims(cls, dims: dict):
        if not isinstance(dims, dict):
            raise ValueError(f"{cls.name} needs a dict of dimensions, got {dims!r}")
        return cls(**{k: _positive(dims, k) for k in cls.RANGES})

    def dims(self) -> dict:
        return {k: float(getattr(self, k)) for k in self.RANGES}

    def visual_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("mesh", mesh=self.mesh())]

    @abc.abstractmethod
    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        """The part families as (poses (N, 4, 4), widths (N,)) pairs, before the self-collision filter."""

    def surface_points(self) -> np.ndarray:
        """Deterministic sample points (P, 3) on the visual mesh, about ``SURFACE_SPACING`` apart (cached)."""
        cached = self.__dict__.get("_surface_cache")
        if cached is None:
            mesh = self.mesh()
            count = int(np.clip(mesh.area / SURFACE_SPACING**2, 1000, 6000))
            cached = trimesh.sample.sample_surface(mesh, count, seed=0)[0]
            object.__setattr__(self, "_surface_cache", cached)
        return cached

    def grasps(self, density: GraspDensity) -> GraspSet:
        """The part families (``_families``; math in the module doc and on each class) minus the grasps whose
        gripper would hit the object's own other parts (cached per density; do not mutate)."""
        cache = self.__dict__.get("_grasp_cache")
        if cache is None:
            cache = {}
            object.__setattr__(self, "_grasp_cache", cache)
        if density not in cache:
            families = self._families(density)
            poses = np.concatenate([p for p, _ in families])
            widths = np.concatenate([w for _, w in families])
            keep = gripper_sweep_free(self.surface_points(), poses, widths)
            cache[density] = GraspSet.unlabelled(poses[keep], widths[keep])
        return cache[density]


def _upright_lying(up: float, down: float, lying: list[tuple[np.ndarray, float]]) -> list[RestPose]:
    poses = [RestPose(np.eye(3), up)] + ([RestPose(rot_x(np.pi), down)] if down > 0 else [])
    return poses + [RestPose(R, p) for R, p in lying]


# -- the objects -----------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Mug(HouseholdShape):
    """Mug: a cup of inner radius ``r_in`` ~U[3, 4.2] cm, 6 mm wall, 8 mm bottom, height ``h`` ~U[7.5, 10.5] cm,
    with a D-shaped handle (a chain of 6 capsules of radius 4.5 mm along a half ellipse) leaving a 2.2 cm gap.

    Object frame: cup axis along z, origin on it at mid-height (the cup spans z ∈ [−h/2, h/2]); the handle lies
    in the xz plane on the +x side. Collision: the tube's ring of 24 boxes for the wall (really hollow), a
    cylinder for the bottom, the capsules as convex meshes.
    Families: rim pinch from the top (mid-wall, 5 mm below the rim, closing radially, width wall + 1.5 cm; not
    within 0.6 rad of the handle's azimuth);
    tube pinch across the body on the axis (``_side_family`` heights, width 2·r_out + 1.5 cm); tube pinch across
    the handle at N points of the ellipse's middle (parameter φ ∈ [−45°, 45°]) all around it.
    Rest poses: upright 0.5, upside down 0.1, on its side with the handle up 0.2 or sideways 0.2.
    """

    r_in: float
    h: float

    name: ClassVar[str] = "mug"
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {"r_in": (0.03, 0.042), "h": (0.075, 0.105)}
    density: ClassVar[float] = 1000.0
    WALL: ClassVar[float] = 0.006
    BOTTOM: ClassVar[float] = 0.008
    RIM_SINK_IN: ClassVar[float] = 0.005
    HANDLE_RADIUS: ClassVar[float] = 0.0045
    HANDLE_GAP: ClassVar[float] = 0.022
    HANDLE_SPAN: ClassVar[float] = 0.6
    """Vertical extent of the handle's centre line as a fraction of h."""
    HANDLE_JOINTS: ClassVar[int] = 7
    RIM_HANDLE_CLEARANCE: ClassVar[float] = 0.6
    """Rim grasps keep this far (rad) in azimuth from the handle: a finger closing there lands on the handle."""

    @property
    def r_out(self) -> float:
        return self.r_in + self.WALL

    def _ellipse(self) -> tuple[float, float, float]:
        """Centre x0 and semi-axes (a_x, a_z) of the handle's centre line: x = x0 + a_x cos φ, z = a_z sin φ."""
        x0 = self.r_out - 0.0005
        return x0, self.HANDLE_GAP + self.HANDLE_RADIUS + 0.0005, self.HANDLE_SPAN * self.h / 2.0

    def handle_points(self, phi: np.ndarray) -> np.ndarray:
        x0, ax, az = self._ellipse()
        return np.stack([x0 + ax * np.cos(phi), np.zeros_like(phi), az * np.sin(phi)], axis=1)

    def _handle_pieces(self) -> list[trimesh.Trimesh]:
        p = self.handle_points(np.linspace(-np.pi / 2.0, np.pi / 2.0, self.HANDLE_JOINTS))
        r = self.HANDLE_RADIUS
        return [_tapered_capsule(p[k], r, p[k + 1], r) for k in range(len(p) - 1)]

    def volume(self) -> float:
        _, ax, az = self._ellipse()
        phi = np.linspace(-np.pi / 2.0, np.pi / 2.0, 200)
        length = float(np.sum(np.hypot(np.diff(ax * np.cos(phi)), np.diff(az * np.sin(phi)))))
        wall = np.pi * (self.r_out**2 - self.r_in**2) * self.h
        return float(wall + np.pi * self.r_in**2 * self.BOTTOM + np.pi * self.HANDLE_RADIUS**2 * length)

    def _build_mesh(self) -> trimesh.Trimesh:
        hh, b = self.h / 2.0, self.BOTTOM
        cup = revolve_profile(np.array([[0.0, -hh], [self.r_out, -hh], [self.r_out, hh], [self.r_in, hh],
                                        [self.r_in, -hh + b], [0.0, -hh + b]]), 48)
        return _concatenate([cup, *self._handle_pieces()])

    def collision_geoms(self) -> list[GeomSpec]:
        hh = self.h / 2.0
        wall = _annulus_boxes(self.r_in, self.r_out, self.h)
        bottom = _cylinder((0, 0, -hh), (0, 0, -hh + self.BOTTOM), self.r_in + self.WALL / 2.0)
        return [*wall, bottom, *(GeomSpec("mesh", mesh=m) for m in self._handle_pieces())]

    def rest_poses(self) -> list[RestPose]:
        return _upright_lying(0.5, 0.1, [(rot_y(-np.pi / 2.0), 0.2), (rot_x(np.pi / 2.0), 0.2)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        angles = density.angle_samples()
        rim_angles = angles[np.abs(np.angle(np.exp(1j * angles))) >= self.RIM_HANDLE_CLEARANCE]
        rim = _revolved_family(make_pose(_TOP, (self.r_in + self.WALL / 2.0, 0.0, self.h / 2.0 - self.RIM_SINK_IN)),
                               rim_angles)
        body = _side_family(self.h, density)
        phi = np.linspace(-np.pi / 4.0, np.pi / 4.0, density.translations)
        _, ax, az = self._ellipse()
        tangents = np.stack([-ax * np.sin(phi), np.zeros_like(phi), az * np.cos(phi)], axis=1)
        normals = np.stack([az * np.cos(phi), np.zeros_like(phi), ax * np.sin(phi)], axis=1)
        handle = _tube_family(self.handle_points(phi), tangents, normals, np.full(len(phi), self.HANDLE_RADIUS),
                              angles)
        return [(rim, np.full(len(rim), self.WALL + PINCH_CLEARANCE)),
                (body, np.full(len(body), 2.0 * self.r_out + PINCH_CLEARANCE)), handle]


@dataclass(frozen=True)
class Bottle(HouseholdShape):
    """Bottle: solid body of radius ``r`` ~U[2.5, 3.6] cm, total height ``h`` ~U[15, 20] cm: body 0.58·h, a
    frustum shoulder 0.14·h, a neck of radius 0.4·r and 0.18·h, a cap 2 mm wider than the neck, 0.10·h tall.

    Object frame: axis along z, origin on it at the body's mid-height (the body spans z ∈ [−0.29 h, 0.29 h]).
    Collision: cylinders for body, neck and cap, a convex frustum mesh for the shoulder.
    Families: tube pinch across the body (``_side_family`` over the body, width 2·r + 1.5 cm) and across the
    neck (⌈N/2⌉ heights, width 2·r_neck + 1.5 cm); a top pinch across the cap (approach down the axis,
    closing radially, origin 8 mm below the top, one per angle, width 2·r_cap + 1.5 cm).
    Rest poses: upright 0.3, lying 0.7.
    """

    r: float
    h: float

    name: ClassVar[str] = "bottle"
    axisymmetric: ClassVar[bool] = True
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {"r": (0.025, 0.036), "h": (0.15, 0.20)}
    density: ClassVar[float] = 400.0
    BODY: ClassVar[float] = 0.58
    SHOULDER: ClassVar[float] = 0.14
    NECK: ClassVar[float] = 0.18
    CAP: ClassVar[float] = 0.10
    CAP_SINK_IN: ClassVar[float] = 0.008

    @property
    def r_neck(self) -> float:
        return 0.4 * self.r

    @property
    def r_cap(self) -> float:
        return self.r_neck + 0.002

    def levels(self) -> tuple[float, float, float, float, float]:
        """z of the bottom, body top, shoulder top, cap bottom and top."""
        zb = -self.BODY * self.h / 2.0
        z1 = -zb
        z2 = z1 + self.SHOULDER * self.h
        z3 = z2 + self.NECK * self.h
        return zb, z1, z2, z3, z3 + self.CAP * self.h

    def volume(self) -> float:
        zb, z1, z2, z3, top = self.levels()
        r, rn = self.r, self.r_neck
        frustum = np.pi * (z2 - z1) * (r * r + r * rn + rn * rn) / 3.0
        neck_and_cap = np.pi * rn * rn * (z3 - z2) + np.pi * self.r_cap**2 * (top - z3)
        return float(np.pi * r * r * (z1 - zb) + frustum + neck_and_cap)

    def _build_mesh(self) -> trimesh.Trimesh:
        zb, z1, z2, z3, top = self.levels()
        r, rn, rc, c = self.r, self.r_neck, self.r_cap, 0.002
        profile = [[0.0, zb], [r - c, zb], [r, zb + c], [r, z1], [rn, z2], [rn, z3], [rc, z3], [rc, top - c / 2],
                   [rc - c / 2, top], [0.0, top]]
        return revolve_profile(np.array(profile), 48)

    def collision_geoms(self) -> list[GeomSpec]:
        zb, z1, z2, z3, top = self.levels()
        shoulder = revolve_profile(np.array([[0.0, z1 - 0.001], [self.r, z1 - 0.001], [self.r_neck, z2],
                                             [0.0, z2]]), 24)
        return [_cylinder((0, 0, zb), (0, 0, z1), self.r), GeomSpec("mesh", mesh=shoulder),
                _cylinder((0, 0, z2 - 0.001), (0, 0, z3), self.r_neck), _cylinder((0, 0, z3), (0, 0, top), self.r_cap)]

    def rest_poses(self) -> list[RestPose]:
        return _upright_lying(0.3, 0.0, [(rot_y(-np.pi / 2.0), 0.7)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        zb, z1, z2, z3, top = self.levels()
        body = _side_family(z1 - zb, density)
        neck_density = GraspDensity(max(1, (density.translations + 1) // 2), density.angles)
        neck = _on_axis(_side_family(z3 - z2, neck_density), (z2 + z3) / 2.0)
        cap = _revolved_family(make_pose(_TOP, (0.0, 0.0, top - self.CAP_SINK_IN)), density.angle_samples())
        return [(body, np.full(len(body), 2.0 * self.r + PINCH_CLEARANCE)),
                (neck, np.full(len(neck), 2.0 * self.r_neck + PINCH_CLEARANCE)),
                (cap, np.full(len(cap), 2.0 * self.r_cap + PINCH_CLEARANCE))]


@dataclass(frozen=True)
class FootedBowl(HouseholdShape):
    """Bowl with a foot: the PS bowl (``SemiSphere``) of outer radius ``r`` ~U[5, 7.5] cm on a foot ring of
    outer radius 0.45·r, 6 mm wall, reaching 1.6 cm below the shell (room for a finger inside it).

    Object frame: the bowl's (sphere centre at the origin, rim at z = 0, opening up); the foot's bottom at
    z = −r − 1.6 cm. The ring's top is embedded in the shell wall, halfway between the outer surface at its outer
    radius and the inner surface at its inner radius, so it neither floats nor pokes into the bowl.
    Collision: the bowl's shell of boxes and a ring of 16 boxes for the foot (both hollow).
    Families: the bowl's rim pinch (mid-wall, 3 mm below the rim, width wall + 1.5 cm) and a foot-ring pinch
    from below the object (approach +z, mid-wall, 3 mm inside the foot's free end, width 6 mm + 1.5 cm): the
    one that comes from above when the bowl lies upside down.
    Rest poses: upright 0.8, upside down 0.2.
    """

    r: float

    name: ClassVar[str] = "footed_bowl"
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {"r": (0.05, 0.075)}
    FOOT_RADIUS: ClassVar[float] = 0.45
    FOOT_WALL: ClassVar[float] = 0.006
    FOOT_DROP: ClassVar[float] = 0.016
    RIM_SINK_IN: ClassVar[float] = 0.003
    FOOT_SINK_IN: ClassVar[float] = 0.003

    @property
    def bowl(self) -> SemiSphere:
        return SemiSphere(self.r)

    def foot(self) -> tuple[float, float, float, float]:
        """Inner and outer radius, bottom and top z of the foot ring."""
        ro = self.FOOT_RADIUS * self.r
        ri = ro - self.FOOT_WALL
        top = -0.5 * (np.sqrt(self.r**2 - ro**2) + np.sqrt(self.bowl.r_in**2 - ri**2))
        return ri, ro, -self.r - self.FOOT_DROP, float(top)

    def volume(self) -> float:
        ri, ro, bottom, _ = self.foot()
        shell_bottom = -np.sqrt(self.r**2 - ((ri + ro) / 2.0) ** 2)
        return float(self.bowl.volume() + np.pi * (ro**2 - ri**2) * (shell_bottom - bottom))

    def _build_mesh(self) -> trimesh.Trimesh:
        ri, ro, bottom, top = self.foot()
        ring = revolve_profile(np.array([[ri, bottom], [ro, bottom], [ro, top], [ri, top]]), 48)
        return _concatenate([self.bowl.mesh(), ring])

    def collision_geoms(self) -> list[GeomSpec]:
        ri, ro, bottom, top = self.foot()
        foot = _annulus_boxes(ri, ro, top - bottom, z=(top + bottom) / 2.0, segments=16)
        return [*self.bowl.collision_geoms(), *foot]

    def rest_poses(self) -> list[RestPose]:
        return _upright_lying(0.8, 0.2, [])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        angles = density.angle_samples()
        bowl = self.bowl
        ri, ro, bottom, _ = self.foot()
        rim = _revolved_family(make_pose(_TOP, ((self.r + bowl.r_in) / 2.0, 0.0, -self.RIM_SINK_IN)), angles)
        foot = _revolved_family(make_pose(_BOTTOM, ((ri + ro) / 2.0, 0.0, bottom + self.FOOT_SINK_IN)), angles)
        return [(rim, np.full(len(rim), self.r - bowl.r_in + PINCH_CLEARANCE)),
                (foot, np.full(len(foot), self.FOOT_WALL + PINCH_CLEARANCE))]


@dataclass(frozen=True)
class Hammer(HouseholdShape):
    """Tool with a head: a round handle of radius ``r_handle`` ~U[1.0, 1.4] cm along x, total length
    ``length`` ~U[15, 20] cm, ending in a box head ``head`` ~U[7, 10] cm long (along y) with a square
    cross-section of side ``head_side`` ~U[2.2, 3.0] cm.

    Object frame: handle axis = x, head at the +x end with its long axis along y; origin on the handle axis at
    the object's centroid (uniform density), so the handle spans x ∈ [−x̄, length − head_side/2 − x̄].
    Collision: a cylinder and a box. Families: tube pinch across the handle at N points from 1 cm after its
    end to 1 cm before the head, all around it (width 2·r_handle + 1.5 cm); box pinch on the head.
    Rest poses: lying on either face of the head (z up 0.5, z down 0.5).
    """

    r_handle: float
    length: float
    head: float
    head_side: float

    name: ClassVar[str] = "hammer"
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {
        "r_handle": (0.010, 0.014), "length": (0.15, 0.20), "head": (0.07, 0.10), "head_side": (0.022, 0.030)}
    density: ClassVar[float] = 900.0

    def _parts(self) -> tuple[float, float, float, float]:
        """Volumes of the handle outside the head and of the head, the centroid x̄ (from the handle's end)
        and the head's centre x (object frame)."""
        c = self.head_side
        v_handle = np.pi * self.r_handle**2 * (self.length - c)
        v_head = c * c * self.head
        x_bar = (v_handle * (self.length - c) / 2.0 + v_head * (self.length - c / 2.0)) / (v_handle + v_head)
        return float(v_handle), float(v_head), float(x_bar), float(self.length - c / 2.0 - x_bar)

    def volume(self) -> float:
        v_handle, v_head, _, _ = self._parts()
        return v_handle + v_head

    def _handle_ends(self) -> tuple[np.ndarray, np.ndarray]:
        _, _, x_bar, x_head = self._parts()
        return np.array([-x_bar, 0.0, 0.0]), np.array([x_head, 0.0, 0.0])

    def _head_size(self) -> tuple[float, float, float]:
        return self.head_side, self.head, self.head_side

    def _build_mesh(self) -> trimesh.Trimesh:
        p0, p1 = self._handle_ends()
        return _concatenate([_cylinder_mesh(p0, p1, self.r_handle), _box_mesh(p1, self._head_size())])

    def collision_geoms(self) -> list[GeomSpec]:
        p0, p1 = self._handle_ends()
        return [_cylinder(p0, p1, self.r_handle), _box(p1, self._head_size())]

    def rest_poses(self) -> list[RestPose]:
        return _upright_lying(0.5, 0.5, [])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        p0, p1 = self._handle_ends()
        xs = np.linspace(p0[0] + 0.01, p1[0] - self.head_side / 2.0 - 0.01, density.translations)
        centres = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
        handle = _tube_family(centres, np.tile(_E[0], (len(xs), 1)), np.tile(_E[2], (len(xs), 1)),
                              np.full(len(xs), self.r_handle), density.angle_samples())
        return [handle, _box_family(make_pose(t=p1), self._head_size(), density)]


@dataclass(frozen=True)
class Banana(HouseholdShape):
    """Banana-like chain: 6 tapered capsules along a circular arc of radius ``R`` ~U[10, 16] cm and angle
    ``angle`` ~U[1.0, 1.4] rad in the xy plane (10-22 cm long); thickness radius ``r`` ~U[1.2, 1.6] cm in the middle,
    tapering to 0.55·r at the tips: ``r(s) = r·(0.55 + 0.45·sin(π s))`` for arc fraction s ∈ [0, 1].

    Object frame: z normal to the arc's plane; origin at the mean of the 7 joint points, the convex side
    towards +x (joints ``(R cos φ − x̄, R sin φ, 0)``, φ ∈ [−angle/2, angle/2]). Collision: the 6 capsules as
    convex meshes. Families: tube pinch across the chain at N arc fractions (i+1)/(N+1), all around it
    (width 2·r(s) + 1.5 cm). Rest poses: lying, either face up (0.5 each), leaning (``lean``).
    """

    R: float
    angle: float
    r: float

    name: ClassVar[str] = "banana"
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {"R": (0.10, 0.16), "angle": (1.0, 1.4), "r": (0.012, 0.016)}
    density: ClassVar[float] = 900.0
    SEGMENTS: ClassVar[int] = 6

    def radius_at(self, s: np.ndarray) -> np.ndarray:
        return self.r * (0.55 + 0.45 * np.sin(np.pi * np.asarray(s)))

    def _centre_line(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points and unit tangents of the centre line at arc fractions ``s``."""
        phi_j = np.linspace(-self.angle / 2.0, self.angle / 2.0, self.SEGMENTS + 1)
        x_bar = float(np.mean(self.R * np.cos(phi_j)))
        phi = -self.angle / 2.0 + self.angle * np.asarray(s)
        pts = np.stack([self.R * np.cos(phi) - x_bar, self.R * np.sin(phi), np.zeros_like(phi)], axis=1)
        tan = np.stack([-np.sin(phi), np.cos(phi), np.zeros_like(phi)], axis=1)
        return pts, tan

    def _pieces(self) -> list[trimesh.Trimesh]:
        cached = self.__dict__.get("_pieces_cache")
        if cached is None:
            s = np.linspace(0.0, 1.0, self.SEGMENTS + 1)
            p, _ = self._centre_line(s)
            r = self.radius_at(s)
            cached = [_tapered_capsule(p[k], r[k], p[k + 1], r[k + 1]) for k in range(self.SEGMENTS)]
            object.__setattr__(self, "_pieces_cache", cached)
        return cached

    def volume(self) -> float:
        """The capsules' volumes minus the joint spheres each two of them share."""
        r = self.radius_at(np.linspace(0.0, 1.0, self.SEGMENTS + 1))[1:-1]
        return float(sum(m.volume for m in self._pieces()) - np.sum(4.0 / 3.0 * np.pi * r**3))

    def _build_mesh(self) -> trimesh.Trimesh:
        return _concatenate(self._pieces())

    def collision_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("mesh", mesh=m) for m in self._pieces()]

    def lean(self) -> float:
        """Tilt (rad) at which the lying chain rests. Its centroid lies on the concave side of the thick middle,
        so it rolls towards −x: turned by ``R_y(−θ)``, its centroid height above the lowest point,
        ``h(θ) = (R c)_z − min_k ((R p_k)_z − r_k)``, falls from θ = 0 to a minimum, the stable lean (found in
        0.005 rad steps). A capsule is the union of the balls (p_k, r_k) interpolated linearly between its end
        balls, so its lowest point is that of densely sampled interpolated balls."""
        cached = self.__dict__.get("_lean_cache")
        if cached is None:
            s = np.linspace(0.0, 1.0, self.SEGMENTS + 1)
            p, _ = self._centre_line(s)
            r = self.radius_at(s)
            t = np.linspace(0.0, 1.0, 40)[:, None]
            centres = np.concatenate([p[k] + t * (p[k + 1] - p[k]) for k in range(self.SEGMENTS)])
            radii = np.concatenate([r[k] + t[:, 0] * (r[k + 1] - r[k]) for k in range(self.SEGMENTS)])
            com = self.mesh().center_mass

            def height(theta: float) -> float:
                R = rot_y(-theta)
                return float((R @ com)[2] - np.min(centres @ R[2] - radii))

            theta, step = 0.0, 0.005
            while theta < np.pi / 2.0 and height(theta + step) < height(theta):
                theta += step
            cached = float(theta)
            object.__setattr__(self, "_lean_cache", cached)
        return cached

    def rest_poses(self) -> list[RestPose]:
        """Lying on either face (0.5 each), leaning by ``lean()`` towards the concave side."""
        tilt = rot_y(-self.lean())
        return [RestPose(tilt, 0.5), RestPose(tilt @ rot_x(np.pi), 0.5)]

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        n = density.translations
        s = (np.arange(n) + 1.0) / (n + 1.0)
        pts, tan = self._centre_line(s)
        return [_tube_family(pts, tan, np.tile(_E[2], (n, 1)), self.radius_at(s), density.angle_samples())]


@dataclass(frozen=True)
class CClamp(HouseholdShape):
    """C-clamp: three bars of square-ish section (in-plane width ``bar`` ~U[1.2, 1.8] cm, thickness
    ``thickness`` ~U[1.2, 1.8] cm) forming a C of depth ``depth`` ~U[6, 8.5] cm (x) and height ``height``
    ~U[8, 12] cm (y), with a screw (4 mm radius) down through the tip of the upper jaw ending in a pad (radius
    0.45·thickness), turned by a T-bar above the jaw.

    Object frame: the C's bounding box centred at the origin, the back bar at x = −depth/2, the jaws along +x
    at y = ±(height − bar)/2, thickness along z. Collision: boxes and cylinders. Families: box pinch on each
    of the three bars. Rest poses: lying flat (z up 0.4, z down 0.4), standing on the back bar (0.2).
    """

    depth: float
    height: float
    bar: float
    thickness: float

    name: ClassVar[str] = "c_clamp"
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {
        "depth": (0.06, 0.085), "height": (0.08, 0.12), "bar": (0.012, 0.018), "thickness": (0.012, 0.018)}
    density: ClassVar[float] = 3000.0
    SCREW_RADIUS: ClassVar[float] = 0.004

    def bars(self) -> list[tuple[np.ndarray, tuple[float, float, float]]]:
        """Centre and full size of the back bar, the upper jaw and the lower jaw (touching, not overlapping)."""
        D, H, b, t = self.depth, self.height, self.bar, self.thickness
        jaw = (D - b, b, t)
        return [(np.array([-D / 2.0 + b / 2.0, 0.0, 0.0]), (b, H, t)),
                (np.array([b / 2.0, H / 2.0 - b / 2.0, 0.0]), jaw),
                (np.array([b / 2.0, -H / 2.0 + b / 2.0, 0.0]), jaw)]

    def _screw(self) -> list[tuple[str, np.ndarray, np.ndarray, float]]:
        """(kind, p0, p1, radius) of the screw, its pad and its T-bar."""
        D, H, b = self.depth, self.height, self.bar
        x = D / 2.0 - b / 2.0
        gap = H - 2.0 * b
        y_end = H / 2.0 - b - 0.35 * gap
        y_top = H / 2.0 + 0.012
        return [("screw", np.array([x, y_end, 0.0]), np.array([x, y_top, 0.0]), self.SCREW_RADIUS),
                ("pad", np.array([x, y_end - 0.004, 0.0]), np.array([x, y_end, 0.0]), 0.45 * self.thickness),
                ("t_bar", np.array([x - 0.012, y_top, 0.0]), np.array([x + 0.012, y_top, 0.0]), 0.003)]

    def volume(self) -> float:
        boxes = sum(float(np.prod(size)) for _, size in self.bars())
        return boxes + sum(np.pi * r * r * float(np.linalg.norm(p1 - p0)) for _, p0, p1, r in self._screw())

    def _build_mesh(self) -> trimesh.Trimesh:
        parts = [_box_mesh(c, s) for c, s in self.bars()]
        return _concatenate(parts + [_cylinder_mesh(p0, p1, r, 24) for _, p0, p1, r in self._screw()])

    def collision_geoms(self) -> list[GeomSpec]:
        return [_box(c, s) for c, s in self.bars()] + [_cylinder(p0, p1, r) for _, p0, p1, r in self._screw()]

    def rest_poses(self) -> list[RestPose]:
        return _upright_lying(0.4, 0.4, [(rot_y(-np.pi / 2.0), 0.2)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        return [_box_family(make_pose(t=c), s, density) for c, s in self.bars()]


@dataclass(frozen=True)
class Can(HouseholdShape):
    """Can: a solid cylinder of radius ``r`` ~U[2.6, 3.4] cm and height ``h`` ~U[9, 13] cm (thinner and taller
    than the PS tube, and closed), its bottom bevelled by 4 mm and its top narrowed by 3 mm to a rim around
    a recessed lid.

    Object frame: axis along z, origin at mid-height (z ∈ [−h/2, h/2]). Collision: three cylinders (body,
    bevelled bottom, top; the lid recess is filled). Families: tube pinch across the straight body
    (``_side_family`` heights, width 2·r + 1.5 cm); top and bottom pinches along the axis (origin 1.2 cm inside
    the end, closing radially through the axis, one per angle, width 2·r + 1.5 cm).
    Rest poses: upright 0.35, upside down 0.15, lying 0.5.
    """

    r: float
    h: float

    name: ClassVar[str] = "can"
    axisymmetric: ClassVar[bool] = True
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {"r": (0.026, 0.034), "h": (0.09, 0.13)}
    density: ClassVar[float] = 700.0
    BEVEL: ClassVar[float] = 0.004
    SHOULDER: ClassVar[float] = 0.006
    RIM_INSET: ClassVar[float] = 0.003
    END_SINK_IN: ClassVar[float] = 0.012

    def volume(self) -> float:
        return float(np.pi * self.r**2 * self.h)

    def _build_mesh(self) -> trimesh.Trimesh:
        hh, r, b, s, i = self.h / 2.0, self.r, self.BEVEL, self.SHOULDER, self.RIM_INSET
        profile = [[0.0, -hh], [r - b, -hh], [r, -hh + b], [r, hh - s], [r - i, hh - 0.002], [r - i, hh],
                   [r - i - 0.0015, hh], [r - i - 0.0015, hh - 0.003], [0.0, hh - 0.003]]
        return revolve_profile(np.array(profile), 48)

    def collision_geoms(self) -> list[GeomSpec]:
        hh, r, b, s, i = self.h / 2.0, self.r, self.BEVEL, self.SHOULDER, self.RIM_INSET
        return [_cylinder((0, 0, -hh + b), (0, 0, hh - s), r), _cylinder((0, 0, -hh), (0, 0, -hh + b + 0.001), r - b),
                _cylinder((0, 0, hh - s - 0.001), (0, 0, hh), r - i)]

    def rest_poses(self) -> list[RestPose]:
        return _upright_lying(0.35, 0.15, [(rot_y(-np.pi / 2.0), 0.5)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        hh, angles = self.h / 2.0, density.angle_samples()
        lo, hi = -hh + self.BEVEL, hh - self.SHOULDER
        body = _on_axis(_side_family(hi - lo, density), (lo + hi) / 2.0)
        top = _revolved_family(make_pose(_TOP, (0.0, 0.0, hh - self.END_SINK_IN)), angles)
        bottom = _revolved_family(make_pose(_BOTTOM, (0.0, 0.0, -hh + self.END_SINK_IN)), angles)
        poses = np.concatenate([body, top, bottom])
        return [(poses, np.full(len(poses), 2.0 * self.r + PINCH_CLEARANCE))]


@dataclass(frozen=True)
class LBracket(HouseholdShape):
    """L-bracket: two plates of thickness ``t`` ~U[4, 7] mm and width ``w`` ~U[3, 5] cm (along y): a base
    plate ``a`` ~U[6, 10] cm long (along x) and an upright plate ``b`` ~U[4, 7] cm tall (along z) standing on
    its −x end.

    Object frame: the bounding box centred at the origin: base plate x ∈ [−a/2, a/2], z ∈ [−b/2, −b/2 + t];
    upright plate x ∈ [−a/2, −a/2 + t], z ∈ [−b/2 + t, b/2] (touching, not overlapping). Collision: two boxes.
    Families: box pinch on each plate; a plate is never approached through its thickness (under
    ``MIN_APPROACH_EXTENT``), so the fingers always close across the plate (width t + 1.5 cm) or along it.
    Rest poses: on the base plate 0.35, on the upright plate 0.35, on either long edge 0.15 each.
    """

    a: float
    b: float
    w: float
    t: float

    name: ClassVar[str] = "l_bracket"
    RANGES: ClassVar[dict[str, tuple[float, float]]] = {
        "a": (0.06, 0.10), "b": (0.04, 0.07), "w": (0.03, 0.05), "t": (0.004, 0.007)}
    density: ClassVar[float] = 2700.0

    @classmethod
    def from_dims(cls, dims: dict) -> LBracket:
        shape = super().from_dims(dims)
        if not (shape.t < MIN_APPROACH_EXTENT and 2.0 * shape.t < min(shape.a, shape.b)):
            raise ValueError(f"l_bracket plates must be thinner than 1 cm and half their length, got {dims}")
        return shape

    def plates(self) -> list[tuple[np.ndarray, tuple[float, float, float]]]:
        a, b, w, t = self.a, self.b, self.w, self.t
        return [(np.array([0.0, 0.0, -b / 2.0 + t / 2.0]), (a, w, t)),
                (np.array([-a / 2.0 + t / 2.0, 0.0, t / 2.0]), (t, w, b - t))]

    def volume(self) -> float:
        return sum(float(np.prod(size)) for _, size in self.plates())

    def _build_mesh(self) -> trimesh.Trimesh:
        return _concatenate([_box_mesh(c, s) for c, s in self.plates()])

    def collision_geoms(self) -> list[GeomSpec]:
        return [_box(c, s) for c, s in self.plates()]

    def rest_poses(self) -> list[RestPose]:
        return _upright_lying(0.35, 0.0, [(rot_y(-np.pi / 2.0), 0.35), (rot_x(np.pi / 2.0), 0.15),
                                          (rot_x(-np.pi / 2.0), 0.15)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        return [_box_family(make_pose(t=c), s, density) for c, s in self.plates()]


HOUSEHOLD_CLASSES: tuple[type[HouseholdShape], ...] = (Mug, Bottle, FootedBowl, Hammer, Banana, CClamp, Can, LBracket)
