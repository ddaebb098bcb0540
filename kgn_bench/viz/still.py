"""Stills from a recording: one observation's camera image with the logged grasps drawn on it, as a PNG.

A headless server cannot open rerun's viewer; ``kgn-bench replay RUN --still OUT.png`` reads the .rrd that
``viz.recording.Recorder`` wrote and draws what the viewer's camera view shows at one attempt:

- the image ``world/camera/rgb`` as it was rendered for the detector (before the attempt moved anything);
- the candidates ``world/candidates`` (coloured by score, red → green) and the executed grasp
  ``world/selected`` (cyan), gripper sketches logged in the world frame, projected with the observation's
  pinhole: ``p_cam = R_wcᵀ (p_world − t_wc)``, ``(u, v) = project(p_cam, K)``, where ``(R_wc, t_wc)`` is the
  logged OpenCV camera-to-world pose ``world/camera`` and ``K`` its ``Pinhole.image_from_camera``;
- the outcome line the trial logged for that attempt, as a caption.

Observation ``k`` of a trial is the ``k``-th image on the ``sim_time`` timeline. A trial logs an attempt's
candidates and executed grasp at the time of the observation they were detected in, and its outcome when the
attempt ends (the time of the next observation): the grasps drawn with observation ``k`` are the last logged
in ``[t_k, t_k+1)``, its caption the last outcome in ``(t_k, t_k+1]``. rerun stores 3×3 matrices
column-major; they are transposed here once, in ``_mat3``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from kgn_bench.geometry import invert_pose, project, transform_points
from kgn_bench.viz.images import save_png
from kgn_bench.viz.recording import SELECTED_COLOR, RecordingError

__all__ = ["Observation", "draw_still", "read_observations", "save_still"]

_NS = 1e-9


@dataclass(frozen=True)
class Observation:
    """One camera observation of a recorded trial and the grasps logged with it.

    ``time``: sim_time (s). ``rgb``: (H, W, 3) uint8. ``K``: (3, 3) intrinsics. ``camera_pose``: (4, 4)
    OpenCV camera-to-world pose. ``candidates`` / ``selected``: lists of ``(points (M, 3) world frame, rgba
    uint8 (4,))`` line strips. ``outcome``: the text the trial logged for this attempt ('' if none).
    """

    time: float
    rgb: np.ndarray
    K: np.ndarray
    camera_pose: np.ndarray
    candidates: list[tuple[np.ndarray, np.ndarray]]
    selected: list[tuple[np.ndarray, np.ndarray]]
    outcome: str


def _mat3(flat) -> np.ndarray:
    """A rerun 3×3 matrix (9 values, column-major) as a row-major (3, 3) array."""
    return np.asarray(flat, dtype=np.float64).reshape(3, 3).T


def _rgba(packed: int) -> np.ndarray:
    """rerun's packed 0xRRGGBBAA colour as (4,) uint8."""
    return np.array([(packed >> s) & 0xFF for s in (24, 16, 8, 0)], dtype=np.uint8)


def _rows(chunks, entity: str) -> list[tuple[float, dict]]:
    """``(sim_time s, {column: value})`` rows of ``entity`` across its chunks, in time order (static rows,
    which carry no time, come first)."""
    rows = []
    for chunk in chunks.get(entity, []):
        table = chunk.to_record_batch().to_pylist()
        for row in table:
            t = row.get("sim_time")
            seconds = -1.0 if t is None else (t.total_seconds() if hasattr(t, "total_seconds") else t * _NS)
            rows.append((seconds, row))
    rows.sort(key=lambda r: r[0])
    return rows


def _strips(row: dict) -> list[tuple[np.ndarray, np.ndarray]]:
    strips = row.get("LineStrips3D:strips") or []
    colors = row.get("LineStrips3D:colors") or [int.from_bytes(bytes([*SELECTED_COLOR, 255]), "big")]
    return [(np.asarray(s, dtype=np.float64), _rgba(colors[min(i, len(colors) - 1)])) for i, s in enumerate(strips)]


def _store(path: Path, trial: int):
    from rerun.chunk import RrdReader

    try:
        reader = RrdReader(path)
        stores = reader.recordings()
    except Exception as e:  # rerun raises its own types for a truncated or foreign file
        raise RecordingError(f"{path}: not a readable rerun recording ({e})") from e
    wanted = [s for s in stores if s.recording_id.endswith(f"trial_{trial:05d}")]
    if not wanted:
        ids = ", ".join(s.recording_id for s in stores) or "none"
        raise RecordingError(f"{path}: no recording of trial {trial} (recordings: {ids})")
    return reader.stream(store=wanted[0])


def read_observations(path: str | Path, trial: int = 0) -> list[Observation]:
    """Every camera observation of ``trial`` in the recording ``path``, in time order. ``RecordingError``
    names a file that is not a recording, a trial it lacks, or a recording without camera images."""
    path = Path(path)
    chunks: dict[str, list] = {}
    for chunk in _store(path, trial):
        chunks.setdefault(str(chunk.entity_path), []).append(chunk)
    images = [r for r in _rows(chunks, "/world/camera/rgb") if r[1].get("Image:buffer")]
    if not images:
        raise RecordingError(f"{path}: trial {trial} has no camera images")
    cameras = [r for r in _rows(chunks, "/world/camera") if r[1].get("Pinhole:image_from_camera")]
    candidates = _rows(chunks, "/world/candidates")
    selected = _rows(chunks, "/world/selected")
    outcomes = [r for r in _rows(chunks, "/outcome") if r[1].get("TextLog:text")]
    if not cameras:
        raise RecordingError(f"{path}: trial {trial} has images but no camera pinhole")
    times = [t for t, _ in images] + [np.inf]
    result = []
    for k, (t, row) in enumerate(images):
        fmt = row["Image:format"][0]
        h, w = int(fmt["height"]), int(fmt["width"])
        buffer = np.asarray(row["Image:buffer"][0], dtype=np.uint8)
        if buffer.size % (h * w):
            raise RecordingError(f"{path}: trial {trial}: image {k} holds {buffer.size} bytes for {w}×{h}")
        rgb = buffer.reshape(h, w, -1)[..., :3].copy()
        cam_row = ([r for tc, r in cameras if tc <= t] or [cameras[0][1]])[-1]
        pose = np.eye(4)
        pose[:3, :3] = _mat3(cam_row["Transform3D:mat3x3"][0])
        pose[:3, 3] = cam_row["Transform3D:translation"][0]

        def last(rows, lo=t, hi=times[k + 1]):
            inside = [r for tr, r in rows if lo <= tr < hi]
            return inside[-1] if inside else {}

        text = [r["TextLog:text"][0] for tr, r in outcomes if t < tr <= times[k + 1]]
        result.append(Observation(time=t, rgb=rgb, K=_mat3(cam_row["Pinhole:image_from_camera"][0]),
                                  camera_pose=pose, candidates=_strips(last(candidates)),
                                  selected=_strips(last(selected)), outcome=text[-1] if text else ""))
    return result


def _draw_strips(img: np.ndarray, strips, camera_pose: np.ndarray, K: np.ndarray, thickness: int) -> None:
    world_to_cam = invert_pose(camera_pose)
    for points, rgba in strips:
        cam = transform_points(world_to_cam, points)
        if np.any(cam[:, 2] <= 1e-3):
            continue
        uv = np.round(project(cam, K)).astype(np.int32)
        cv2.polylines(img, [uv.reshape(-1, 1, 2)], False, tuple(int(v) for v in rgba[:3]), thickness, cv2.LINE_AA)


def draw_still(obs: Observation, caption: str = "") -> np.ndarray:
    """The observation's image with its candidates (1 px) and the executed grasp (3 px) drawn on it in their
    logged colours (score colours; ``recording.SELECTED_COLOR``), and ``caption`` (default: the attempt's
    outcome) on a dark band at the top."""
    img = np.ascontiguousarray(obs.rgb.copy())
    _draw_strips(img, obs.candidates, obs.camera_pose, obs.K, 1)
    _draw_strips(img, obs.selected, obs.camera_pose, obs.K, 3)
    text = caption or obs.outcome
    if text:
        cv2.rectangle(img, (0, 0), (img.shape[1], 22), (30, 30, 30), -1)
        cv2.putText(img, text[:100], (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return img


def save_still(recording: str | Path, out: str | Path, trial: int = 0, attempt: int = 1) -> Observation:
    """Write the still of ``attempt`` (counted from 1, as the trial's outcome lines count) of ``trial`` in
    ``recording`` to ``out`` (PNG, atomic); returns its observation. ``RecordingError`` for an attempt the
    trial does not have."""
    observations = read_observations(recording, trial)
    if not 1 <= attempt <= len(observations):
        raise RecordingError(f"{recording}: trial {trial} has {len(observations)} attempts, no attempt {attempt}")
    obs = observations[attempt - 1]
    caption = f"trial {trial}, t = {obs.time:.1f} s, " + (obs.outcome or f"attempt {attempt}: no outcome logged")
    save_png(out, draw_still(obs, caption))
    return obs
