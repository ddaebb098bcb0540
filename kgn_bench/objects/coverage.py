"""Which of an object's grasps the gripper can execute in each of its rest poses, and a verification budget
spent so that every rest pose gets some.

A rest pose is a rotation ``R`` of the object frame (the manifest's ``rest_poses``, from trimesh's
quasi-static estimate). Standing in it on the table, the object's pose is ``T_table_obj = [R | (0, 0, −z_min)]``
with ``z_min`` the lowest point of the rotated mesh: the object touches the table top z = 0, its centre of mass
above the table frame's origin. A grasp ``T_obj_grasp`` is **executable** in that rest pose when
``T_table_obj · T_obj_grasp`` keeps the whole gripper above the table: the labelling proxy at the grasp, and
the palm and wrist from the pre-grasp to where the executor closes (``sim.collision.gripper_hits_table``, with
the executor's ``PREGRASP_DISTANCE`` and ``GRASP_DEPTH``). That excludes approaches from below and grasps whose
fingers reach under the object, which no selector can take however well they hold. Other objects and the
arm's reach are a scene's business, not the object's.

``coverage_subset`` chooses which candidates the importer checks in physics: first up to ``per_rest`` spread
candidates executable in each rest pose, most likely pose first, then the rest of the budget spread over all
(``shapes.grasp_sampling.diverse_subset``). Without it, an object that rests on its side could keep 140 held
grasps none of which reaches it from above.
"""

from __future__ import annotations

import numpy as np
import trimesh

from kgn_bench.execution import GRASP_DEPTH, PREGRASP_DISTANCE
from kgn_bench.gripper import GRIPPER, GripperGeometry
from kgn_bench.shapes.grasp_sampling import diverse_subset
from kgn_bench.shapes.mesh_object import MeshObject
from kgn_bench.sim.collision import gripper_hits_table

__all__ = ["REST_GRASPS", "coverage_subset", "executable", "rest_pose_grasps", "rest_transforms"]

REST_GRASPS = 12
"""Candidates executable in each rest pose that the importer checks first (and, when fewer than a third of
them hold, as many more once)."""


def rest_transforms(mesh: trimesh.Trimesh, rotations: list) -> np.ndarray:
    """(K, 4, 4) ``T_table_obj`` of each rest rotation (module docstring)."""
    out = np.tile(np.eye(4), (len(rotations), 1, 1))
    for k, R in enumerate(rotations):
        R = np.asarray(R, dtype=float)
        out[k, :3, :3] = R
        out[k, 2, 3] = -float((mesh.vertices @ R.T)[:, 2].min())
    return out


def executable(mesh: trimesh.Trimesh, rotations: list, poses: np.ndarray, widths: np.ndarray,
               gripper: GripperGeometry = GRIPPER) -> np.ndarray:
    """(K, N) bool: grasp ``n`` (``poses`` (N, 4, 4) in the object frame, ``widths`` (N,)) is executable in
    rest pose ``k`` (module docstring)."""
    poses = np.asarray(poses, dtype=float)
    out = np.zeros((len(rotations), len(poses)), dtype=bool)
    if len(poses) == 0:
        return out
    for k, T in enumerate(rest_transforms(mesh, rotations)):
        out[k] = ~gripper_hits_table(T @ poses, widths, PREGRASP_DISTANCE, GRASP_DEPTH, gripper)
    return out


def rest_pose_grasps(shape: MeshObject) -> list[tuple[float, int]]:
    """(probability, executable verified grasps) of each rest pose of an imported object: the manifest's
    counts where the import wrote them, else counted now (objects imported before the counts existed)."""
    rests = shape.manifest["rest_poses"]
    if all("grasps" in r for r in rests):
        return [(float(r["probability"]), int(r["grasps"])) for r in rests]
    verified = shape.verified_grasps
    ok = executable(shape.mesh(), [r["R"] for r in rests], verified.poses, verified.widths)
    return [(float(r["probability"]), int(row.sum())) for r, row in zip(rests, ok)]


def coverage_subset(ok: np.ndarray, poses: np.ndarray, budget: int, rng: np.random.Generator,
                    per_rest: int = REST_GRASPS, exclude: np.ndarray | None = None) -> np.ndarray:
    """Sorted indices of at most ``budget`` candidates (module docstring): for each rest pose in order (rows of
    ``ok``, (K, N)), spread candidates executable there until the chosen ones hold ``per_rest`` of them, then
    spread ones of any kind up to ``budget``. ``exclude``: (N,) bool of candidates not to choose (checked
    already)."""
    n = len(poses)
    chosen = np.zeros(n, dtype=bool) if exclude is None else np.asarray(exclude, dtype=bool).copy()
    taken = chosen.copy()
    for row in ok:
        need = min(per_rest - int((row & chosen & ~taken).sum()), budget - int((chosen & ~taken).sum()))
        free = np.flatnonzero(row & ~chosen)
        if need > 0 and len(free):
            chosen[free[diverse_subset(poses[free], min(need, len(free)), rng)]] = True
    left = budget - int((chosen & ~taken).sum())
    free = np.flatnonzero(~chosen)
    if left > 0 and len(free):
        chosen[free[diverse_subset(poses[free], min(left, len(free)), rng)]] = True
    return np.flatnonzero(chosen & ~taken)
