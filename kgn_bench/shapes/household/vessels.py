"""The household objects of revolution, hollow or solid: mug, bottle, footed bowl and can. Each class states
its object frame, its parts, its grasp families (object frame, ``shapes.household.families``) and its rest
poses."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import trimesh

from kgn_bench.geometry import make_pose, rot_x, rot_y
from kgn_bench.shapes.base import GeomSpec, GraspDensity, RestPose
from kgn_bench.shapes.household.base import HouseholdShape, upright_lying
from kgn_bench.shapes.household.families import PINCH_CLEARANCE, on_axis, tube_family
from kgn_bench.shapes.household.parts import concatenate, cylinder, tapered_capsule
from kgn_bench.shapes.meshes import revolve_profile
from kgn_bench.shapes.primitives import _BOTTOM, _TOP, SemiSphere, _annulus_boxes, _revolved_family, _side_family

__all__ = ["Bottle", "Can", "FootedBowl", "Mug"]


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
        return [tapered_capsule(p[k], r, p[k + 1], r) for k in range(len(p) - 1)]

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
        return concatenate([cup, *self._handle_pieces()])

    def collision_geoms(self) -> list[GeomSpec]:
        hh = self.h / 2.0
        wall = _annulus_boxes(self.r_in, self.r_out, self.h)
        bottom = cylinder((0, 0, -hh), (0, 0, -hh + self.BOTTOM), self.r_in + self.WALL / 2.0)
        return [*wall, bottom, *(GeomSpec("mesh", mesh=m) for m in self._handle_pieces())]

    def rest_poses(self) -> list[RestPose]:
        return upright_lying(0.5, 0.1, [(rot_y(-np.pi / 2.0), 0.2), (rot_x(np.pi / 2.0), 0.2)])

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
        handle = tube_family(self.handle_points(phi), tangents, normals, np.full(len(phi), self.HANDLE_RADIUS),
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
        return [cylinder((0, 0, zb), (0, 0, z1), self.r), GeomSpec("mesh", mesh=shoulder),
                cylinder((0, 0, z2 - 0.001), (0, 0, z3), self.r_neck), cylinder((0, 0, z3), (0, 0, top), self.r_cap)]

    def rest_poses(self) -> list[RestPose]:
        return upright_lying(0.3, 0.0, [(rot_y(-np.pi / 2.0), 0.7)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        zb, z1, z2, z3, top = self.levels()
        body = _side_family(z1 - zb, density)
        neck_density = GraspDensity(max(1, (density.translations + 1) // 2), density.angles)
        neck = on_axis(_side_family(z3 - z2, neck_density), (z2 + z3) / 2.0)
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
        return concatenate([self.bowl.mesh(), ring])

    def collision_geoms(self) -> list[GeomSpec]:
        ri, ro, bottom, top = self.foot()
        foot = _annulus_boxes(ri, ro, top - bottom, z=(top + bottom) / 2.0, segments=16)
        return [*self.bowl.collision_geoms(), *foot]

    def rest_poses(self) -> list[RestPose]:
        return upright_lying(0.8, 0.2, [])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        angles = density.angle_samples()
        bowl = self.bowl
        ri, ro, bottom, _ = self.foot()
        rim = _revolved_family(make_pose(_TOP, ((self.r + bowl.r_in) / 2.0, 0.0, -self.RIM_SINK_IN)), angles)
        foot = _revolved_family(make_pose(_BOTTOM, ((ri + ro) / 2.0, 0.0, bottom + self.FOOT_SINK_IN)), angles)
        return [(rim, np.full(len(rim), self.r - bowl.r_in + PINCH_CLEARANCE)),
                (foot, np.full(len(foot), self.FOOT_WALL + PINCH_CLEARANCE))]


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
        return [cylinder((0, 0, -hh + b), (0, 0, hh - s), r), cylinder((0, 0, -hh), (0, 0, -hh + b + 0.001), r - b),
                cylinder((0, 0, hh - s - 0.001), (0, 0, hh), r - i)]

    def rest_poses(self) -> list[RestPose]:
        return upright_lying(0.35, 0.15, [(rot_y(-np.pi / 2.0), 0.5)])

    def _families(self, density: GraspDensity) -> list[tuple[np.ndarray, np.ndarray]]:
        hh, angles = self.h / 2.0, density.angle_samples()
        lo, hi = -hh + self.BEVEL, hh - self.SHOULDER
        body = on_axis(_side_family(hi - lo, density), (lo + hi) / 2.0)
        top = _revolved_family(make_pose(_TOP, (0.0, 0.0, hh - self.END_SINK_IN)), angles)
        bottom = _revolved_family(make_pose(_BOTTOM, (0.0, 0.0, -hh + self.END_SINK_IN)), angles)
        poses = np.concatenate([body, top, bottom])
        return [(poses, np.full(len(poses), 2.0 * self.r + PINCH_CLEARANCE))]
