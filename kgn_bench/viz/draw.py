"""PNG drawings: grasps as keypoint boxes on RGB images, depth colour maps, dataset view previews."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from kgn_bench.data.format import DatasetError, SceneAnnotation, read_view, scene_dir
from kgn_bench.geometry import invert_pose, project
from kgn_bench.grasp import KEYPOINT_LINKS, keypoints_in_frame
from kgn_bench.types import Observation
from kgn_bench.viz.images import PALETTE_RGB

__all__ = ["PALETTE", "colorize_depth", "draw_grasps", "draw_keypoints", "show_predictions", "show_view"]

PALETTE = np.array(PALETTE_RGB, dtype=np.uint8)
"""Distinct RGB colours (matplotlib's tab10) used per object."""


def draw_grasps(rgb: np.ndarray, poses_cam: np.ndarray, sides: np.ndarray, K: np.ndarray,
                color: tuple[int, int, int], thickness: int = 1) -> np.ndarray:
    """Draw grasps (camera frame poses (N, 4, 4)) as keypoint boxes of the given sides onto a copy of
    ``rgb``: the links L–TL, R–TR, TL–TR and a dot at the grasp origin. Grasps behind the camera are
    skipped."""
    out = rgb.copy()
    if len(poses_cam) == 0:
        return out
    kpts = keypoints_in_frame(poses_cam, sides)
    front = (kpts[..., 2] > 1e-3).all(axis=1) & (poses_cam[:, 2, 3] > 1e-3)
    uv = project(kpts[front], K)
    centres = project(poses_cam[front, :3, 3], K)
    scale = 16  # sub-pixel line positions (cv2 shift = 4 bits)
    for pts, c in zip(uv, centres):
        p = np.rint(pts * scale).astype(np.int64)
        for a, b in KEYPOINT_LINKS:
            cv2.line(out, tuple(p[a]), tuple(p[b]), color, thickness, cv2.LINE_AA, shift=4)
        cv2.circle(out, tuple(np.rint(c * scale).astype(np.int64)), 2 * scale, color, -1, cv2.LINE_AA, shift=4)
    return out


def draw_keypoints(rgb: np.ndarray, keypoints: np.ndarray, scores: np.ndarray, thickness: int = 1) -> np.ndarray:
    """Draw predicted keypoint boxes (N, 4, 2) image px (L, R, TL, TR) onto a copy of ``rgb``, coloured by
    score from red (0.3) to green (1); the L–R fingertip line is drawn thicker. Highest scores on top."""
    out = rgb.copy()
    scale = 16
    for k in np.argsort(scores):
        t = float(np.clip((scores[k] - 0.3) / 0.7, 0.0, 1.0))
        color = (int(255 * (1 - t)), int(255 * t), 40)
        p = np.rint(keypoints[k] * scale).astype(np.int64)
        if not np.all(np.abs(p) < 2**20):
            continue
        for a, b in KEYPOINT_LINKS:
            cv2.line(out, tuple(p[a]), tuple(p[b]), color, thickness, cv2.LINE_AA, shift=4)
        cv2.line(out, tuple(p[0]), tuple(p[1]), color, thickness + 1, cv2.LINE_AA, shift=4)
    return out


def show_predictions(detector, root: Path, scene: int, view: int) -> np.ndarray:
    """Side by side: a detector's predicted keypoint boxes on the view's RGB (coloured by score) and the
    view's collision-free ground truth (0.1 m boxes, one colour per object). ``detector`` follows the
    Detector protocol and returns candidates with keypoints."""
    ann = SceneAnnotation.load(scene_dir(root, scene) / "scene.json")
    rgbd = read_view(scene_dir(root, scene), view)
    obs = Observation(rgbd.rgb, rgbd.depth, ann.intrinsics, ann.camera_poses[view])
    cands = detector.detect(obs)
    kp = cands.keypoints if cands.keypoints is not None else np.zeros((0, 4, 2))
    left = draw_keypoints(rgbd.rgb, kp, cands.confidences)
    _label(left, f"{getattr(detector, 'name', 'detector')}: {len(cands)} candidates (red 0.3 .. green 1.0)")
    right = rgbd.rgb.copy()
    T_cam_world = invert_pose(ann.camera_poses[view])
    for i, obj in enumerate(ann.objects):
        free = obj.grasps.free()
        right = draw_grasps(right, T_cam_world @ free.poses, np.full(len(free), 0.1), ann.intrinsics.K,
                            tuple(int(c) for c in PALETTE[i % len(PALETTE)]))
    _label(right, f"ground truth: scene {scene} view {view}")
    return np.concatenate([left, right], axis=1)


def colorize_depth(depth: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """Turbo colour map of the valid depth range (RGB uint8); pixels without return are black."""
    valid = depth > 0
    if not np.any(valid):
        return np.zeros((*depth.shape, 3), np.uint8), (0.0, 0.0)
    lo, hi = float(depth[valid].min()), float(depth[valid].max())
    norm = np.zeros(depth.shape, np.uint8)
    norm[valid] = np.clip(255 * (depth[valid] - lo) / max(hi - lo, 1e-6), 0, 255).astype(np.uint8)
    colored = cv2.cvtColor(cv2.applyColorMap(norm, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
    colored[~valid] = 0
    return colored, (lo, hi)


def _label(img: np.ndarray, text: str) -> None:
    (w, h), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.5, 1)
    cv2.rectangle(img, (4, 6), (12 + w, 12 + h + 4), (0, 0, 0), -1)
    cv2.putText(img, text, (8, 10 + h), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)


def show_view(root: Path, scene: int, view: int, box: str = "width") -> np.ndarray:
    """Preview of one dataset view (RGB uint8): collision-free ground-truth grasps on the RGB image,
    coloured by object, beside the colour-mapped depth.

    ``box = "width"`` draws each keypoint box with side = the grasp width (L and R at the fingertips);
    ``box = "fixed"`` draws the 0.1 m box whose projections are the KGN training keypoints.
    """
    if box not in ("width", "fixed"):
        raise ValueError(f"box must be 'width' or 'fixed', got {box!r}")
    folder = scene_dir(root, scene)
    ann = SceneAnnotation.load(folder / "scene.json")
    if not 0 <= view < len(ann.camera_poses):
        raise DatasetError(f"scene {scene} has views 0..{len(ann.camera_poses) - 1}, not {view}")
    rgbd = read_view(folder, view)
    K = ann.intrinsics.K
    T_cam_world = invert_pose(ann.camera_poses[view])
    img = rgbd.rgb
    n_free = 0
    legend = []
    for i, obj in enumerate(ann.objects):
        free = obj.grasps.free()
        n_free += len(free)
        color = tuple(int(c) for c in PALETTE[i % len(PALETTE)])
        sides = free.widths if box == "width" else np.full(len(free), 0.1)
        img = draw_grasps(img, T_cam_world @ free.poses, sides, K, color)
        legend.append((f"{i}:{obj.type} {len(free)}/{len(obj.grasps)}", color))
    img = np.ascontiguousarray(img)
    _label(img, f"scene {scene} view {view}: {n_free} collision-free grasps ({box} boxes)")
    for k, (text, color) in enumerate(legend):
        y = 44 + 18 * k
        cv2.rectangle(img, (8, y - 11), (20, y + 1), color, -1)
        cv2.putText(img, text, (26, y), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    depth_img, (lo, hi) = colorize_depth(rgbd.depth)
    _label(depth_img, f"depth {lo:.3f}-{hi:.3f} m (black = no return)")
    return np.hstack([img, depth_img])

