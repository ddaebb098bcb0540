"""The oracle detector: ground-truth grasp families read from the simulator (privileged).

It is the harness's upper bound, not a detector: it sees object types, sizes and poses, which no camera
gives. For every object still on the table it returns the evaluation-density families (``EVAL_DENSITY``), each
also tilted by ±``TILT_DEG`` about its closing axis (``G · R_z(±α)``: the fingers stay where they pinch, the
approach leans along the pinched wall or axis, so a ring standing on edge can be taken from above at a slant;
an imported object's physics-verified grasps are used untilted, ``Shape.grasps_verified``), minus those whose
labelling proxy collides or whose palm and wrist would hit anything on the straight approach from
``approach`` m back to where the executor closes, ``grasp_depth`` past the grasp origin (``sim/collision.py``,
exact scene geometry), in the camera frame. Confidence favours top-down approaches (the executor's easiest)
near the object's centre (the stablest): ``c = ½ (1 − x_grasp · ẑ_world) − 2 m⁻¹ · ‖t_grasp − t_object‖``.
There is no reprojection error (NaN).
"""

from __future__ import annotations

import numpy as np

from kgn_bench.config import ExecutionConfig
from kgn_bench.geometry import invert_pose, make_pose, rot_z
from kgn_bench.grasp import GraspSet
from kgn_bench.shapes.base import EVAL_DENSITY
from kgn_bench.sim.collision import body_collisions, label_collisions
from kgn_bench.sim.robot import on_table
from kgn_bench.sim.scene import Scene

from .base import Candidates, DetectorError, Observation

__all__ = ["TILT_DEG", "OracleDetector", "tilted", "true_grasps"]

TILT_DEG = 30.0


def tilted(grasps: GraspSet, angles: tuple[float, ...]) -> GraspSet:
    """Every grasp turned about its own closing axis z by each of ``angles`` (rad): ``G · R_z(α)``."""
    turns = [make_pose(rot_z(a)) for a in angles]
    return GraspSet.concatenate([GraspSet(grasps.poses @ R, grasps.widths, grasps.collides) for R in turns])


def true_grasps(scene: Scene, i: int) -> GraspSet:
    """Object ``i``'s true grasps where it lies now (world frame): its evaluation-density families, each also
    tilted by ±``TILT_DEG`` about the closing axis (an imported object's verified grasps untilted), minus those
    whose labelling proxy collides with the table or another object. The oracle's candidates are these minus
    the ones its palm and wrist cannot reach; ``eval.explain`` measures a detector's grasps against them."""
    family = scene.objects[i].shape.grasps(EVAL_DENSITY)
    if not scene.objects[i].shape.grasps_verified:  # a physics-verified set is used as it is
        family = tilted(family, (0.0, np.deg2rad(TILT_DEG), -np.deg2rad(TILT_DEG)))
    return label_collisions(scene, i, family.transformed(scene.object_pose(i))).free()


class OracleDetector:
    """Ground-truth grasps of the objects on the table (privileged: call ``attach(scene)`` first)."""

    name = "oracle"
    privileged = True

    def __init__(self, approach: float | None = None) -> None:
        """``approach``: how far back the body check sweeps the palm and wrist (default: the pre-grasp
        distance of ``ExecutionConfig``; ``configure`` sets the task's)."""
        self.approach = ExecutionConfig().pregrasp_distance if approach is None else approach
        self.depth = ExecutionConfig().grasp_depth
        self._scene: Scene | None = None

    def configure(self, execution: ExecutionConfig) -> None:
        """Take the task's execution settings (the pre-grasp distance and the push past the grasp origin of
        the body check)."""
        self.approach = execution.pregrasp_distance
        self.depth = execution.grasp_depth

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
            grasps = true_grasps(scene, i)
            pushed = grasps.poses.copy()  # where the executor closes the jaws
            pushed[:, :3, 3] += self.depth * grasps.poses[:, :3, 0]
            grasps = grasps.with_collisions(body_collisions(scene, pushed, self.approach + self.depth)).free()
            sets.append(grasps)
            centres.append(np.repeat(T[None, :3, 3], len(grasps), axis=0))
        if not sets:
            return Candidates.empty()
        world = GraspSet.concatenate(sets)
        off_centre = np.linalg.norm(world.poses[:, :3, 3] - np.concatenate(centres), axis=1)
        conf = 0.5 * (1.0 - world.poses[:, 2, 0]) - 2.0 * off_centre
        poses = invert_pose(observation.camera_pose) @ world.poses
        return Candidates(poses, world.widths.copy(), conf, np.full(len(poses), np.nan))
