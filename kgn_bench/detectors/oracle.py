"""The oracle detector: ground-truth grasp families read from the simulator (privileged).

It is the harness's upper bound, not a detector: it sees object types, sizes and poses, which no camera
gives. For every object still on the table it returns the evaluation-density families (``EVAL_DENSITY``), each
also tilted by ±``TILT_DEG`` about its closing axis (``G · R_z(±α)``: the fingers stay where they pinch, the
approach leans along the pinched wall or axis, so a ring standing on edge can be taken from above at a slant;
an imported object's physics-verified grasps are used untilted, ``Shape.grasps_verified``), minus those wider
than the task's gripper opens, those whose labelling proxy collides and those whose palm and wrist would hit
anything on the straight approach from ``approach`` m back to where the executor closes (``sim/collision.py``,
exact scene geometry, the task's gripper), in the camera frame. Where it closes: ``grasp_depth`` past the grasp
origin for the arm; at the origin itself, after GIGA's 5 cm pre-grasp, for the floating hand
(``sim.floating_hand``), whose fingers, always fully open, are swept too. The floating hand's success rule
also needs the jaws to stay more than ``giga.MIN_HELD_WIDTH × max_width`` (8 mm) apart on the object, so there
the oracle also drops the grasps whose pinched extent (``pinched_extent``, on the object's mesh) is not
``PINCH_MARGIN`` more than that.

Confidence favours top-down approaches (the executor's easiest) near the object's centre (the stablest):
``c = ½ (1 − x_grasp · ẑ_world) − 2 m⁻¹ · ‖t_grasp − t_object‖``.
There is no reprojection error (NaN).
"""

from __future__ import annotations

import numpy as np
import trimesh

from kgn_bench import giga
from kgn_bench.config import ExecutionConfig
from kgn_bench.geometry import invert_pose, make_pose, rot_z
from kgn_bench.grasp import GraspSet
from kgn_bench.gripper import GRIPPER, GripperGeometry
from kgn_bench.shapes.base import EVAL_DENSITY
from kgn_bench.sim.collision import body_collisions, label_collisions
from kgn_bench.sim.robot import on_table
from kgn_bench.sim.scene import Scene

from .base import Candidates, DetectorError, Observation

__all__ = ["PINCH_MARGIN", "TILT_DEG", "OracleDetector", "pinched_extent", "tilted", "true_grasps"]

TILT_DEG = 30.0
PINCH_MARGIN = 0.002
"""How much thicker (m) than the floating hand's held-width floor the pinched part must be for the oracle."""


def pinched_extent(mesh: trimesh.Trimesh, poses: np.ndarray, widths: np.ndarray, finger_length: float,
                   samples: int = 3) -> np.ndarray:
    """(N,) how much of ``mesh`` the jaws of grasps ``poses`` (N, 4, 4, the mesh's frame) opened to ``widths``
    pinch: along the closing axis z, rays from each jaw (at ``±w/2``) towards the other, at ``samples`` depths
    ``x ∈ (−finger_length, 0)`` of the pads; the extent at one depth is ``w − d₊ − d₋`` (the first hits'
    distances) where both rays hit within ``w``, the result the largest over the depths (0 where none does)."""
    n = len(poses)
    if n == 0:
        return np.zeros(0)
    xs = -finger_length * (np.arange(samples) + 0.5) / samples
    R, t = poses[:, :3, :3], poses[:, :3, 3]
    z = R[:, :, 2]
    half = np.asarray(widths, dtype=float) / 2.0
    centres = t[:, None, :] + xs[None, :, None] * R[:, None, :, 0]  # (N, S, 3)
    origins = np.concatenate([centres - half[:, None, None] * z[:, None], centres + half[:, None, None] * z[:, None]])
    dirs = np.concatenate([np.broadcast_to(z[:, None], centres.shape), np.broadcast_to(-z[:, None], centres.shape)])
    locations, index, _ = trimesh.ray.ray_triangle.RayMeshIntersector(mesh).intersects_location(
        origins.reshape(-1, 3), dirs.reshape(-1, 3), multiple_hits=False)
    rays = origins.reshape(-1, 3)
    dist = np.full(len(rays), np.inf)
    if len(index):  # trimesh returns a flat empty array when no ray hits
        dist[index] = np.linalg.norm(np.asarray(locations).reshape(-1, 3) - rays[index], axis=1)
    d_plus, d_minus = dist[: n * samples].reshape(n, samples), dist[n * samples:].reshape(n, samples)
    extent = np.asarray(widths, dtype=float)[:, None] - d_plus - d_minus
    extent[~np.isfinite(extent) | (d_plus > 2 * half[:, None]) | (d_minus > 2 * half[:, None])] = 0.0
    return np.maximum(extent.max(axis=1), 0.0)


def tilted(grasps: GraspSet, angles: tuple[float, ...]) -> GraspSet:
    """Every grasp turned about its own closing axis z by each of ``angles`` (rad): ``G · R_z(α)``."""
    turns = [make_pose(rot_z(a)) for a in angles]
    return GraspSet.concatenate([GraspSet(grasps.poses @ R, grasps.widths, grasps.collides) for R in turns])


def true_grasps(scene: Scene, i: int, gripper: GripperGeometry = GRIPPER) -> GraspSet:
    """Object ``i``'s true grasps for ``gripper`` where it lies now (world frame): its evaluation-density
    families, each also tilted by ±``TILT_DEG`` about the closing axis (an imported object's verified grasps
    untilted), minus those wider than the gripper's maximum opening and those whose labelling proxy collides
    with the table or another object. The oracle's candidates are these minus the ones its palm and wrist cannot
    reach; ``eval.explain`` measures a detector's grasps against them."""
    family = scene.objects[i].shape.grasps(EVAL_DENSITY)
    if not scene.objects[i].shape.grasps_verified:  # a physics-verified set is used as it is
        family = tilted(family, (0.0, np.deg2rad(TILT_DEG), -np.deg2rad(TILT_DEG)))
    family = family.subset(family.widths <= gripper.max_width)
    return label_collisions(scene, i, family.transformed(scene.object_pose(i)), gripper).free()


class OracleDetector:
    """Ground-truth grasps of the objects on the table (privileged: call ``attach(scene)`` first)."""

    name = "oracle"
    privileged = True

    def __init__(self, approach: float | None = None) -> None:
        """``approach``: how far back the body check sweeps the palm and wrist (default: the pre-grasp
        distance of ``ExecutionConfig``; ``configure`` sets the task's)."""
        self.approach = ExecutionConfig().pregrasp_distance if approach is None else approach
        self.depth = ExecutionConfig().grasp_depth
        self.gripper = GRIPPER
        self.fingers_open: float | None = None
        self.min_pinch = 0.0
        self._scene: Scene | None = None

    def configure(self, execution: ExecutionConfig) -> None:
        """Take the task's execution settings: its gripper, and the pre-grasp distance and push past the grasp
        origin of the body check (the arm's ``pregrasp_distance`` and ``grasp_depth``; the floating hand's
        ``giga.PREGRASP_DISTANCE`` and no push)."""
        self.gripper = execution.geometry
        if execution.hand == "floating":
            self.approach, self.depth, self.fingers_open = giga.PREGRASP_DISTANCE, 0.0, self.gripper.max_width
            self.min_pinch = giga.MIN_HELD_WIDTH * self.gripper.max_width + PINCH_MARGIN
        else:
            self.approach, self.depth, self.fingers_open = execution.pregrasp_distance, execution.grasp_depth, None
            self.min_pinch = 0.0

    def attach(self, scene: Scene) -> None:
        self._scene = scene

    def reset(self, seed: list[int]) -> None:
        pass

    def detect(self, observation: Observation) -> Candidates:
        if self._scene is None:
            raise DetectorError("the oracle needs the simulator: call attach(scene) before detect()")
        scene = self._scene
        sets, centres = [], []
        for i in range(len(scene.objects)):
            if not on_table(scene, i):
                continue
            T = scene.object_pose(i)
            grasps = true_grasps(scene, i, self.gripper)
            pushed = grasps.poses.copy()  # where the executor closes the jaws
            pushed[:, :3, 3] += self.depth * grasps.poses[:, :3, 0]
            hits = body_collisions(scene, pushed, self.approach + self.depth, self.gripper, self.fingers_open)
            grasps = grasps.with_collisions(hits).free()
            if self.min_pinch > 0 and len(grasps):
                local = invert_pose(T) @ grasps.poses
                pinch = pinched_extent(scene.objects[i].shape.mesh(), local, grasps.widths, self.gripper.finger_length)
                grasps = grasps.subset(pinch > self.min_pinch)
            sets.append(grasps)
            centres.append(np.repeat(T[None, :3, 3], len(grasps), axis=0))
        if not sets:
            return Candidates.empty()
        world = GraspSet.concatenate(sets)
        off_centre = np.linalg.norm(world.poses[:, :3, 3] - np.concatenate(centres), axis=1)
        conf = 0.5 * (1.0 - world.poses[:, 2, 0]) - 2.0 * off_centre
        poses = invert_pose(observation.camera_pose) @ world.poses
        return Candidates(poses, world.widths.copy(), conf, np.full(len(poses), np.nan))
