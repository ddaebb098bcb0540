"""The six Primitive Shape (PS) objects with their reference size ranges and grasp families.

Sizes, widths and sink-in depths follow the reference implementation's PS dataset; angles are unique
samples over [0, 2π) (the reference's ``linspace(0, 2π, N)`` repeats 0 at 2π). ``R_z(θ)`` is a rotation
about the object's z axis. The helpers ``_top``/``_bottom``/``_side`` are the family orientations of the
reference:

* top:    ``axis_align(−3, 2, 1)``: approach −Z (down), y = +Y, closing along +X;
* bottom: ``axis_align(3, −2, 1)``: approach +Z (up), y = −Y, closing along +X;
* side:   ``axis_align(1, −3, 2)``: approach +X (radially inward), y = −Z, closing along +Y.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import trimesh

from kgn_bench.geometry import axis_align, frame_from_xz, make_pose, quat_wxyz_from_matrix, rot_x, rot_y, rot_z
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes.base import GeomSpec, GraspDensity, RestPose, Shape
from kgn_bench.shapes.meshes import arc, revolve_profile

__all__ = ["WALL_RATIO", "Cuboid", "Cylinder", "Ring", "SemiSphere", "Sphere", "Stick"]

WALL_RATIO = 1.15
"""Outer over inner radius of the hollow tube, ring and bowl (the reference implementation's value)."""

_TOP = axis_align((-3, 2, 1))
_BOTTOM = axis_align((3, -2, 1))
_SIDE = axis_align((1, -3, 2))
_LYING = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
"""Rest orientation of an axisymmetric object on its side: object z → world +x, object x → world −z.

With the object's +x pointing down, the side family's θ = 0 member approaches from straight above:
this is the reference implementation's stick rectification (a lying stick is turned about its own axis so
that its side family holds an exact top-down grasp), expressed for unique angles."""

_REVOLVE_SECTIONS = 48


def _uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(rng.uniform(lo, hi))


def _positive(dims: dict, key: str) -> float:
    try:
        v = float(dims[key])
    except (KeyError, TypeError, ValueError):
        raise ValueError(f"missing or non-numeric dimension {key!r} in {dims}") from None
    if not (np.isfinite(v) and v > 0.0):
        raise ValueError(f"dimension {key!r} must be a positive number, got {dims[key]!r}")
    return v


def _disc_solid_angle(radius: float, distance: float) -> float:
    """Solid angle (sr) of a disc of ``radius`` seen from ``distance`` on its axis."""
    return 2.0 * np.pi * (1.0 - distance / np.hypot(distance, radius))


def _rect_solid_angle(a: float, b: float, distance: float) -> float:
    """Solid angle (sr) of an a×b rectangle seen from ``distance`` on its central normal."""
    return 4.0 * np.arcsin(a * b / np.sqrt((a * a + 4 * distance**2) * (b * b + 4 * distance**2)))


def _revolved_family(base: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Poses ``R_z(θ) @ base`` for each angle θ: (N, 4, 4)."""
    rz = np.zeros((len(angles), 4, 4))
    rz[:, :3, :3] = rot_z(angles)
    rz[:, 3, 3] = 1.0
    return rz @ base


def _annulus_boxes(r_in: float, r_out: float, height: float, z: float = 0.0, segments: int = 24) -> list[GeomSpec]:
    """A hollow annulus as ``segments`` boxes around the wall: really hollow inside ``r_in``."""
    t = r_out - r_in
    r_mid = 0.5 * (r_in + r_out)
    half_len = r_out * np.tan(np.pi / segments)
    geoms = []
    for k in range(segments):
        phi = 2.0 * np.pi * k / segments
        geoms.append(
            GeomSpec(
                "box",
                (t / 2.0, half_len, height / 2.0),
                pos=(r_mid * np.cos(phi), r_mid * np.sin(phi), z),
                quat=(np.cos(phi / 2.0), 0.0, 0.0, np.sin(phi / 2.0)),
            )
        )
    return geoms


def _axisymmetric_rest_poses(cap_radius: float, height: float) -> list[RestPose]:
    """Upright, upside-down and lying orientations of a solid of revolution, weighted by the solid
    angle their support face subtends from the centre (a quasi-static estimate)."""
    cap = _disc_solid_angle(cap_radius, height / 2.0) / (4.0 * np.pi)
    return [
        RestPose(np.eye(3), cap),
        RestPose(rot_x(np.pi), cap),
        RestPose(_LYING, 1.0 - 2.0 * cap),
    ]


@dataclass(frozen=True)
class Cuboid(Shape):
    """Box of extents ``size`` = (x, y, z), each ~U[0.04, 0.12] m; object frame at its centre."""

    size: tuple[float, float, float]

    name: ClassVar[str] = "cuboid"
    SIZE_RANGE: ClassVar[tuple[float, float]] = (0.04, 0.12)
    SINK_IN: ClassVar[float] = 0.02
    WIDTH_FACTOR: ClassVar[float] = 1.2

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Cuboid:
        return cls(tuple(float(v) for v in rng.uniform(*cls.SIZE_RANGE, size=3)))

    @classmethod
    def from_dims(cls, dims: dict) -> Cuboid:
        size = dims.get("size")
        if not isinstance(size, (list, tuple)) or len(size) != 3:
            raise ValueError(f"cuboid needs 'size' = [x, y, z], got {dims}")
        return cls(tuple(_positive({"size": v}, "size") for v in size))

    def dims(self) -> dict:
        return {"size": list(self.size)}

    def volume(self) -> float:
        return float(np.prod(self.size))

    def _build_mesh(self) -> trimesh.Trimesh:
        return trimesh.creation.box(extents=self.size)

    def collision_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("box", tuple(s / 2.0 for s in self.size))]

    def rest_poses(self) -> list[RestPose]:
        x, y, z = self.size
        faces = [
            (np.eye(3), _rect_solid_angle(x, y, z / 2)),  # −Z face down
            (rot_x(np.pi), _rect_solid_angle(x, y, z / 2)),  # +Z face down
            (rot_y(-np.pi / 2), _rect_solid_angle(y, z, x / 2)),  # −X face down
            (rot_y(np.pi / 2), _rect_solid_angle(y, z, x / 2)),  # +X face down
            (rot_x(np.pi / 2), _rect_solid_angle(x, z, y / 2)),  # −Y face down
            (rot_x(-np.pi / 2), _rect_solid_angle(x, z, y / 2)),  # +Y face down
        ]
        total = sum(w for _, w in faces)
        return [RestPose(R, w / total) for R, w in faces]

    def grasps(self, density: GraspDensity) -> GraspSet:
        """Approach along ±X, ±Y or ±Z, closing along one of the two other (positive) axes.

        The fingertip midpoint sinks ``SINK_IN`` = 2 cm inside the face the gripper enters through, sits
        at ``(−½ + (i+1)/(N+1))·d_y`` along the grasp's y axis (N = translations) and at 0 along the
        closing axis; width = 1.2 × the extent along the closing axis.
        """
        n = density.translations
        d = np.asarray(self.size)
        fractions = -0.5 + (np.arange(n) + 1.0) / (n + 1.0)
        poses, widths = [], []
        for app in range(3):
            for sign in (1.0, -1.0):
                x_g = sign * np.eye(3)[app]
                for close in (a for a in range(3) if a != app):
                    z_g = np.eye(3)[close]
                    R = frame_from_xz(x_g, z_g)
                    y_g = R[:, 1]
                    y_axis = int(np.argmax(np.abs(y_g)))
                    for f in fractions:
                        t = -sign * (d[app] / 2.0 - self.SINK_IN) * np.eye(3)[app]
                        t = t + f * d[y_axis] * y_g
                        poses.append(make_pose(R, t))
                        widths.append(self.WIDTH_FACTOR * d[close])
        return GraspSet.unlabelled(np.stack(poses), np.array(widths))


@dataclass(frozen=True)
class Cylinder(Shape):
    """Hollow tube, inner radius ``r_in`` ~U[0.03, 0.07] m, outer 1.15·r_in, height ``h`` ~U[0.05, 0.10] m.

    Object frame at the centre, axis along z, the wall spans z ∈ [−h/2, h/2].
    """

    r_in: float
    h: float

    name: ClassVar[str] = "cylinder"
    axisymmetric: ClassVar[bool] = True
    R_RANGE: ClassVar[tuple[float, float]] = (0.03, 0.07)
    H_RANGE: ClassVar[tuple[float, float]] = (0.05, 0.10)
    RIM_SINK_IN: ClassVar[float] = 0.005
    RIM_WIDTH_FACTOR: ClassVar[float] = 5.0
    SIDE_WIDTH_FACTOR: ClassVar[float] = 2.4
    HAS_SIDE_FAMILY: ClassVar[bool] = True
    SEGMENTS: ClassVar[int] = 24

    @classmethod
    def sample(cls, rng: np.random.Generator):
        return cls(_uniform(rng, *cls.R_RANGE), _uniform(rng, *cls.H_RANGE))

    @classmethod
    def from_dims(cls, dims: dict):
        return cls(_positive(dims, "r_in"), _positive(dims, "h"))

    def dims(self) -> dict:
        return {"r_in": self.r_in, "h": self.h}

    @property
    def r_out(self) -> float:
        return WALL_RATIO * self.r_in

    def volume(self) -> float:
        return float(np.pi * (self.r_out**2 - self.r_in**2) * self.h)

    def _build_mesh(self) -> trimesh.Trimesh:
        hh = self.h / 2.0
        profile = np.array([[self.r_in, -hh], [self.r_out, -hh], [self.r_out, hh], [self.r_in, hh]])
        return revolve_profile(profile, _REVOLVE_SECTIONS)

    def visual_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("mesh", mesh=self.mesh())]

    def collision_geoms(self) -> list[GeomSpec]:
        return _annulus_boxes(self.r_in, self.r_out, self.h, segments=self.SEGMENTS)

    def rest_poses(self) -> list[RestPose]:
        return _axisymmetric_rest_poses(self.r_out, self.h)

    def rim_width(self) -> float:
        return self.RIM_WIDTH_FACTOR * (self.r_out - self.r_in)

    def side_width(self) -> float:
        return self.SIDE_WIDTH_FACTOR * self.r_out

    def grasps(self, density: GraspDensity) -> GraspSet:
        """Rim grasps from the top and from the bottom and, for tubes, side grasps across the body.

        Rim: fingertip midpoint in the middle of the wall (radius (r_in + r_out)/2), 5 mm inside the end
        face, closing radially, width 5·(r_out − r_in), one per angle. Side: fingertip midpoint on the
        axis at N heights ``linspace(−h/2, h/2, N+2)[1:−1]``, approach radial, closing horizontal,
        width 2.4·r_out.
        """
        angles = density.angle_samples()
        r_mid = 0.5 * (self.r_in + self.r_out)
        hh = self.h / 2.0
        top = make_pose(_TOP, (r_mid, 0.0, hh - self.RIM_SINK_IN))
        bottom = make_pose(_BOTTOM, (r_mid, 0.0, -hh + self.RIM_SINK_IN))
        poses = [_revolved_family(top, angles), _revolved_family(bottom, angles)]
        widths = [np.full(2 * len(angles), self.rim_width())]
        if self.HAS_SIDE_FAMILY:
            poses.append(_side_family(self.h, density))
            widths.append(np.full(len(poses[-1]), self.side_width()))
        return GraspSet.unlabelled(np.concatenate(poses), np.concatenate(widths))


def _side_family(h: float, density: GraspDensity) -> np.ndarray:
    """Side grasps of a solid of revolution: ``[R_z(θ) | (0, 0, z)] · side`` for N heights × angles."""
    heights = np.linspace(-h / 2.0, h / 2.0, density.translations + 2)[1:-1]
    poses = []
    for z in heights:
        poses.append(_revolved_family(make_pose(_SIDE, (0.0, 0.0, z)), density.angle_samples()))
    return np.concatenate(poses)


@dataclass(frozen=True)
class Ring(Cylinder):
    """Flat ring: the tube's annulus with ``r_in`` ~U[0.02, 0.05] m and ``h`` ~U[0.008, 0.024] m; rim
    grasps only."""

    name: ClassVar[str] = "ring"
    R_RANGE: ClassVar[tuple[float, float]] = (0.02, 0.05)
    H_RANGE: ClassVar[tuple[float, float]] = (0.008, 0.024)
    HAS_SIDE_FAMILY: ClassVar[bool] = False


@dataclass(frozen=True)
class Stick(Shape):
    """Solid rod of radius ``r_in`` ~U[0.005, 0.01] m and height ``h`` ~U[0.05, 0.10] m, axis along z."""

    r_in: float
    h: float

    name: ClassVar[str] = "stick"
    axisymmetric: ClassVar[bool] = True
    R_RANGE: ClassVar[tuple[float, float]] = (0.005, 0.01)
    H_RANGE: ClassVar[tuple[float, float]] = (0.05, 0.10)

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Stick:
        return cls(_uniform(rng, *cls.R_RANGE), _uniform(rng, *cls.H_RANGE))

    @classmethod
    def from_dims(cls, dims: dict) -> Stick:
        return cls(_positive(dims, "r_in"), _positive(dims, "h"))

    def dims(self) -> dict:
        return {"r_in": self.r_in, "h": self.h}

    def volume(self) -> float:
        return float(np.pi * self.r_in**2 * self.h)

    def _build_mesh(self) -> trimesh.Trimesh:
        hh = self.h / 2.0
        return revolve_profile(np.array([[0.0, -hh], [self.r_in, -hh], [self.r_in, hh], [0.0, hh]]), 32)

    def collision_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("cylinder", (self.r_in, self.h / 2.0))]

    def rest_poses(self) -> list[RestPose]:
        return _axisymmetric_rest_poses(self.r_in, self.h)

    def grasps(self, density: GraspDensity) -> GraspSet:
        """Side grasps only, on the axis; width 2.4·r_out with the reference's r_out = 1.15·r_in."""
        poses = _side_family(self.h, density)
        return GraspSet.unlabelled(poses, np.full(len(poses), 2.4 * WALL_RATIO * self.r_in))


@dataclass(frozen=True)
class Sphere(Shape):
    """Solid sphere of radius ``r`` ~U[0.02, 0.05] m; object frame at its centre."""

    r: float

    name: ClassVar[str] = "sphere"
    R_RANGE: ClassVar[tuple[float, float]] = (0.02, 0.05)

    @classmethod
    def sample(cls, rng: np.random.Generator) -> Sphere:
        return cls(_uniform(rng, *cls.R_RANGE))

    @classmethod
    def from_dims(cls, dims: dict) -> Sphere:
        return cls(_positive(dims, "r"))

    def dims(self) -> dict:
        return {"r": self.r}

    def volume(self) -> float:
        return float(4.0 / 3.0 * np.pi * self.r**3)

    def _build_mesh(self) -> trimesh.Trimesh:
        return trimesh.creation.icosphere(subdivisions=3, radius=self.r)

    def collision_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("sphere", (self.r,))]

    def rest_poses(self) -> list[RestPose]:
        return [RestPose(np.eye(3), 1.0)]

    def grasps(self, density: GraspDensity) -> GraspSet:
        """Top (approach down) and side (horizontal approach and closing) families through the centre,
        one grasp per angle each; width 2.4·r."""
        angles = density.angle_samples()
        poses = np.concatenate([_revolved_family(make_pose(_TOP), angles), _revolved_family(make_pose(_SIDE), angles)])
        return GraspSet.unlabelled(poses, np.full(len(poses), 2.4 * self.r))


@dataclass(frozen=True)
class SemiSphere(Shape):
    """Hollow hemispherical bowl, outer radius ``r`` ~U[0.04, 0.08] m, inner r/1.15, opening up.

    Object frame at the sphere centre: the shell spans z ∈ [−r, 0] and the rim lies at z = 0.
    """

    r: float

    name: ClassVar[str] = "semi_sphere"
    R_RANGE: ClassVar[tuple[float, float]] = (0.04, 0.08)
    RIM_SINK_IN: ClassVar[float] = 0.002
    BANDS: ClassVar[int] = 4
    SECTORS: ClassVar[int] = 16

    @classmethod
    def sample(cls, rng: np.random.Generator) -> SemiSphere:
        return cls(_uniform(rng, *cls.R_RANGE))

    @classmethod
    def from_dims(cls, dims: dict) -> SemiSphere:
        return cls(_positive(dims, "r"))

    def dims(self) -> dict:
        return {"r": self.r}

    @property
    def r_in(self) -> float:
        return self.r / WALL_RATIO

    def volume(self) -> float:
        return float(2.0 / 3.0 * np.pi * (self.r**3 - self.r_in**3))

    def _build_mesh(self) -> trimesh.Trimesh:
        outer = arc(self.r, 0.0, np.pi / 2.0, 17)
        inner = arc(self.r_in, np.pi / 2.0, 0.0, 17)
        return revolve_profile(np.concatenate([outer, inner]), _REVOLVE_SECTIONS)

    def visual_geoms(self) -> list[GeomSpec]:
        return [GeomSpec("mesh", mesh=self.mesh())]

    def collision_geoms(self) -> list[GeomSpec]:
        """Shell of ``BANDS × SECTORS`` boxes, each tangent to the mid-wall sphere: really hollow."""
        t = self.r - self.r_in
        r_mid = 0.5 * (self.r + self.r_in)
        d_alpha = (np.pi / 2.0) / self.BANDS
        geoms = []
        for b in range(self.BANDS):
            alpha = (b + 0.5) * d_alpha
            half_merid = self.r * np.tan(d_alpha / 2.0)
            half_azim = self.r * np.sin((b + 1) * d_alpha) * np.tan(np.pi / self.SECTORS)
            for s in range(self.SECTORS):
                theta = 2.0 * np.pi * (s + 0.5 * (b % 2)) / self.SECTORS
                n = np.array([np.sin(alpha) * np.cos(theta), np.sin(alpha) * np.sin(theta), -np.cos(alpha)])
                e_theta = np.array([-np.sin(theta), np.cos(theta), 0.0])
                e_alpha = np.cross(n, e_theta)
                R = np.stack([n, e_theta, e_alpha], axis=1)
                geoms.append(
                    GeomSpec(
                        "box",
                        (t / 2.0, half_azim, half_merid),
                        pos=tuple(r_mid * n),
                        quat=tuple(quat_wxyz_from_matrix(R)),
                    )
                )
        return geoms

    def rest_poses(self) -> list[RestPose]:
        return [RestPose(np.eye(3), 1.0)]

    def rim_width(self) -> float:
        return 5.0 * (self.r - self.r_in)

    def grasps(self, density: GraspDensity) -> GraspSet:
        """Rim grasps from the top: mid-wall, 2 mm below the rim, closing radially; width 5·(r − r_in)."""
        r_mid = 0.5 * (self.r + self.r_in)
        base = make_pose(_TOP, (r_mid, 0.0, -self.RIM_SINK_IN))
        poses = _revolved_family(base, density.angle_samples())
        return GraspSet.unlabelled(poses, np.full(len(poses), self.rim_width()))
