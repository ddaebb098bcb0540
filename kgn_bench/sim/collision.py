"""Collision labelling of ground-truth grasps with the gripper proxy (as in the reference implementation), and the
privileged check of the whole gripper's approach (``body_collisions``, the oracle's).

A grasp collides when its proxy box (``gripper.GRIPPER``) penetrates the table or any object other
than the one being grasped. The table is the half-space z < 0 under its 1 m² top (the proxy never
reaches past its edge from objects placed near the centre), tested exactly on the box corners; objects
are tested with MuJoCo's own collision detection on their collision geometry, so hollow shapes are
hollow here too.
"""

from __future__ import annotations

import numpy as np

from kgn_bench.grasp import GraspSet
from kgn_bench.gripper import GRIPPER, GripperGeometry, box_corners
from kgn_bench.sim.scene import Scene

__all__ = ["LABEL_VERSION", "body_collisions", "gripper_hits_table", "label_collisions", "proxy_hits_table"]

LABEL_VERSION = 2
"""Bumped whenever a change alters collision labels; evaluation caches key on it. 2: a proxy wider than its
compiled size now reaches neighbours in its outer band (MuJoCo's midphase used the compiled box)."""


def proxy_hits_table(poses: np.ndarray, widths: np.ndarray, gripper: GripperGeometry = GRIPPER) -> np.ndarray:
    """(N,) bool: the proxy box of world grasp ``poses`` dips strictly below the table top z = 0."""
    corners = gripper.proxy_corners(poses, widths)
    return corners[..., 2].min(axis=1) < 0.0


def label_collisions(scene: Scene, object_index: int, grasps_world: GraspSet,
                     gripper: GripperGeometry = GRIPPER) -> GraspSet:
    """Label grasps on object ``object_index`` (world frame) as colliding or not; returns a new set.

    The grasped object itself is excluded from the test (its proxy overlaps it by construction).
    """
    n = len(grasps_world)
    if n == 0:
        return grasps_world
    poses, widths = grasps_world.poses, grasps_world.widths
    hits = proxy_hits_table(poses, widths, gripper)
    half = gripper.proxy_half_extents(widths)
    centres = poses[:, :3, :3] @ gripper.proxy_centre + poses[:, :3, 3]
    with scene.proxy_only_collisions():
        scene.exclude_object_from_proxy(object_index)
        for k in np.flatnonzero(~hits):
            hits[k] = scene.proxy_hits_object(centres[k], poses[k, :3, :3], half[k])
    return grasps_world.with_collisions(hits)


def label_scene(scene: Scene, density) -> list[GraspSet]:
    """Every object's grasp families at ``density`` (a ``shapes.GraspDensity``), in the world frame at
    the objects' current poses, labelled with ``label_collisions``."""
    out = []
    for i, obj in enumerate(scene.objects):
        grasps = obj.shape.grasps(density).transformed(scene.object_pose(i))
        out.append(label_collisions(scene, i, grasps))
    return out


def _swept_boxes(gripper: GripperGeometry, back: float, fingers_open: float | None) -> list:
    """The palm and wrist (and, given ``fingers_open``, the fingers open that wide) swept ``back`` m along the
    approach; parts of zero size (a hand without a wrist) left out."""
    parts = [gripper.palm_box(), gripper.wrist_box()]
    if fingers_open is not None:
        parts += [gripper.finger_box(+1, fingers_open), gripper.finger_box(-1, fingers_open)]
    return [b.swept(back) for b in parts if np.all(b.half > 0)]


def _boxes_below_table(boxes: list, poses: np.ndarray) -> np.ndarray:
    hits = np.zeros(len(poses), dtype=bool)
    for box in boxes:
        hits |= box_corners(box, poses)[..., 2].min(axis=1) < 0.0
    return hits


def gripper_hits_table(poses: np.ndarray, widths: np.ndarray, back: float, depth: float,
                       gripper: GripperGeometry = GRIPPER) -> np.ndarray:
    """(N,) bool: the gripper of world grasps ``poses`` (N, 4, 4) dips below the table top z = 0: its labelling
    proxy at the grasp (``proxy_hits_table``), or its palm and wrist where the jaws close, ``depth`` m past the
    grasp origin along the approach, swept back ``back + depth`` m (the table half of ``body_collisions``).
    No scene needed: what the importer asks of a grasp in each of an object's rest poses."""
    pushed = poses.copy()
    pushed[:, :3, 3] += depth * poses[:, :3, 0]
    return proxy_hits_table(poses, widths, gripper) | _boxes_below_table(_swept_boxes(gripper, back + depth, None),
                                                                         pushed)


def body_collisions(scene: Scene, poses: np.ndarray, back: float, gripper: GripperGeometry = GRIPPER,
                    fingers_open: float | None = None) -> np.ndarray:
    """(N,) bool: the palm or wrist of world grasps ``poses`` (N, 4, 4), swept along the straight approach
    from ``back`` m behind the grasp, penetrates the table top (z < 0) or any object, the grasped one included.

    The proxy of ``label_collisions`` stands for the fingers and the space they close on; it is 2 cm thick
    and 10 cm deep, while the palm spans the full jaw travel and the wrist follows it. Between them the two
    tests cover the whole gripper's approach (the fingers' swept path behind ``−proxy_depth`` lies inside
    the swept palm). A gripper without a wrist (``wrist_length`` 0: the floating hand) sweeps its palm only.
    ``fingers_open``: also sweep the two fingers open that wide (m), for a hand that always opens fully (the
    floating hand): its fingers pass outside the grasp's own width, where the proxy does not look.
    Exact scene geometry, so privileged: the oracle's, never a detector's.
    """
    boxes = _swept_boxes(gripper, back, fingers_open)
    hits = _boxes_below_table(boxes, poses)
    with scene.proxy_only_collisions():
        scene.exclude_object_from_proxy(None)
        for k in np.flatnonzero(~hits):
            R, t = poses[k, :3, :3], poses[k, :3, 3]
            hits[k] = any(scene.proxy_hits_object(R @ b.centre + t, R, b.half) for b in boxes)
    return hits
