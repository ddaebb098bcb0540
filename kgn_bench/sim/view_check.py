"""Whether a camera sees the workspace, checked on the rendered segmentation before a task's first trial.

The workspace is the square of half side ``WORKSPACE_HALF`` on the table top (world z = 0) about the camera's
target. A grid of ``GRID``² points on it is projected with the camera (``T_world_cam``, OpenCV axes, the
scene's intrinsics ``K``):

* fewer than ``MIN_VISIBLE`` of them inside the image, in front of the camera: the camera cannot see the
  workspace;
* of those inside, fewer than ``MIN_VISIBLE`` show the table itself in the segmentation of the empty work
  cell (the arm parked): something stands between the camera and the workspace, and the error names it
  (the arm, the place bin, the pile box or another part of the cell).

Either is a ``ViewError``, one line naming the camera, raised before anything of the run is written.
"""

from __future__ import annotations

from collections import Counter

import mujoco
import numpy as np

from kgn_bench.errors import KGNBenchError
from kgn_bench.geometry import invert_pose, project, transform_points
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.scene import Scene

__all__ = ["GRID", "MIN_VISIBLE", "WORKSPACE_HALF", "ViewError", "check_view", "workspace_points"]

WORKSPACE_HALF = 0.12
"""Half side (m) of the table square about the camera target that every camera must see."""
GRID = 9
MIN_VISIBLE = 0.9


class ViewError(KGNBenchError, ValueError):
    """A camera that does not see the workspace, or whose view of it is blocked."""


def workspace_points(target: np.ndarray, half: float = WORKSPACE_HALF, n: int = GRID) -> np.ndarray:
    """(n², 3) world points of the table-top square of half side ``half`` about ``target`` (z = 0)."""
    g = np.linspace(-half, half, n)
    X, Y = np.meshgrid(g, g)
    return np.stack([X.ravel() + target[0], Y.ravel() + target[1], np.zeros(n * n)], axis=1)


def _blocker(name: str) -> str:
    if name.startswith("arm7/"):
        return "the arm"
    if name.startswith("bin_"):
        return "the place bin"
    if name.startswith("pile_wall"):
        return "the pile box"
    return f"geom {name!r}"


def check_view(renderer: SceneRenderer, scene: Scene, camera_pose: np.ndarray, target: np.ndarray,
               label: str = "camera") -> None:
    """Raise ``ViewError`` (naming ``label``) unless the camera at ``camera_pose`` sees the workspace about
    ``target`` (module docstring); renders once with ``renderer`` (of ``scene``, objects away)."""
    pts = workspace_points(np.asarray(target, dtype=float))
    cam = transform_points(invert_pose(camera_pose), pts)
    w, h = scene.intrinsics.width, scene.intrinsics.height
    front = cam[:, 2] > 1e-6
    uv = np.full((len(pts), 2), -1.0)
    uv[front] = project(cam[front], scene.intrinsics.K)
    u, v = np.rint(uv[:, 0]).astype(int), np.rint(uv[:, 1]).astype(int)
    inside = front & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    if inside.mean() < MIN_VISIBLE:
        raise ViewError(f"{label} cannot see the workspace: {100 * inside.mean():.0f} % of the table square "
                        f"±{100 * WORKSPACE_HALF:.0f} cm about its target lies in its image")
    renderer.render(camera_pose)
    geoms = renderer.last_geom_ids()[v[inside], u[inside]]
    table = geoms == scene.table_geom
    if table.mean() < MIN_VISIBLE:
        names = Counter(_blocker(mujoco.mj_id2name(scene.model, mujoco.mjtObj.mjOBJ_GEOM, int(g)) or str(g))
                        for g in geoms[~table] if g >= 0)
        what = names.most_common(1)[0][0] if names else "nothing (the table is not in view)"
        raise ViewError(f"{label}: {what} blocks the view of the workspace ({100 * (1 - table.mean()):.0f} % of "
                        f"the table square ±{100 * WORKSPACE_HALF:.0f} cm about its target is hidden)")
