"""Antipodal grasp candidates on any mesh, before the physics check (``sim.grasp_verify``).

For a surface point ``p`` with outward normal ``n_p``, the ray from ``p`` along ``−n_p`` leaves the solid at
one or more points ``q`` (outward normal ``n_q``, ``n_q · (−n_p) > 0``): the first exit pinches the wall at
``p``, a later one spans the object across a hollow or a gap (the fingers touch only ``p`` and ``q``, and the
sweep filter drops a finger that would have to pass through the object). The pair is antipodal when the
closing axis ``a = (q − p)/|q − p|`` lies in both friction cones: ``∠(−n_p, a) ≤ θ`` and ``∠(n_q, a) ≤ θ``,
with half-angle ``θ = friction_cone_deg`` (a margin under MuJoCo's ``atan μ`` = 45° for μ = 1). Its width is
``|q − p| + PINCH_CLEARANCE`` (the jaws open 7.5 mm clear of each contact), which must fit the gripper.

Each pair gives ``approaches`` grasps about its closing axis: the grasp origin at the contact midpoint
``c = (p + q)/2``, the closing axis ``z = a``, the approach ``x = cos β·u + sin β·(a × u)`` for evenly spaced
β (from a random phase) and a unit ``u ⟂ a``. Grasps whose gripper, swept over its approach and its closing,
would run into the object itself are dropped (``shapes.household.families.gripper_sweep_free``). Everything is in the
mesh's (object) frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from kgn_bench.geometry import frame_from_xz
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.household.families import PINCH_CLEARANCE, gripper_sweep_free

__all__ = ["SamplingConfig", "antipodal_accepts", "antipodal_pairs", "diverse_subset", "sample_antipodal_grasps"]

_DIRECTIONS = np.array([d for d in np.ndindex(3, 3, 3) if d != (1, 1, 1)], dtype=float) - 1.0
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1, keepdims=True)
"""26 directions (cube faces, edges and corners) that bin closing axes and approaches."""


@dataclass(frozen=True)
class SamplingConfig:
    """How many candidates to draw: ``points`` surface samples, ``approaches`` per antipodal pair, friction
    cone half-angle ``friction_cone_deg``, the smallest pinched extent ``min_extent`` (m)."""

    points: int = 600
    approaches: int = 8
    friction_cone_deg: float = 20.0
    min_extent: float = 0.003


def antipodal_pairs(mesh: trimesh.Trimesh, rng: np.random.Generator, config: SamplingConfig = SamplingConfig()
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Antipodal contact pairs ``(p, q)`` as two (M, 3) arrays (object frame); see the module doc."""
    points, faces = trimesh.sample.sample_surface(mesh, config.points, seed=int(rng.integers(2**31)))
    normals = mesh.face_normals[faces]
    origins = points - 1e-5 * normals
    hits, rays, tri = mesh.ray.intersects_location(origins, -normals, multiple_hits=True)
    if len(rays) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    exits = np.einsum("ij,ij->i", mesh.face_normals[tri], -normals[rays]) > 0.0
    hits, rays, tri = hits[exits], rays[exits], tri[exits]
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
                            surface: np.ndarray | None = None, toward: np.ndarray | None = None,
                            spread_deg: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    """Candidate grasps ``(poses (N, 4, 4), widths (N,))`` on ``mesh`` whose gripper sweep is free of the
    object's ``surface`` points (default: 4000 points sampled on the mesh).

    ``toward`` (a unit direction, object frame) aims the approaches instead of spreading them round the
    closing axis: each pair's ``approaches`` grasps turn ``β ∈ [−spread_deg, spread_deg]`` (evenly) from
    ``u`` = the direction's part perpendicular to the pair's axis, normalised; pairs whose axis is within 30° of
    the direction cannot approach along it and are skipped. ``toward = R⁻¹ (0, 0, −1)`` asks for grasps from
    above an object resting in the rotation ``R`` (``objects.coverage``)."""
    p, q = antipodal_pairs(mesh, rng, config)
    if len(p) == 0:
        return np.zeros((0, 4, 4)), np.zeros(0)
    span = q - p
    d = np.linalg.norm(span, axis=1)
    a = span / d[:, None]
    k = config.approaches
    if toward is None:
        u = _perpendicular(a)
        beta = rng.uniform(0.0, 2.0 * np.pi, len(p))[:, None] + 2.0 * np.pi * np.arange(k)[None] / k  # (M, k)
    else:
        t = np.asarray(toward, dtype=float) / np.linalg.norm(toward)
        along = a @ t
        aimed = np.abs(along) < np.cos(np.deg2rad(30.0))
        p, q, a, d, along = p[aimed], q[aimed], a[aimed], d[aimed], along[aimed]
        if len(p) == 0:
            return np.zeros((0, 4, 4)), np.zeros(0)
        u = t[None] - along[:, None] * a
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        beta = np.broadcast_to(np.deg2rad(np.linspace(-spread_deg, spread_deg, k))[None], (len(p), k))
    v = np.cross(a, u)
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


def diverse_subset(poses: np.ndarray, count: int, rng: np.random.Generator) -> np.ndarray:
    """Indices (sorted) of ``count`` of ``poses`` (N, 4, 4) spread over grasp directions: each grasp is binned
    by its closing axis (the nearest of 13 sign-free directions) and its approach (the nearest of 26), and the
    bins are drawn from in turn, in random order, each bin's grasps in random order.

    A uniform draw would follow the surface area: on a flat object most antipodal pairs close across its
    thickness, and a grasp that closes vertically on an object lying flat puts a finger into the table, so
    that object would end up with few grasps a robot can use."""
    n = len(poses)
    if n <= count:
        return np.arange(n)
    closing = np.argmax(np.abs(poses[:, :3, 2] @ _DIRECTIONS.T), axis=1)
    closing = np.minimum(closing, 25 - closing)  # d and −d share a bin (the list is symmetric about its middle)
    approach = np.argmax(poses[:, :3, 0] @ _DIRECTIONS.T, axis=1)
    bins: dict[int, list[int]] = {}
    for i in rng.permutation(n):
        bins.setdefault(int(closing[i]) * 26 + int(approach[i]), []).append(int(i))
    queues = [bins[k] for k in rng.permutation(sorted(bins))]
    picked: list[int] = []
    while len(picked) < count:
        for q in queues:
            if q and len(picked) < count:
                picked.append(q.pop())
    return np.sort(np.asarray(picked))


def antipodal_accepts(mesh: trimesh.Trimesh, poses: np.ndarray, widths: np.ndarray,
                      config: SamplingConfig = SamplingConfig(), surface: np.ndarray | None = None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """The labeller's geometric test applied to given grasps ``poses`` (N, 4, 4, object frame) of ``widths``:
    each jaw, closing along the grasp's ``z`` through its origin from the executor's opening
    ``GRIPPER.opening(w)``, first touches the surface at ``p`` (from ``−z``) and ``q`` (from ``+z``). The grasp
    passes when both contacts exist, the pinched extent ``d = (q − p)·z`` is at least ``min_extent`` and its
    width ``d + PINCH_CLEARANCE`` fits the gripper, both normals lie in the friction cone of the closing axis
    (module doc), and the gripper sweep at that width is free. A candidate of ``sample_antipodal_grasps`` has
    passed exactly this test, so it says whether the labeller would accept a grasp that came from elsewhere (a
    closed-form family), and with what width. Returns ``(accepted (N,) bool, labeller widths (N,))``."""
    n = len(poses)
    if n == 0:
        return np.zeros(0, dtype=bool), np.zeros(0)
    z, c = poses[:, :3, 2], poses[:, :3, 3]
    half = (np.asarray(GRIPPER.opening(np.asarray(widths, dtype=float))) / 2.0)[:, None]
    found, points, normals = [], [], []
    for sign in (-1.0, 1.0):  # the jaw at −z moves along +z, the one at +z along −z
        hits, rays, tri = mesh.ray.intersects_location(c + sign * half * z, -sign * z, multiple_hits=False)
        point, normal, hit = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, dtype=bool)
        point[rays], normal[rays], hit[rays] = hits, mesh.face_normals[tri], True
        found.append(hit)
        points.append(point)
        normals.append(normal)
    d = np.einsum("ij,ij->i", points[1] - points[0], z)
    labelled = d + PINCH_CLEARANCE
    cos_t = np.cos(np.deg2rad(config.friction_cone_deg))
    ok = (found[0] & found[1] & (d >= config.min_extent) & (labelled <= GRIPPER.max_width)
          & (np.einsum("ij,ij->i", normals[0], -z) >= cos_t) & (np.einsum("ij,ij->i", normals[1], z) >= cos_t))
    if surface is None:
        surface = trimesh.sample.sample_surface(mesh, 4000, seed=0)[0]
    if ok.any():
        ok[ok] = gripper_sweep_free(surface, poses[ok], labelled[ok])
    return ok, labelled
