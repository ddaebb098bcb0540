"""VGN's training data, generated in this simulator the way VGN and GIGA generate theirs.

A scene (``generate_scene``): ``Poisson(mean_objects) + 1`` objects of the training set (never the real test
objects), sized GIGA's way and arranged as a pile or packed (``sim.placement``), on the table of the floating
hand's work cell (``sim.floating_hand``); objects that leave the workspace cube leave the scene. Then:

- **the network input**: one depth image from GIGA's side view (``kgn_bench.giga``'s camera and intrinsics)
  with their "dex" noise (``sim.depth_noise.DexNoise``), fused into the 40³ TSDF of the workspace
  (``kgn_bench.tsdf``);
- **grasps**: ``grasps_per_scene`` grasp positions, each on a point ``p`` drawn uniformly (by area) from the
  objects' surfaces inside the valid part of the workspace (2 cm in from its sides, 5 mm above the table)
  whose outward normal ``n`` has ``n_z > −0.1`` and that one of VGN's 1 to 6 random views from above sees
  (``grasp_views``: VGN samples the surface those views reconstruct). The approach is ``a = −n``; the fingertips go
  ``e ~ U(−0.1 d, 1.1 d)`` past ``p`` (``d`` = the hand's finger length, VGN's finger depth), so the grasp
  origin (the fingertip midpoint) is ``o = p + e·a``. VGN's position of the grasp is its reference point
  ``r = o − giga.GRASP_REFERENCE_DEPTH · a``, ``d − e`` in front of the surface; with ``snap`` (the default)
  ``r`` then moves to the nearest grid point ``WORKSPACE_ORIGIN + round((r − WORKSPACE_ORIGIN) / voxel) · voxel``
  and the fingertips with it (``snap_references``).
  The closing axis at yaw 0 is the world x axis made perpendicular to ``a`` (world y if ``a`` is nearly along
  x), and ``yaws`` closing axes turned about ``a`` cover [0, π): grasp frame ``R = [a, c × a, c]`` (+x
  approach, z closing; world frame);
- **labels in physics**: each (position, yaw) is executed from the scene's saved state by the floating hand
  exactly as the benchmark executes GIGA's protocol, except that any contact on the way in fails it (VGN's
  data generation: a grasp must be reachable without touching anything). With ``precheck`` (the default) the
  kinematic test ``sim.floating_hand.precheck_grasp`` first rejects the grasps that execution would fail at
  the pre-grasp, on the way in or by closing on nothing (about 96 % of them, each ~7× cheaper than an
  execution); only the rest run in physics. A position is positive when some yaw holds; its rotation is the
  yaw in the middle of the longest run of holding yaws (circularly: yaw π is yaw 0) and its width the opening
  measured there. A negative keeps yaw 0 and the hand's maximum opening. Every yaw's outcome is stored too
  (``holds``, turned to start at the stored yaw; ``data.vgn_format``): where every yaw holds (a ball, the top
  of a can) the stored yaw says nothing about the object, and a training may want the whole set.

**The reference point.** The network predicts a grasp at each voxel; what it can see there decides what it can
learn. VGN's position is its TCP, a finger depth behind the fingertips: in front of the sampled surface, in the
observed band, where the surface's side and normal show. The fingertips themselves lie 0-5.5 cm past the
surface, inside a 7 cm object, where one voxel collects grasps from every side of it (v2 of this data, which
stored the fingertips, trained a rotation head that never left the mean direction).

**Why snap.** The detector executes the grasp whose reference point is the voxel ``(i, j, k) · voxel``; VGN
labels a grasp wherever it was sampled and reads it at the rounded voxel, so a label describes a grasp up to
half a voxel (3.75 mm) away from the one that is executed. On this generator's data that shift alone turned
39 of 65 holding grasps into failures in 4 scenes (pre-grasp collisions and misses: most grasps sit close to a
collision). Snapped, every label is the grasp the detector would execute at its voxel.

Positions are stored in VGN's voxel convention: ``(r − WORKSPACE_ORIGIN) / VOXEL_SIZE`` (no half-voxel
shift; integers when snapped), rotations as unit quaternions ``(w, x, y, z)`` of ``R_grid_grasp`` (the grid's
axes are the world's), widths in voxels. Grasps whose reference point lies outside the valid part of the
cube are dropped (VGN's cleaning).
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import mujoco
import numpy as np
import trimesh

from kgn_bench import giga
from kgn_bench.camera import INTRINSICS, orbit_pose
from kgn_bench.data.format import DatasetError
from kgn_bench.data.vgn_format import finalize_dataset, list_scene_ids, write_scene
from kgn_bench.environment import computed_with
from kgn_bench.geometry import make_pose, quat_wxyz_from_matrix
from kgn_bench.gripper import PANDA_HAND
from kgn_bench.io import atomic_write_text
from kgn_bench.pool import LOCAL, Backend, run_jobs
from kgn_bench.progress import Progress
from kgn_bench.shapes import PRIMITIVES, giga_objects
from kgn_bench.shapes.scaled import giga_names
from kgn_bench.sim.depth_noise import DexNoise
from kgn_bench.sim.floating_hand import FloatingHand, add_floating_cell, execute_grasp, precheck_grasp
from kgn_bench.sim.placement import GIGA_PILE, add_pile_box, giga_pack, giga_pile
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.scene import PhysicsError, Scene, SceneObject
from kgn_bench.threads import pin_worker_threads
from kgn_bench.tsdf import TSDFVolume, VoxelGrid

__all__ = ["VALID_MARGIN", "GraspLabels", "VGNDataConfig", "generate_scene", "generate_vgn_dataset", "grasp_frames",
           "grasp_views", "label_grasps", "reference_points", "sample_surface_points", "side_view", "snap_references",
           "to_voxels",
           "widest_run_centre"]

VALID_MARGIN = 0.02
"""Grasp positions stay this far (m) inside the workspace cube's sides (VGN's cleaning of its data)."""
TABLE_MARGIN = 0.005
"""Surface points lower than this (m) above the table are not sampled (VGN's valid volume)."""


def sample_surface_points(scene: Scene, n: int, rng: np.random.Generator, max_normal_down: float = -0.1,
                          views: list[tuple[np.ndarray, np.ndarray]] | None = None, tolerance: float = 0.003
                          ) -> tuple[np.ndarray, np.ndarray]:
    """``n`` world points (n, 3) and their outward unit normals (n, 3) drawn uniformly by area from the visual
    surfaces of the objects still in the scene, kept only where the point lies in the valid volume (``VALID_MARGIN``
    inside the cube's sides, ``TABLE_MARGIN`` above the table) and ``n_z > max_normal_down``, and, given
    ``views`` (planar depth (H, W) m, ``T_world_cam``) of the scene's camera intrinsics, only where some view sees
    it: its depth in that view is within ``tolerance`` of the depth rendered at its pixel (VGN samples the
    surface its views reconstruct). Fewer than ``n`` when too few such points exist among ``20 n`` draws."""
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
    if views is not None:
        seen = np.zeros(len(points), dtype=bool)
        for depth, T_world_cam in views:
            seen |= _visible(points, depth, scene.intrinsics.K, T_world_cam, tolerance)
        keep &= seen
    idx = np.flatnonzero(keep)
    if len(idx) > n:
        idx = rng.choice(idx, size=n, replace=False)
    return points[idx], normals[idx]


def _visible(points: np.ndarray, depth: np.ndarray, K: np.ndarray, T_world_cam: np.ndarray, tolerance: float
             ) -> np.ndarray:
    """(N,) bool: which world ``points`` project into the image in front of the camera at a pixel whose
    rendered planar depth is within ``tolerance`` of theirs."""
    T = np.linalg.inv(T_world_cam)
    p = points @ T[:3, :3].T + T[:3, 3]
    z = p[:, 2]
    out = np.zeros(len(points), dtype=bool)
    front = z > 1e-6
    uv = (p[front, :2] / z[front, None]) @ K[:2, :2].T + K[:2, 2]
    u, v = np.rint(uv[:, 0]).astype(int), np.rint(uv[:, 1]).astype(int)
    h, w = depth.shape
    inside = (u >= 0) & (u < w) & (v >= 0) & (v < h)
    idx = np.flatnonzero(front)[inside]
    out[idx] = np.abs(depth[v[inside], u[inside]] - z[idx]) < tolerance
    return out


def grasp_views(rng: np.random.Generator) -> list[np.ndarray]:
    """VGN's random views for sampling grasps, ``T_world_cam`` each: ``n ~ U{1..6}`` cameras at ``r ~ U(1.6, 2.4)``
    × the cube's side, polar angle ``θ ~ U(0, π/4)``, azimuth ``φ ~ U(0, 2π)``, looking at the cube's centre
    line at the cube's floor (their origin ``(0.15, 0.15, 0)``)."""
    target = np.array([0.0, 0.0, giga.WORKSPACE_ORIGIN[2]])
    out = []
    for _ in range(int(rng.integers(1, 7))):
        r = rng.uniform(1.6, 2.4) * giga.WORKSPACE_SIZE
        theta, phi = rng.uniform(0.0, np.pi / 4), rng.uniform(0.0, 2.0 * np.pi)
        T = orbit_pose(r, np.pi / 2 - max(theta, 1e-3), phi)
        T[:3, 3] += target
        out.append(T)
    return out


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


def reference_points(poses: np.ndarray) -> np.ndarray:
    """(..., 3) VGN's position of grasps ``poses`` (..., 4, 4, world): ``GRASP_REFERENCE_DEPTH`` behind the
    fingertip midpoint along the approach (+x), ``o − GRASP_REFERENCE_DEPTH · a``."""
    return poses[..., :3, 3] - giga.GRASP_REFERENCE_DEPTH * poses[..., :3, 0]


def snap_references(frames: np.ndarray) -> np.ndarray:
    """``frames`` (..., 4, 4, world) each moved so that its reference point (``reference_points``) lies on the
    nearest point of the grid's lattice ``WORKSPACE_ORIGIN + (i, j, k) · VOXEL_SIZE`` (module doc); orientations
    unchanged."""
    out = np.array(frames, dtype=float)
    origin = np.asarray(giga.WORKSPACE_ORIGIN)
    ref = reference_points(out)
    snapped = origin + np.rint((ref - origin) / giga.VOXEL_SIZE) * giga.VOXEL_SIZE
    out[..., :3, 3] += snapped - ref
    return out


def widest_run_centre(holds: np.ndarray) -> int:
    """The index in the middle of the longest run of ``True`` in the circular sequence ``holds`` (yaw π follows
    the last yaw and is yaw 0 again; the earlier middle of a run of even length); the first such run when several
    are as long. −1 when none."""
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
            best_len, best_mid = run, (idx - run // 2) % n
    return best_mid


@dataclass(frozen=True)
class GraspLabels:
    """The labelled grasp positions of one scene: world ``poses`` (N, 4, 4) at the chosen yaw, ``widths`` (N,)
    metres, ``labels`` (N,) bool, ``holds`` (N, yaws) every yaw's outcome and ``chosen`` (N,) the index of the
    yaw in ``poses`` (0 for a negative)."""

    poses: np.ndarray
    widths: np.ndarray
    labels: np.ndarray
    holds: np.ndarray
    chosen: np.ndarray

    def turns(self) -> np.ndarray:
        """(N, yaws) bool: ``holds`` turned so that column ``j`` is the yaw ``j`` steps past the chosen one, the
        grasp ``poses[n] · R_x(j π / yaws)`` (``data.vgn_format``'s ``holds``)."""
        yaws = self.holds.shape[1]
        cols = (self.chosen[:, None] + np.arange(yaws)[None, :]) % yaws
        return np.take_along_axis(self.holds, cols, axis=1)


def label_grasps(scene: Scene, hand: FloatingHand, frames: np.ndarray, precheck: bool = True) -> GraspLabels:
    """Execute every grasp of ``frames`` (N, yaws, 4, 4, world) from the scene's present state, restored before
    each, without contact on the way in; returns the labels (module doc). With ``precheck`` a grasp that
    ``precheck_grasp`` rejects fails without being executed. A grasp whose simulation blows up fails."""
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
            if precheck:
                if precheck_grasp(hand, frames[i, k]) is not None:
                    continue
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
    return GraspLabels(frames[rows, pick], np.where(labels, openings[rows, pick], hand.g.max_width), labels, holds,
                       pick)


def to_voxels(poses: np.ndarray, widths: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """VGN's stored form of world grasps: ``(voxels (N, 3) float, quaternions (N, 4) wxyz, widths (N,) in voxels,
    keep (N,) bool)``; ``voxels`` are the reference points', ``keep`` false where one lies outside the valid
    part of the cube."""
    grid = reference_points(poses) - giga.WORKSPACE_ORIGIN
    keep = np.all((grid >= VALID_MARGIN) & (grid <= giga.WORKSPACE_SIZE - VALID_MARGIN), axis=1)
    quats = np.array([quat_wxyz_from_matrix(T[:3, :3]) for T in poses]).reshape(-1, 4)
    return grid / giga.VOXEL_SIZE, quats, widths / giga.VOXEL_SIZE, keep


@dataclass(frozen=True)
class VGNDataConfig:
    """The generator's settings. Scene ``i`` draws everything from ``default_rng([seed, i])`` and is a pile
    when ``i`` is even, packed when odd; ``objects``: the training set (names; never the real test objects);
    ``snap`` and ``precheck`` as in the module doc."""

    scenes: int = 2000
    objects: tuple[str, ...] = tuple(PRIMITIVES)
    grasps_per_scene: int = 240
    yaws: int = 6
    mean_objects: float = 4.0
    seed: int = 0
    snap: bool = True
    precheck: bool = True
    labels: str = field(default="physics-floating-panda-v4")
    """The labelling rule's version (a change of rule makes another dataset). v2: the kinematic pre-check;
    v3: positions at VGN's reference point; v4: every yaw's outcome stored (``holds``)."""

    def settings(self) -> dict[str, Any]:
        return {**asdict(self), "objects": list(self.objects)}


def side_view() -> np.ndarray:
    """GIGA's camera, ``T_world_cam`` (OpenCV axes; ``kgn_bench.giga``)."""
    T = orbit_pose(giga.CAMERA_DISTANCE, np.deg2rad(giga.CAMERA_ELEVATION_DEG), np.deg2rad(giga.CAMERA_AZIMUTH_DEG))
    T[:3, 3] += np.asarray(giga.CAMERA_TARGET)
    return T


def _arranged_scene(config: VGNDataConfig, index: int, rng: np.random.Generator) -> tuple[Scene, FloatingHand, str]:
    """Scene ``index``'s objects placed GIGA's way (a pile or packed), the hand parked; retried on a blow-up or
    when no object is left in play."""
    arrangement = "pile" if index % 2 == 0 else "packed"
    for _ in range(5):
        count = min(int(rng.poisson(config.mean_objects)) + 1, giga.PACKED_TRIES)
        shapes = giga_objects(giga_names(config.objects, arrangement, rng, count), arrangement, rng)
        objects = [SceneObject(shape, tuple(float(c) for c in rng.uniform(0.1, 0.9, 3))) for shape in shapes]

        def extend(root, pile: bool = arrangement == "pile") -> None:
            add_floating_cell(root, PANDA_HAND)
            if pile:
                add_pile_box(root, GIGA_PILE)

        scene = Scene(objects, INTRINSICS["giga"], extend=extend)
        hand = FloatingHand(scene, PANDA_HAND)
        hand.park()
        try:
            play = giga_pile(scene, rng) if arrangement == "pile" else giga_pack(scene, rng)
        except PhysicsError:
            continue
        if play:
            return scene, hand, arrangement
    raise PhysicsError(f"scene {index}: no stable {arrangement} with an object in the workspace in 5 draws")


def generate_scene(config: VGNDataConfig, index: int) -> dict[str, Any]:
    """Scene ``index`` (module doc): its network input, its labelled grasps in VGN's voxel form and its facts."""
    rng = np.random.default_rng([config.seed, index])
    t0 = time.perf_counter()
    scene, hand, arrangement = _arranged_scene(config, index, rng)
    t1 = time.perf_counter()
    cam = side_view()
    with SceneRenderer(scene) as renderer:
        depth = renderer.render(cam).depth
        views = [(renderer.render(T).depth, T) for T in grasp_views(rng)]
    depth = DexNoise().apply(depth, scene.intrinsics.fx, rng)
    volume = TSDFVolume(VoxelGrid(giga.WORKSPACE_SIZE, giga.RESOLUTION, giga.TRUNCATION_VOXELS),
                        make_pose(t=giga.WORKSPACE_ORIGIN))
    volume.integrate(depth, scene.intrinsics, cam)
    t2 = time.perf_counter()
    points, normals = sample_surface_points(scene, config.grasps_per_scene, rng, views=views)
    d = PANDA_HAND.finger_length
    depths = rng.uniform(-0.1 * d, 1.1 * d, len(points))
    frames = grasp_frames(points, normals, depths, config.yaws)
    if config.snap:
        frames = snap_references(frames)
    labels = label_grasps(scene, hand, frames, config.precheck)
    voxels, quats, widths, keep = to_voxels(labels.poses, labels.widths)
    t3 = time.perf_counter()
    in_play = [i for i in range(len(scene.objects)) if i not in scene.retired]
    meta = {"index": index, "arrangement": arrangement, "objects": [scene.objects[i].shape.name for i in in_play],
            "seconds": {"scene": round(t1 - t0, 3), "view": round(t2 - t1, 3), "label": round(t3 - t2, 3)}}
    return {"tsdf": volume.network_input(), "voxels": voxels[keep], "quats": quats[keep], "widths": widths[keep],
            "labels": labels.labels[keep], "holds": labels.turns()[keep], "meta": meta}


GENERATOR = "vgn_generator.json"
"""The settings a dataset folder is being generated with, written before its first scene."""


def _job(args: tuple[VGNDataConfig, int]) -> tuple[int, dict[str, Any]]:
    config, index = args
    return index, generate_scene(config, index)


def _prepare(config: VGNDataConfig, out: Path) -> list[int]:
    """The scene indices still to generate into ``out``; ``DatasetError`` if it is being generated with other
    settings."""
    out.mkdir(parents=True, exist_ok=True)
    settings = {**config.settings(), "kernels": computed_with()}
    del settings["scenes"]  # a dataset grows by rerunning with more scenes: scene i is the same either way
    path = out / GENERATOR
    if path.is_file():
        existing = json.loads(path.read_text())
        if existing != settings:
            diff = [k for k in settings if existing.get(k) != settings[k]]
            raise DatasetError(f"{out} is being generated with other settings ({', '.join(diff)}); use another folder")
    else:
        atomic_write_text(path, json.dumps(settings, indent=1) + "\n")
    done = set(list_scene_ids(out))
    return [i for i in range(config.scenes) if f"{i:06d}" not in done]


def generate_vgn_dataset(config: VGNDataConfig, out: Path, workers: int = 1, progress: bool = True,
                         backend: Backend = LOCAL) -> dict[str, float]:
    """Generate (or finish) VGN's dataset in ``out``; each scene is written as it finishes, so a stopped run
    resumes where it was; the manifest is written at the end. Returns the throughput figures."""
    out = Path(out)
    todo = _prepare(config, out)
    bar = Progress(len(todo), "vgn data", unit="scenes", enabled=progress)
    start = time.perf_counter()
    grasps = 0

    def finished(result: tuple[int, dict[str, Any]]) -> None:
        nonlocal grasps
        index, scene = result
        write_scene(out, index, scene["tsdf"], scene["voxels"], scene["quats"], scene["widths"], scene["labels"],
                    scene["meta"], scene["holds"])
        grasps += len(scene["labels"])
        bar.update()

    run_jobs([(config, i) for i in todo], _job, finished, workers=workers, initializer=pin_worker_threads,
             what=f"VGN data generation into {out}", backend=backend)
    wall = time.perf_counter() - start
    manifest = finalize_dataset(out, settings=config.settings())
    return {"scenes": len(todo), "grasps": grasps, "wall_s": wall,
            "scenes_per_hour": 3600 * len(todo) / wall if wall > 0 else float("nan"),
            "positives": manifest.positives, "total_grasps": manifest.grasps}
