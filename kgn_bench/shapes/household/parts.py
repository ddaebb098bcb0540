"""Part builders of the household objects: boxes, cylinders and tapered capsules as MuJoCo geoms
(``GeomSpec``) and as watertight meshes, placed in the object frame.

A part is given by object-frame points and sizes in metres; ``z_to`` is the rotation that turns a part's own
+z axis onto a direction (cylinders and capsules are built along +z, then turned). ``concatenate`` joins part
meshes without merging them, so a whole made of closed parts stays watertight.
"""

from __future__ import annotations

import numpy as np
import trimesh

from kgn_bench.geometry import frame_from_xz, make_pose, quat_wxyz_from_matrix
from kgn_bench.shapes.base import GeomSpec
from kgn_bench.shapes.meshes import arc, revolve_profile

__all__ = ["AXES", "box", "box_mesh", "concatenate", "cylinder", "cylinder_mesh", "tapered_capsule", "unit", "z_to"]

AXES = np.eye(3)
"""The object frame's unit axes e_x, e_y, e_z as rows."""
_CAPSULE_SECTIONS = 20


def unit(v: np.ndarray) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def z_to(direction: np.ndarray) -> np.ndarray:
    """A rotation taking +z to ``direction`` (any twist about it)."""
    z = unit(direction)
    helper = AXES[0] if abs(z[0]) < 0.9 else AXES[1]
    x = unit(np.cross(helper, z))
    return frame_from_xz(x, z)


def box(centre, size, R: np.ndarray | None = None) -> GeomSpec:
    """A box of full extents ``size`` at ``centre``, rotated by ``R``."""
    q = (1.0, 0.0, 0.0, 0.0) if R is None else tuple(float(v) for v in quat_wxyz_from_matrix(R))
    return GeomSpec("box", tuple(float(s) / 2.0 for s in size), pos=tuple(float(c) for c in centre), quat=q)


def box_mesh(centre, size, R: np.ndarray | None = None) -> trimesh.Trimesh:
    return trimesh.creation.box(extents=size, transform=make_pose(R, np.asarray(centre, dtype=float)))


def cylinder(p0, p1, r: float) -> GeomSpec:
    """A solid cylinder of radius ``r`` from ``p0`` to ``p1``."""
    p0, p1 = np.asarray(p0, dtype=float), np.asarray(p1, dtype=float)
    R = z_to(p1 - p0)
    return GeomSpec("cylinder", (r, float(np.linalg.norm(p1 - p0)) / 2.0), pos=tuple(0.5 * (p0 + p1)),
                    quat=tuple(float(v) for v in quat_wxyz_from_matrix(R)))


def cylinder_mesh(p0, p1, r: float, sections: int = 32) -> trimesh.Trimesh:
    return trimesh.creation.cylinder(radius=r, segment=np.array([p0, p1], dtype=float), sections=sections)


def tapered_capsule(p0, r0: float, p1, r1: float) -> trimesh.Trimesh:
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
    mesh.apply_transform(make_pose(z_to(p1 - p0), p0))
    return mesh


def concatenate(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """The parts as one mesh (not merged: each part stays closed, so the whole is watertight)."""
    return trimesh.util.concatenate(meshes)

