"""Antipodal grasp candidates on any mesh, before the physics check (``sim.grasp_verify``).

For a surface point ``p`` with outward normal ``n_p``, the ray from ``p`` along ``−n_p`` leaves the solid at
``q`` (outward normal ``n_q``). The pair is antipodal when the closing axis ``a = (q − p)/|q − p|`` lies in both
friction cones: ``∠(−n_p, a) ≤ θ`` and ``∠(n_q, a) ≤ θ``, with half-angle ``θ = friction_cone_deg``
(a margin under MuJoCo's ``atan μ`` = 45° for μ = 1). Its width is ``|q − p| + PINCH_CLEARANCE`` (the jaws
open 7.5 mm clear of each contact), which must fit the gripper.

Each pair gives ``approaches`` grasps about its closing axis: the grasp origin at the contact midpoint
``c = (p + q)/2``, the closing axis ``z = a``, the approach ``x = cos β·u + sin β·(a × u)`` for evenly spaced
β (from a random phase) and a unit ``u ⟂ a``. Grasps whose gripper, swept over its approach and its closing,
would run into the object itself are dropped (``shapes.household.gripper_sweep_free``). Everything is in the
mesh's (object) frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from kgn_bench.geometry import frame_from_xz
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.household import PINCH_CLEARANCE, gripper_sweep_free

__all__ = ["SamplingConfig", "antipodal_pairs", "sample_antipodal_grasps"]


@dataclass(frozen=True)
class SamplingConfig:
    """How many candidates to draw: ``points`` surface samples, ``approaches`` per antipodal pair, friction
    cone half-angle ``friction_cone_deg``, the smallest pinched extent ``min_extent`` (m)."""

    points: int = 600
    approaches: int = 8
    friction_cone_deg: float = 20.0
    min_extent: float = 0.004


def antipodal_pairs(mesh: trimesh.Trimesh, rng: np.random.Generator, config: SamplingConfig = SamplingConfig()
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Antipodal contact pairs ``(p, q)`` as two (M, 3) arrays (object frame); see the module doc."""
    points, faces = trimesh.sample.sample_surface(mesh, config.points, seed=int(rng.integers(2**31)))
    normals = mesh.face_normals[faces]
    origins = points - 1e-5 * normals
    hits, rays, tri = mesh.ray.intersects_location(origins, -normals, multiple_hits=False)
    if len(rays) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    p, n_p = points[rays], normals[rays]
    q, n_q = hits, mesh.face_normals[tri]
    span = q - p
    d = np.linalg.norm(span, axis=1)
    a = span / np.maximum(d, 1e-12)[:, None]
    cos_t = np.cos(np.deg2rad(config.friction_cone_deg))
    ok = ((d >= config.min_extent) & (d + PINCH_CLEARANCE <= GRIPPER.max_width)
          & (np.einsum("ij,ij->i", -n_p, a) >= cos_t) & (np.einsum("ij,ij->i", n_q, a) >= cos_t))
    return p[ok], q[ok]


def _perpendicular(a: np.ndarray) -> np.ndarray:
    """Unit vectors (M, 3) perpendicular to unit ``a`` (M, 3)."""
    ref = np.where(np.abs(a[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    u = np.cross(a, ref)
    return u / np.linalg.norm(u, axis=1, keepdims=True)


def sample_antipodal_grasps(mesh: trimesh.Trimesh, rng: np.random.Generator,
                            config: SamplingConfig = SamplingConfig(),
                            surface: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Candidate grasps ``(poses (N, 4, 4), widths (N,))`` on ``mesh`` whose gripper sweep is free of the
    object's ``surface`` points (default: 4000 points sampled on the mesh)."""
    p, q = antipodal_pairs(mesh, rng, config)
    if len(p) == 0:
        return np.zeros((0, 4, 4)), np.zeros(0)
    span = q - p
    d = np.linalg.norm(span, axis=1)
    a = span / d[:, None]
    u = _perpendicular(a)
    v = np.cross(a, u)
    k = config.approaches
    beta = rng.uniform(0.0, 2.0 * np.pi, len(p))[:, None] + 2.0 * np.pi * np.arange(k)[None] / k  # (M, k)
    x = np.cos(beta)[..., None] * u[:, None] + np.sin(beta)[..., None] * v[:, None]  # (M, k, 3)
    z = np.broadcast_to(a[:, None], x.shape)
    poses = np.tile(np.eye(4), (len(p) * k, 1, 1))
    poses[:, :3, :3] = frame_from_xz(x.reshape(-1, 3), z.reshape(-1, 3))
    poses[:, :3, 3] = np.repeat((p + q) / 2.0, k, axis=0)
    widths = np.repeat(d + PINCH_CLEARANCE, k)
    if surface is None:
        surface = trimesh.sample.sample_surface(mesh, 4000, seed=int(rng.integers(2**31)))[0]
    keep = gripper_sweep_free(surface, poses, widths)
    return poses[keep], widths[keep]
