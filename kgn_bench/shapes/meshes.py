"""Watertight meshes of revolution (tubes, rings, sticks, spheres, bowls) built with trimesh."""

from __future__ import annotations

import numpy as np
import trimesh

__all__ = ["arc", "revolve_profile"]


def arc(radius: float, start: float, stop: float, n: int) -> np.ndarray:
    """Profile points (ρ, z) on a circle of ``radius`` about the origin, polar angle from −z in [start, stop].

    The polar angle α is measured from the downward axis: ``ρ = r·sin α``, ``z = −r·cos α``.
    """
    a = np.linspace(start, stop, n)
    return np.stack([radius * np.sin(a), -radius * np.cos(a)], axis=1)


def revolve_profile(profile: np.ndarray, sections: int = 48) -> trimesh.Trimesh:
    """Revolve a closed profile (M, 2) of (ρ, z) points about the z axis into a watertight mesh.

    The profile is a closed loop traversed counter-clockwise in the (ρ, z) half-plane (the material on
    the left); consecutive points are joined and the last joins the first. Points with ρ = 0 lie on the
    axis and become single vertices, so solids of revolution close without holes.
    """
    profile = np.asarray(profile, dtype=float)
    if profile.ndim != 2 or profile.shape[1] != 2 or len(profile) < 3:
        raise ValueError("profile must be an (M ≥ 3, 2) array of (rho, z) points")
    theta = 2.0 * np.pi * np.arange(sections) / sections
    cos, sin = np.cos(theta), np.sin(theta)
    m = len(profile)
    on_axis = profile[:, 0] <= 1e-12
    verts, rings, start = [], [], 0
    for (rho, z), axis in zip(profile, on_axis):
        if axis:
            verts.append(np.array([[0.0, 0.0, z]]))
            rings.append(np.full(sections, start))
            start += 1
        else:
            verts.append(np.stack([rho * cos, rho * sin, np.full(sections, z)], axis=1))
            rings.append(start + np.arange(sections))
            start += sections
    k = np.arange(sections)
    k1 = np.roll(k, -1)
    faces = []
    for i in range(m):
        j = (i + 1) % m
        if on_axis[i] and on_axis[j]:
            continue
        a, b = rings[i], rings[j]
        tris = np.concatenate([np.stack([a[k], b[k], b[k1]], 1), np.stack([a[k], b[k1], a[k1]], 1)])
        keep = (tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])
        faces.append(tris[keep])
    mesh = trimesh.Trimesh(np.concatenate(verts), np.concatenate(faces), process=True)
    if mesh.volume < 0:
        mesh.invert()
    return mesh
