"""VGN's training data, generated in this simulator the way VGN and GIGA generate theirs.

A scene (``generate_scene``): ``Poisson(mean_objects) + 1`` objects of the training set (never the real test
objects), sized GIGA's way and arranged as a pile or packed (``sim.placement``), on the table of the floating
hand's work cell (``sim.floating_hand``); objects that leave the workspace cube leave the scene. Then:

- **the network input**: one depth image from GIGA's side view (``kgn_bench.giga``'s camera and intrinsics)
  with their "dex" noise (``sim.depth_noise.DexNoise``), fused into the 40³ TSDF of the workspace
  (``kgn_bench.tsdf``);
- **grasps**: ``grasps_per_scene`` grasp positions, each on a point ``p`` drawn uniformly (by area) from the
  objects' surfaces inside the valid part of the workspace (2 cm in from its sides, 5 mm above the table)
  whose outward normal ``n`` has ``n_z > −0.1``. The approach is ``a = −n``; the fingertips go
  ``e ~ U(−0.1 d, 1.1 d)`` past ``p`` (``d`` = the hand's finger length, VGN's finger depth), so the grasp
  origin (the fingertip midpoint) is ``o = p + e·a``. The closing axis at yaw 0 is the world x axis made
  perpendicular to ``a`` (world y if ``a`` is nearly along x), and ``yaws`` closing axes turned about ``a``
  cover [0, π): grasp frame ``R = [a, c × a, c]`` (+x approach, z closing; world frame);
- **labels in physics**: each (position, yaw) is executed from the scene's saved state by the floating hand
  exactly as the benchmark executes GIGA's protocol, except that any contact on the way in fails it (VGN's
  data generation: a grasp must be reachable without touching anything). A position is positive when some yaw
  holds; its rotation is the yaw in the middle of the longest run of holding yaws (circularly: yaw π is yaw 0)
  and its width the opening measured there. A negative keeps yaw 0 and the hand's maximum opening.

Positions are stored in VGN's voxel convention: ``(o − WORKSPACE_ORIGIN) / VOXEL_SIZE`` (no half-voxel
shift), rotations as unit quaternions ``(w, x, y, z)`` of ``R_grid_grasp`` (the grid's axes are the world's),
widths in voxels. Grasps whose origin lies outside the valid part of the cube are dropped (VGN's cleaning).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
import trimesh

from kgn_bench import giga
from kgn_bench.geometry import quat_wxyz_from_matrix
from kgn_bench.sim.floating_hand import FloatingHand, execute_grasp
from kgn_bench.sim.scene import PhysicsError, Scene

__all__ = ["VALID_MARGIN", "GraspLabels", "grasp_frames", "label_grasps", "sample_surface_points", "to_voxels",
           "widest_run_centre"]

VALID_MARGIN = 0.02
"""Grasp positions stay this far (m) inside the workspace cube's sides (VGN's cleaning of its data)."""
TABLE_MARGIN = 0.005
"""Surface points lower than this (m) above the table are not sampled (VGN's valid volume)."""


def sample_surface_points(scene: Scene, n: int, rng: np.random.Generator, max_normal_down: float = -0.1
                          ) -> tuple[np.ndarray, np.ndarray]:
    """``n`` world points (n, 3) and their outward unit normals (n, 3) drawn uniformly by area from the visual
    surfaces of the objects still in the scene, kept only where the point lies in the valid volume (``VALID_MARGIN``
    inside the cube's sides, ``TABLE_MARGIN`` above the table) and ``n_z > max_normal_down``. Fewer than ``n``
    when too few such points exist among ``20 n`` draws."""
    meshes = []
    for i, obj in enumerate(scene.objects):
        if i in scene.retired:
            continue
        mesh = obj.shape.mesh().copy()
        mesh.apply_transform(scene.object_pose(i))
        meshes.append(mesh)
    if not meshes:
        return np.zeros((0, 3)), np.zeros((0, 3))
    world = trimesh.util.concatenate(meshes)
    points, faces = trimesh.sample.sample_surface(world, 20 * n, seed=int(rng.integers(2**31)))
    normals = world.face_normals[faces]
    grid = points - giga.WORKSPACE_ORIGIN
    inside = np.all((grid >= VALID_MARGIN) & (grid <= giga.WORKSPACE_SIZE - VALID_MARGIN), axis=1)
    keep = inside & (points[:, 2] >= TABLE_MARGIN) & (normals[:, 2] > max_normal_down)
    idx = np.flatnonzero(keep)
    if len(idx) > n:
        idx = rng.choice(idx, size=n, replace=False)
    return points[idx], normals[idx]


def grasp_frames(points: np.ndarray, normals: np.ndarray, depths: np.ndarray, yaws: int) -> np.ndarray:
    """(N, yaws, 4, 4) world grasp poses: approach ``a = −n``, origin ``p + e·a`` (``depths`` e), closing axes
    turned about ``a`` by ``k π / yaws`` from the yaw-0 axis (world x made perpendicular to ``a``, or world y
    when ``a`` is within 10° of x). Frame ``R = [a, c × a, c]``."""
    a = -normals / np.linalg.norm(normals, axis=1, keepdims=True)
    ref = np.where((np.abs(a[:, 0]) > np.cos(np.deg2rad(10.0)))[:, None], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
    c0 = ref - np.sum(ref * a, axis=1, keepdims=True) * a
    c0 /= np.linalg.norm(c0, axis=1, keepdims=True)
    b0 = np.cross(a, c0)
    theta = np.pi * np.arange(yaws) / yaws
    c = np.cos(theta)[None, :, None] * c0[:, None] + np.sin(theta)[None, :, None] * b0[:, None]
    a_ = np.broadcast_to(a[:, None], c.shape)
    out = np.zeros((len(points), yaws, 4, 4))
    out[..., :3, 0] = a_
    out[..., :3, 1] = np.cross(c, a_)
    out[..., :3, 2] = c
    out[..., :3, 3] = (points + depths[:, None] * a)[:, None]
    out[..., 3, 3] = 1.0
    return out


def widest_run_centre(holds: np.ndarray) -> int:
    """The index in the middle of the longest run of ``True`` in the circular sequence ``holds`` (yaw π
    follows the last yaw and is yaw 0 again); the first such run when several are as long. −1 when none."""
    n = len(holds)
    if not holds.any():
        return -1
    if holds.all():
        return 0
    start = int(np.flatnonzero(~holds)[0]) + 1  # begin just after a failure: no run wraps past the start
    best_len, best_mid, run = 0, -1, 0
    for k in range(n):
        idx = (start + k) % n
        run = run + 1 if holds[idx] else 0
        if run > best_len:
            best_len, best_mid = run, (idx - (run - 1) // 2) % n
    return best_mid


@dataclass(frozen=True)
class GraspLabels:
    """The labelled grasp positions of one scene: world ``poses`` (N, 4, 4) at the chosen yaw, ``widths`` (N,)
    metres, ``labels`` (N,) bool, and ``holds`` (N, yaws) every yaw's outcome."""

    poses: np.ndarray
    widths: np.ndarray
    labels: np.ndarray
    holds: np.ndarray


def label_grasps(scene: Scene, hand: FloatingHand, frames: np.ndarray) -> GraspLabels:
    """Execute every grasp of ``frames`` (N, yaws, 4, 4, world) from the scene's present state, restored before
    each, without contact on the way in; returns the labels (module doc). A grasp whose simulation blows up
    fails."""
    m, d = scene.model, scene.data
    size = mujoco.mj_stateSize(m, mujoco.mjtState.mjSTATE_INTEGRATION)
    saved = np.empty(size)
    mujoco.mj_getState(m, d, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
    n, yaws = frames.shape[:2]
    holds = np.zeros((n, yaws), dtype=bool)
    openings = np.full((n, yaws), hand.g.max_width)
    for i in range(n):
        for k in range(yaws):
            mujoco.mj_setState(m, d, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
            scene.forward()
            try:
                out = execute_grasp(hand, frames[i, k], allow_contact=False)
            except PhysicsError:
                continue
            holds[i, k] = out.reason is None
            openings[i, k] = out.opening
    mujoco.mj_setState(m, d, saved, mujoco.mjtState.mjSTATE_INTEGRATION)
    scene.forward()
    best = np.array([widest_run_centre(h) for h in holds])
    labels = best >= 0
    pick = np.where(labels, best, 0)
    rows = np.arange(n)
    return GraspLabels(frames[rows, pick], np.where(labels, openings[rows, pick], hand.g.max_width), labels, holds)


def to_voxels(poses: np.ndarray, widths: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """VGN's stored form of world grasps: ``(voxels (N, 3) float, quaternions (N, 4) wxyz, widths (N,) in voxels,
    keep (N,) bool)``, ``keep`` false where the origin lies outside the valid part of the cube."""
    grid = poses[:, :3, 3] - giga.WORKSPACE_ORIGIN
    keep = np.all((grid >= VALID_MARGIN) & (grid <= giga.WORKSPACE_SIZE - VALID_MARGIN), axis=1)
    quats = np.array([quat_wxyz_from_matrix(T[:3, :3]) for T in poses]).reshape(-1, 4)
    return grid / giga.VOXEL_SIZE, quats, widths / giga.VOXEL_SIZE, keep
