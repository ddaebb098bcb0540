"""The household objects made of straight and curved bars and plates: hammer, banana, C-clamp and L-bracket.
Each class states its object frame, its parts, its grasp families (object frame,
``shapes.household.families``) and its rest poses."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import trimesh

from kgn_bench.geometry import make_pose, rot_x, rot_y
from kgn_bench.shapes.base import GeomSpec, GraspDensity, RestPose
from kgn_bench.shapes.household.base import HouseholdShape, upright_lying
from kgn_bench.shapes.household.families import MIN_APPROACH_EXTENT, box_family, tube_family
from kgn_bench.shapes.household.parts import AXES, box, box_mesh, concatenate, cylinder, cylinder_mesh, tapered_capsule

__all__ = ["Banana", "CClamp", "Hammer", "LBracket"]


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
        return concatenate([cylinder_mesh(p0, p1, self.r_handle), box_mesh(p1, self._head_size())])

    def collision_geoms(self) -> list[GeomSpec]:
        p0, p1 = self._handle_ends()
        return [cylinder(p0, p1, self.r_handle), box(p1, self._head_size())]

    def rest_poses(self) -> list[RestPose]:
        return upright_lying(0.5, 0.5, [])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        p0, p1 = self._handle_ends()
        xs = np.linspace(p0[0] + 0.01, p1[0] - self.head_side / 2.0 - 0.01, density.translations)
        centres = np.stack([xs, np.zeros_like(xs), np.zeros_like(xs)], axis=1)
        handle = tube_family(centres, np.tile(AXES[0], (len(xs), 1)), np.tile(AXES[2], (len(xs), 1)),
                              np.full(len(xs), self.r_handle), density.angle_samples())
        return [handle, box_family(make_pose(t=p1), self._head_size(), density)]


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
            cached = [tapered_capsule(p[k], r[k], p[k + 1], r[k + 1]) for k in range(self.SEGMENTS)]
            object.__setattr__(self, "_pieces_cache", cached)
        return cached

    def volume(self) -> float:
        """The capsules' volumes minus the joint spheres each two of them share."""
        r = self.radius_at(np.linspace(0.0, 1.0, self.SEGMENTS + 1))[1:-1]
        return float(sum(m.volume for m in self._pieces()) - np.sum(4.0 / 3.0 * np.pi * r**3))

    def _build_mesh(self) -> trimesh.Trimesh:
        return concatenate(self._pieces())

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
        return [tube_family(pts, tan, np.tile(AXES[2], (n, 1)), self.radius_at(s), density.angle_samples())]


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
        parts = [box_mesh(c, s) for c, s in self.bars()]
        return concatenate(parts + [cylinder_mesh(p0, p1, r, 24) for _, p0, p1, r in self._screw()])

    def collision_geoms(self) -> list[GeomSpec]:
        return [box(c, s) for c, s in self.bars()] + [cylinder(p0, p1, r) for _, p0, p1, r in self._screw()]

    def rest_poses(self) -> list[RestPose]:
        return upright_lying(0.4, 0.4, [(rot_y(-np.pi / 2.0), 0.2)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        return [box_family(make_pose(t=c), s, density) for c, s in self.bars()]


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
        return concatenate([box_mesh(c, s) for c, s in self.plates()])

    def collision_geoms(self) -> list[GeomSpec]:
        return [box(c, s) for c, s in self.plates()]

    def rest_poses(self) -> list[RestPose]:
        return upright_lying(0.35, 0.0, [(rot_y(-np.pi / 2.0), 0.35), (rot_x(np.pi / 2.0), 0.15),
                                          (rot_x(-np.pi / 2.0), 0.15)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        return [box_family(make_pose(t=c), s, density) for c, s in self.plates()]
