"""The rerun writer: one .rrd recording of a benchmark trial: scene geometry, body motion, observations, grasps,
outcomes.

One ``Recorder`` writes one .rrd file for one trial through its own ``rr.RecordingStream``; it never
touches rerun's global or thread-local recording, so several recorders may live (one after another or
side by side) in one process and trials may run in parallel worker processes.

Frames and entity paths:

- ``world``: world frame, origin at the table-top centre, +z up (logged as right-handed z-up).
- ``world/bodies/{body}``: ``Transform3D`` = pose of MuJoCo body ``body`` in the world frame, one per
  ``log_state`` call on the ``sim_time`` timeline. The world body's own geoms (table …) live under
  ``world/bodies/world`` with no transform (identity, static).
- ``world/bodies/{body}/{geom}``: static ``Transform3D`` = pose of the geom in its body's frame, plus the
  geom's shape (``Boxes3D``, ``Ellipsoids3D``, ``Capsules3D``, ``Cylinders3D`` or ``Mesh3D``) in the geom
  frame, coloured with the geom's rgba.
- ``world/camera``: ``Transform3D`` = OpenCV camera-to-world pose (x right, y down, z forward) and a
  ``Pinhole`` (``camera_xyz`` = RDF); ``world/camera/rgb`` and ``world/camera/depth`` hold the images.
- ``world/points``: the back-projected depth as a coloured point cloud in the world frame.
- ``world/candidates`` / ``world/selected``: grasp candidates / the executed grasp as gripper sketches in
  the world frame (see ``gripper_sketch``).
- ``outcome``: ``TextLog`` lines describing attempt results.

Time: the only timeline is ``sim_time``, a duration in **seconds** of simulated time (rerun stores
nanoseconds). Wall-clock ``log_time`` is not recorded, so a recording depends only on what was logged.

Body names may contain ``/`` (dm_control prefixes such as ``robot/link3``); each path part is sanitised
(every character outside ``[A-Za-z0-9_-]`` becomes ``_``, collisions get an ``_{id}`` suffix).

The recording's files (merge, copy) and the viewers are in ``viz.rerun_viewer``; what a trial records, in
``bench.trial_recording``.
"""

from __future__ import annotations

import re
import shutil
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType

import mujoco
import numpy as np
import rerun as rr

from kgn_bench.errors import KGNBenchError
from kgn_bench.geometry import backproject
from kgn_bench.gripper import GRIPPER

__all__ = [
    "APPLICATION_ID",
    "MAX_POINTS",
    "SELECTED_COLOR",
    "STEM_LENGTH",
    "TIMELINE",
    "Recorder",
    "RecordingError",
    "gripper_sketch",
    "sanitize_path_part",
    "score_colors",
]

APPLICATION_ID = "kgn-bench"
TIMELINE = "sim_time"
"""Name of the recording's timeline: simulated time, logged as a duration in seconds."""
MAX_POINTS = 50_000
"""Largest point cloud logged per observation; denser clouds are subsampled with a fixed pixel stride."""
STEM_LENGTH = 0.04
"""Length (m) of the stem drawn behind the palm of a gripper sketch."""

_STATE_FLUSH_EVERY = 200
"""``log_state`` buffers body poses and sends them in columns once this many states are pending."""
_DEFAULT_GEOM_RGBA = np.array([0.5, 0.5, 0.5, 1.0], dtype=np.float32)
_VISIBLE_GROUPS = (0, 1, 2)
_PLANE_HALF_SIZE = 5.0
"""Half extent (m) drawn for an infinite MuJoCo plane (size 0)."""
_CANDIDATE_RADIUS = 0.001
_SELECTED_RADIUS = 0.003
SELECTED_COLOR = (0, 200, 255)
"""RGB of the executed grasp's sketch (cyan)."""
_POINT_RADIUS = 0.001


# -- pure helpers ---------------------------------------------------------------------------------
class RecordingError(KGNBenchError, RuntimeError):
    """A recording that cannot be written, merged, copied or served."""


def sanitize_path_part(name: str) -> str:
    """A rerun entity-path part made of ``[A-Za-z0-9_-]`` only: other characters (``/``, spaces …) become ``_``."""
    return re.sub(r"[^A-Za-z0-9_\-]", "_", name)


def gripper_sketch(poses: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """Line segments sketching a parallel-jaw gripper at each grasp pose.

    ``poses`` (N, 4, 4) are grasp frames in some frame F (origin at the fingertip midpoint, +x approach,
    z closing axis with the left finger at +z; the gripper body lies at x < 0); ``widths`` (N,) are the jaw
    openings in metres. Returns an (N, 4, 2, 3) array of segment end points in frame F:

    - ``[:, 0]`` left finger: ``(−L, 0, +w/2) → (0, 0, +w/2)``
    - ``[:, 1]`` right finger: ``(−L, 0, −w/2) → (0, 0, −w/2)``
    - ``[:, 2]`` palm: ``(−L, 0, +w/2) → (−L, 0, −w/2)``
    - ``[:, 3]`` stem: ``(−L, 0, 0) → (−L − STEM_LENGTH, 0, 0)``

    with ``L = GRIPPER.finger_length`` and the points as written expressed in the grasp frame, then mapped
    by each pose. ``result.reshape(-1, 2, 3)`` is a list of 2-point strips for ``rr.LineStrips3D``.
    """
    poses = np.asarray(poses, dtype=np.float64)
    widths = np.asarray(widths, dtype=np.float64)
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise ValueError(f"poses must have shape (N, 4, 4), got {poses.shape}")
    if widths.shape != (poses.shape[0],):
        raise ValueError(f"widths must have shape ({poses.shape[0]},), got {widths.shape}")
    L = GRIPPER.finger_length
    h = widths / 2.0
    local = np.zeros((len(widths), 4, 2, 3))
    local[:, 0, 0] = np.stack([np.full_like(h, -L), np.zeros_like(h), h], axis=-1)
    local[:, 0, 1, 2] = h
    local[:, 1, 0] = np.stack([np.full_like(h, -L), np.zeros_like(h), -h], axis=-1)
    local[:, 1, 1, 2] = -h
    local[:, 2, 0] = local[:, 0, 0]
    local[:, 2, 1] = local[:, 1, 0]
    local[:, 3, 0, 0] = -L
    local[:, 3, 1, 0] = -L - STEM_LENGTH
    R, t = poses[:, :3, :3], poses[:, :3, 3]
    return np.einsum("nij,nksj->nksi", R, local) + t[:, None, None, :]


def score_colors(scores: np.ndarray) -> np.ndarray:
    """RGB colours (N, 3) uint8 for grasp scores: min-max normalised, red (lowest) → yellow → green (highest).

    Equal scores (including a single candidate) are all green. Raises ``ValueError`` on non-finite scores.
    """
    s = np.asarray(scores, dtype=np.float64)
    if s.ndim != 1:
        raise ValueError(f"scores must be one-dimensional, got shape {s.shape}")
    if not np.all(np.isfinite(s)):
        raise ValueError("scores must be finite")
    if s.size == 0:
        return np.zeros((0, 3), dtype=np.uint8)
    span = s.max() - s.min()
    t = (s - s.min()) / span if span > 0 else np.ones_like(s)
    rgb = np.stack([np.minimum(1.0, 2.0 * (1.0 - t)), np.minimum(1.0, 2.0 * t), np.zeros_like(t)], axis=-1)
    return np.round(255.0 * rgb).astype(np.uint8)


def _rgba_u8(rgba: np.ndarray) -> np.ndarray:
    return np.round(255.0 * np.clip(rgba, 0.0, 1.0)).astype(np.uint8)


def _xyzw(quat_wxyz: np.ndarray) -> np.ndarray:
    """MuJoCo (w, x, y, z) quaternions (..., 4) to rerun's (x, y, z, w)."""
    return np.asarray(quat_wxyz)[..., [1, 2, 3, 0]]


def _vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals of a triangle mesh (vertices without faces get +z)."""
    tri = vertices[faces]
    face_n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(n, faces[:, k], face_n)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(norm > 0, n / np.where(norm > 0, norm, 1.0), np.array([0.0, 0.0, 1.0]))


def _geom_rgba(model: mujoco.MjModel, g: int) -> np.ndarray:
    """The colour MuJoCo draws geom ``g`` with: its material's rgba when the geom keeps the default rgba."""
    rgba = np.asarray(model.geom_rgba[g], dtype=np.float32)
    mat = int(model.geom_matid[g])
    if mat >= 0 and np.allclose(rgba, _DEFAULT_GEOM_RGBA):
        rgba = np.asarray(model.mat_rgba[mat], dtype=np.float32)
    return rgba


def _geom_shape(model: mujoco.MjModel, g: int, rgba: np.ndarray) -> rr.AsComponents | None:
    """The rerun archetype drawing geom ``g`` in its own frame, or ``None`` for unsupported types."""
    kind = int(model.geom_type[g])
    size = np.asarray(model.geom_size[g], dtype=np.float64)
    color = [_rgba_u8(rgba)]
    solid = rr.components.FillMode.Solid
    T = mujoco.mjtGeom
    if kind == T.mjGEOM_BOX:
        return rr.Boxes3D(half_sizes=[size], colors=color, fill_mode=solid)
    if kind == T.mjGEOM_PLANE:
        hx = size[0] if size[0] > 0 else _PLANE_HALF_SIZE
        hy = size[1] if size[1] > 0 else _PLANE_HALF_SIZE
        return rr.Boxes3D(half_sizes=[[hx, hy, 0.0]], colors=color, fill_mode=solid)
    if kind == T.mjGEOM_SPHERE:
        return rr.Ellipsoids3D(half_sizes=[[size[0]] * 3], colors=color, fill_mode=solid)
    if kind == T.mjGEOM_ELLIPSOID:
        return rr.Ellipsoids3D(half_sizes=[size], colors=color, fill_mode=solid)
    if kind == T.mjGEOM_CAPSULE:
        # rerun's capsule runs from (0, 0, 0) to (0, 0, length); MuJoCo's is centred on the geom origin.
        return rr.Capsules3D(lengths=[2.0 * size[1]], radii=[size[0]], translations=[[0.0, 0.0, -size[1]]],
                             colors=color, fill_mode=solid)
    if kind == T.mjGEOM_CYLINDER:
        return rr.Cylinders3D(lengths=[2.0 * size[1]], radii=[size[0]], centers=[[0.0, 0.0, 0.0]], colors=color,
                              fill_mode=solid)
    if kind == T.mjGEOM_MESH:
        mesh = int(model.geom_dataid[g])
        va, vn = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        fa, fn = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
        vertices = np.asarray(model.mesh_vert[va : va + vn], dtype=np.float64)
        faces = np.asarray(model.mesh_face[fa : fa + fn], dtype=np.int64)
        return rr.Mesh3D(vertex_positions=vertices.astype(np.float32), triangle_indices=faces.astype(np.uint32),
                         vertex_normals=_vertex_normals(vertices, faces).astype(np.float32), albedo_factor=color[0])
    return None


def _body_name(model: mujoco.MjModel, b: int) -> str:
    return model.body(b).name or f"body_{b}"


def _unique(part: str, taken: set[str], suffix: int) -> str:
    if part in taken:
        part = f"{part}_{suffix}"
    taken.add(part)
    return part


# -- recorder -------------------------------------------------------------------------------------
@dataclass
class _StateBuffer:
    """Body poses pending a columnar send: times (s), positions (T, B, 3) and xyzw quaternions (T, B, 4)."""

    times: list[float] = field(default_factory=list)
    positions: list[np.ndarray] = field(default_factory=list)
    quaternions: list[np.ndarray] = field(default_factory=list)

    def clear(self) -> None:
        self.times.clear()
        self.positions.clear()
        self.quaternions.clear()


class Recorder:
    """Writes one rerun recording (.rrd file) for one trial.

    Call ``log_geometry`` once (it fixes the set of bodies) before any ``log_state``; the other methods
    may be called in any order. Every ``time`` argument is simulated time in seconds on the ``sim_time``
    timeline. ``log_state`` buffers poses in memory and sends them in columns every few hundred states
    and on ``close``/``flush``: close the recorder (or use it as a context manager) or the last states are
    lost. All rerun calls go through the recorder's own stream, never the global one.
    """

    def __init__(self, path: Path, name: str) -> None:
        """Open ``path`` for writing (its parent must exist); ``name`` becomes the recording id and name."""
        path = Path(path)
        if not path.parent.is_dir():
            raise RecordingError(f"cannot write recording {path}: directory {path.parent} does not exist")
        if not name:
            raise ValueError("recording name must be non-empty")
        self.path = path
        self.name = name
        self._stream = rr.RecordingStream(APPLICATION_ID, recording_id=name)
        self._stream.set_log_time_enabled(False)
        self._stream.set_log_tick_enabled(False)
        self._stream.save(path)
        self._stream.send_recording_name(name)
        self._stream.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._closed = False
        self._body_ids: np.ndarray | None = None
        self._body_paths: list[str] = []
        self._nbody = -1
        self._states = _StateBuffer()

    # context manager ------------------------------------------------------------------------
    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"recorder for {self.path} is closed")

    def _set_time(self, time: float) -> None:
        if not np.isfinite(time):
            raise ValueError(f"time must be finite, got {time}")
        self._stream.set_time(TIMELINE, duration=float(time))

    # geometry -------------------------------------------------------------------------------
    @property
    def body_paths(self) -> list[str]:
        """Entity paths ``world/bodies/{body}`` of the bodies whose poses ``log_state`` records."""
        return list(self._body_paths)

    def log_geometry(self, model: mujoco.MjModel) -> None:
        """Log every visible geom (rgba alpha > 0, group 0, 1 or 2) as static geometry, once per recording.

        Each geom goes to ``world/bodies/{body}/{geom name or geom_<id>}`` with its pose in the body frame
        (``geom_pos``, ``geom_quat``) and its shape in the geom frame. The world body's geoms are static in the
        world frame under ``world/bodies/world``. Bodies other than the world body that own at least one
        logged geom are the ones ``log_state`` tracks. Height fields and SDF geoms are skipped with a warning.
        """
        self._check_open()
        if self._body_ids is not None:
            raise RuntimeError("log_geometry was already called for this recording")
        body_part: dict[int, str] = {}
        taken_bodies: set[str] = set()
        geom_parts: dict[int, set[str]] = {}
        tracked: list[int] = []
        skipped: list[str] = []
        for g in range(model.ngeom):
            if int(model.geom_group[g]) not in _VISIBLE_GROUPS:
                continue
            rgba = _geom_rgba(model, g)
            if rgba[3] <= 0:
                continue
            geom_label = model.geom(g).name or f"geom_{g}"
            shape = _geom_shape(model, g, rgba)
            if shape is None:
                skipped.append(f"{geom_label} (type {mujoco.mjtGeom(int(model.geom_type[g])).name})")
                continue
            b = int(model.geom_bodyid[g])
            if b not in body_part:
                body_part[b] = _unique(sanitize_path_part(_body_name(model, b)), taken_bodies, b)
                geom_parts[b] = set()
                if b != 0:
                    tracked.append(b)
            part = _unique(sanitize_path_part(geom_label), geom_parts[b], g)
            entity = f"world/bodies/{body_part[b]}/{part}"
            local = rr.Transform3D(translation=model.geom_pos[g], quaternion=_xyzw(model.geom_quat[g]))
            self._stream.log(entity, local, shape, static=True)
        if skipped:
            warnings.warn(f"recording {self.name}: geoms not drawn (unsupported type): {', '.join(skipped)}",
                          stacklevel=2)
        self._body_ids = np.array(sorted(tracked), dtype=np.int64)
        self._body_paths = [f"world/bodies/{body_part[b]}" for b in self._body_ids]
        self._nbody = int(model.nbody)

    # motion ---------------------------------------------------------------------------------
    def log_state(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Record the world poses (``data.xpos``, ``data.xquat``) of the bodies drawn by ``log_geometry`` at
        ``sim_time = data.time`` (seconds).

        The poses are whatever ``data`` holds (after ``mj_step`` they belong to the state before the last
        integration step; call ``mj_forward`` or ``mj_kinematics`` first for exact agreement). Cheap: the
        poses are copied into a buffer and sent as one column chunk per body every ``_STATE_FLUSH_EVERY``
        states and on ``flush``/``close``. Raises ``RuntimeError`` if ``log_geometry`` was not called.
        """
        self._check_open()
        if self._body_ids is None:
            raise RuntimeError("call log_geometry(model) before log_state")
        if model.nbody != self._nbody:
            raise ValueError(f"model has {model.nbody} bodies but log_geometry saw {self._nbody}")
        t = float(data.time)
        if not np.isfinite(t):
            raise ValueError(f"data.time must be finite, got {t}")
        ids = self._body_ids
        self._states.times.append(t)
        self._states.positions.append(data.xpos[ids])
        self._states.quaternions.append(data.xquat[ids])
        if len(self._states.times) >= _STATE_FLUSH_EVERY:
            self._send_states()

    def _send_states(self) -> None:
        buf = self._states
        if not buf.times or self._body_ids is None or len(self._body_ids) == 0:
            buf.clear()
            return
        times = rr.TimeColumn(TIMELINE, duration=np.asarray(buf.times, dtype=np.float64))
        pos = np.stack(buf.positions)
        quat = _xyzw(np.stack(buf.quaternions))
        for j, entity in enumerate(self._body_paths):
            columns = rr.Transform3D.columns(translation=pos[:, j], quaternion=quat[:, j])
            self._stream.send_columns(entity, indexes=[times], columns=columns)
        buf.clear()

    # observations ---------------------------------------------------------------------------
    def log_observation(self, rgb: np.ndarray, depth: np.ndarray, K: np.ndarray, camera_pose: np.ndarray,
                        time: float) -> None:
        """Log one RGB-D view at ``time`` (s).

        ``rgb`` (H, W, 3) uint8; ``depth`` (H, W) planar z in metres, 0 (or non-finite) = no measurement;
        ``K`` 3×3 intrinsics in pixels (OpenCV); ``camera_pose`` the 4×4 OpenCV camera-to-world pose (x right,
        y down, z forward). Logs ``world/camera`` (Transform3D + Pinhole, RDF), ``world/camera/rgb``,
        ``world/camera/depth`` (metres) and ``world/points``: the valid depth pixels back-projected, mapped to
        the world frame by ``camera_pose``, subsampled with a fixed stride to at most ``MAX_POINTS`` and
        coloured from ``rgb``.
        """
        self._check_open()
        rgb = np.asarray(rgb)
        depth = np.asarray(depth)
        K = np.asarray(K, dtype=np.float64)
        pose = np.asarray(camera_pose, dtype=np.float64)
        if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
            raise ValueError(f"rgb must be (H, W, 3) uint8, got {rgb.shape} {rgb.dtype}")
        if depth.shape != rgb.shape[:2]:
            raise ValueError(f"depth must be (H, W) = {rgb.shape[:2]}, got {depth.shape}")
        if K.shape != (3, 3) or not np.all(np.isfinite(K)) or K[0, 0] <= 0 or K[1, 1] <= 0:
            raise ValueError(f"K must be a finite 3x3 intrinsic matrix with positive focal lengths, got {K}")
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)) or not np.allclose(pose[3], [0, 0, 0, 1]):
            raise ValueError("camera_pose must be a finite 4x4 homogeneous transform")
        h, w = depth.shape
        self._set_time(time)
        depth = depth.astype(np.float32)
        valid = np.isfinite(depth) & (depth > 0)
        self._stream.log("world/camera", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]),
                         rr.Pinhole(image_from_camera=K, resolution=[w, h], camera_xyz=rr.ViewCoordinates.RDF,
                                    image_plane_distance=0.1))
        self._stream.log("world/camera/rgb", rr.Image(rgb))
        self._stream.log("world/camera/depth", rr.DepthImage(np.where(valid, depth, 0.0), meter=1.0))
        idx = np.flatnonzero(valid)
        if idx.size > MAX_POINTS:
            idx = idx[:: -(-idx.size // MAX_POINTS)]
        cam_points = backproject(np.where(valid, depth, 0.0), K).reshape(-1, 3)[idx]
        world_points = cam_points @ pose[:3, :3].T + pose[:3, 3]
        colors = rgb.reshape(-1, 3)[idx]
        self._stream.log("world/points", rr.Points3D(world_points.astype(np.float32), colors=colors,
                                                      radii=_POINT_RADIUS))

    # grasps ---------------------------------------------------------------------------------
    def log_candidates(self, poses_world: np.ndarray, widths: np.ndarray, scores: np.ndarray, selected: int | None,
                       time: float) -> None:
        """Log grasp candidates at ``time`` (s) as gripper sketches (``gripper_sketch``) in the world frame.

        ``poses_world`` (N, 4, 4) grasp poses in the world frame, ``widths`` (N,) jaw openings (m), ``scores``
        (N,) any finite reals, coloured red (lowest) → green (highest) by min-max normalisation
        (``score_colors``). ``selected`` indexes the executed candidate, drawn thicker in bright cyan at
        ``world/selected``; ``None`` clears ``world/selected`` from ``time`` on. N = 0 clears
        ``world/candidates``.
        """
        self._check_open()
        poses = np.asarray(poses_world, dtype=np.float64)
        widths = np.asarray(widths, dtype=np.float64)
        scores = np.asarray(scores, dtype=np.float64)
        if poses.ndim != 3 or poses.shape[1:] != (4, 4):
            raise ValueError(f"poses_world must have shape (N, 4, 4), got {poses.shape}")
        n = poses.shape[0]
        if widths.shape != (n,) or scores.shape != (n,):
            raise ValueError(f"widths and scores must have shape ({n},), got {widths.shape} and {scores.shape}")
        if not (np.all(np.isfinite(poses)) and np.all(np.isfinite(widths))) or np.any(widths < 0):
            raise ValueError("poses_world must be finite and widths finite and non-negative")
        if selected is not None and not 0 <= selected < n:
            raise IndexError(f"selected = {selected} is out of range for {n} candidates")
        colors = score_colors(scores)
        segments = gripper_sketch(poses, widths)
        self._set_time(time)
        if n == 0:
            self._stream.log("world/candidates", rr.Clear(recursive=False))
        else:
            self._stream.log("world/candidates", rr.LineStrips3D(
                segments.reshape(-1, 2, 3).astype(np.float32), colors=np.repeat(colors, 4, axis=0),
                radii=_CANDIDATE_RADIUS))
        if selected is None:
            self._stream.log("world/selected", rr.Clear(recursive=False))
        else:
            label = f"#{selected} score {scores[selected]:.3g} width {widths[selected] * 1000:.0f} mm"
            self._stream.log("world/selected", rr.LineStrips3D(
                segments[selected].astype(np.float32), colors=[SELECTED_COLOR], radii=_SELECTED_RADIUS,
                labels=[label] + [""] * 3, show_labels=True))

    def log_outcome(self, text: str, time: float, level: str = "INFO") -> None:
        """Log a line such as ``"attempt 2: success (cuboid)"`` at ``outcome`` at ``time`` (s)."""
        self._check_open()
        self._set_time(time)
        self._stream.log("outcome", rr.TextLog(text, level=level))

    # lifetime -------------------------------------------------------------------------------
    def flush(self) -> None:
        """Send buffered states and wait until everything logged so far is written to the file."""
        self._check_open()
        self._send_states()
        self._stream.flush()

    def close(self) -> None:
        """Send buffered states, flush and close the file. Idempotent. ``RecordingError`` naming the file if
        rerun could not write it (a full disk stops rerun's file-writer thread)."""
        if self._closed:
            return
        try:
            self._send_states()
            self._stream.flush()
        except (RuntimeError, OSError) as e:
            reason = str(e).strip().splitlines()[0]
            if shutil.disk_usage(self.path.parent).free < (1 << 20):
                reason = "disk full"  # rerun's writer thread stops without saying why
            raise RecordingError(f"cannot write recording {self.path}: {reason}") from None
        finally:
            self._stream.disconnect()
            self._closed = True
        if not self.path.is_file():
            raise RecordingError(f"cannot write recording {self.path}: the file was not created")
