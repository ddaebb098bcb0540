"""A picture of an object and its grasps (matplotlib 3-D, two views), for ``kgn-bench objects show``.

Each grasp is drawn in the object frame as the gripper's outline: the two fingers from the fingertips
(``x = 0``, ``z = ±w/2``) back to ``x = −finger_length``, the bar joining them, and the approach stem behind it
(``GRIPPER`` dimensions), green for verified grasps.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.base import GraspDensity, Shape
from kgn_bench.viz.figures import save_figure

__all__ = ["draw_grasp_sets", "draw_object", "gripper_outlines"]


def gripper_outlines(poses: np.ndarray, widths: np.ndarray) -> np.ndarray:
    """Line segments (N·4, 2, 3) of the gripper outline of each grasp, in the poses' frame."""
    L = GRIPPER.finger_length
    segs = []
    for T, w in zip(poses, widths):
        h = float(GRIPPER.opening(w)) / 2.0
        local = np.array([[[0, 0, h], [-L, 0, h]], [[0, 0, -h], [-L, 0, -h]],
                          [[-L, 0, h], [-L, 0, -h]], [[-L, 0, 0], [-L - GRIPPER.palm_depth, 0, 0]]])
        segs.append(local @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(segs) if segs else np.zeros((0, 2, 3))


def draw_grasp_sets(mesh, sets: list[tuple[np.ndarray, np.ndarray, str, str]], out: str | Path,
                    title: str = "", color: tuple[float, float, float] = (0.7, 0.55, 0.35),
                    max_grasps: int = 40) -> Path:
    """Save a PNG of ``mesh`` (a trimesh, object frame) seen from two sides, with grasp sets ``(poses, widths,
    colour, label)`` drawn as gripper outlines (at most ``max_grasps`` of each, evenly spaced)."""
    faces = mesh.vertices[mesh.faces]
    normals = mesh.face_normals
    if len(faces) > 6000:
        keep = np.linspace(0, len(faces) - 1, 6000).astype(int)
        faces, normals = faces[keep], normals[keep]
    shade = np.clip(normals @ np.array([0.3, -0.4, 0.87]), 0.15, 1.0)
    drawn = []
    for poses, widths, colour, label in sets:
        pick = np.linspace(0, len(poses) - 1, min(max_grasps, len(poses))).round().astype(int) if len(poses) else []
        drawn.append((gripper_outlines(poses[pick], widths[pick]), colour, f"{label} ({len(poses)})"))
    segs_all = [d[0].reshape(-1, 3) for d in drawn if len(d[0])]
    pts = np.concatenate([mesh.vertices, *segs_all])
    centre, half = pts.mean(axis=0), (pts.max(axis=0) - pts.min(axis=0)).max() / 2.0
    fig = Figure(figsize=(8.0, 4.2))
    for k, (elev, azim) in enumerate(((25, -60), (80, -90))):
        ax = fig.add_subplot(1, 2, k + 1, projection="3d")
        ax.add_collection3d(Poly3DCollection(faces, facecolors=np.clip(np.asarray(color)[None] * shade[:, None], 0, 1),
                                             edgecolors="none"))
        for segs, colour, label in drawn:
            if len(segs):
                ax.add_collection3d(Line3DCollection(segs, colors=colour, linewidths=0.9, label=label))
        for i, lim in enumerate((ax.set_xlim, ax.set_ylim, ax.set_zlim)):
            lim(centre[i] - half, centre[i] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=elev, azim=azim)
        ax.set_xlabel("x (m)", fontsize=7)
        ax.set_ylabel("y (m)", fontsize=7)
        ax.set_zlabel("z (m)", fontsize=7)
        ax.tick_params(labelsize=6)
        if k == 0 and len(drawn) > 1:
            ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(title, fontsize=10)
    save_figure(fig, out)
    return Path(out)


def draw_object(shape: Shape, out: str | Path, max_grasps: int = 40, title: str | None = None) -> Path:
    """Save a PNG of ``shape``'s visual mesh with up to ``max_grasps`` of its grasps, seen from two sides."""
    grasps = shape.grasps(GraspDensity(translations=max_grasps, angles=1))
    total = len(getattr(shape, "verified_grasps", grasps))
    drawn = min(max_grasps, len(grasps))
    colour = tuple(getattr(shape, "manifest", {}).get("color", (0.7, 0.55, 0.35)))
    return draw_grasp_sets(shape.mesh(), [(grasps.poses, grasps.widths, "tab:green", "grasps")], out,
                           title=title or f"{shape.name}: {total} grasps ({drawn} drawn)", color=colour,
                           max_grasps=max_grasps)
