"""The robot and work cell: the 7-DoF arm (assets/arm7.xml), the gripper generated from ``gripper.py``,
the place bin and the floor, composed into a scene with dm_control's mjcf.

Frames (world = table-top centre, +z up):

- ``T_world_base``: the arm's mounting frame, at ``BASE_POSITION`` with the world's orientation.
- The gripper's ``hand`` body sits at the wrist flange with the grasp frame's orientation
  (``kgn_bench.grasp``): +x along the last joint axis (approach), z the closing axis. Its site ``tcp`` lies at
  ``(tcp_offset, 0, 0)``, the fingertip midpoint, so the TCP pose *is* a grasp pose.
- The closing axis is the flange's y axis turned −45° about the flange z axis (the Panda hand's yaw).

Gripper actuation follows the usual tendon scheme: a fixed tendon ``0.5·(q_left + q_right)`` (half the jaw
opening), a joint equality keeping the fingers symmetric, and a force-limited position servo on the tendon
(``GripperGeometry.grip_force``; its gain ``grip_stiffness`` is high enough that the limit, not the object's
width, sets the squeeze). Pads: condim 4, elliptic cones with impratio 10 (scene option), stiff solref/solimp
and priority 1 so their contact parameters win.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import mujoco
import numpy as np
from dm_control import mjcf

from kgn_bench.geometry import frame_from_xz, quat_wxyz_from_matrix
from kgn_bench.gripper import GRIPPER, GripperGeometry
from kgn_bench.resources import arm_xml
from kgn_bench.sim.scene import GROUP_ROBOT, TABLE_HALF_SIZE, Scene

__all__ = [
    "ARM_JOINTS",
    "BASE_POSITION",
    "BIN",
    "PARK_Q",
    "READY_Q",
    "WORKSPACE_HALF",
    "PlaceBin",
    "RobotIndex",
    "add_floor",
    "add_workcell",
    "build_gripper",
    "build_robot",
    "descends",
    "on_table",
    "robot_only_model",
]

ARM_XML = arm_xml()

ARM_JOINTS = tuple(f"joint{i}" for i in range(1, 8))
FINGER_JOINTS = ("left_finger", "right_finger")
BASE_POSITION = np.array([-0.55, 0.0, 0.0])
"""Arm base in the world frame: just behind the table's −x edge, at table-top height."""

WORKSPACE_HALF = 0.40
"""Half side (m) of the square over the table centre where grasps are taken: objects are placed within ±0.3 m;
the arm's base (x = −0.55), its first links and the place bin lie outside it."""

READY_Q = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 1.9, 0.785])
"""Above the workspace, gripper pointing down: the seed of every IK solve."""
PARK_Q = np.array([-1.45, -0.6, 0.0, -2.6, 0.0, 2.0, 0.785])
"""Folded towards the bin side (−y), out of the default camera's view."""

PAD_CONTACT = dict(condim=6, friction=(1.0, 0.01, 0.005), solref=(0.004, 1.0), solimp=(0.95, 0.99, 0.001),
                   priority=1)
ROBOT_COLLISION = dict(contype=4, conaffinity=1)
"""Robot geoms touch the table, bin and objects (contype 1) but not each other or the labelling proxy."""


@dataclass(frozen=True)
class PlaceBin:
    """An open box beside the table: inner half size ``half`` (m), floor top at z = 0, walls ``height``."""

    centre: tuple[float, float] = (-0.40, -0.60)
    half: float = 0.13
    height: float = 0.15
    wall: float = 0.01
    pile_height: float = 0.25

    def contains(self, p: np.ndarray) -> bool:
        """Whether world point ``p`` lies in the bin: between the walls, above the floor, and no higher than
        ``pile_height`` (objects may rest on others already in the bin)."""
        d = np.abs(np.asarray(p[:2]) - self.centre)
        return bool(np.all(d <= self.half) and -0.01 <= p[2] <= self.pile_height)


BIN = PlaceBin()


def build_gripper(g: GripperGeometry = GRIPPER) -> mjcf.RootElement:
    """The gripper MJCF from ``g``: hand body in the grasp frame's orientation, origin at the flange."""
    root = mjcf.RootElement(model="gripper")
    root.compiler.angle = "radian"
    hand = root.worldbody.add("body", name="hand", gravcomp=1)
    off = g.tcp_offset
    palm = g.palm_box()
    hand.add("geom", name="palm", type="box", size=palm.half, pos=palm.centre + np.array([off, 0.0, 0.0]),
             mass=g.palm_mass, rgba=(0.25, 0.25, 0.28, 1), group=GROUP_ROBOT, **ROBOT_COLLISION)
    hand.add("site", name="tcp", pos=(off, 0.0, 0.0), size=(0.005,), rgba=(1, 0, 0, 1), group=GROUP_ROBOT)
    for side, name in ((+1, "left_finger"), (-1, "right_finger")):
        box = g.finger_box(side, 0.0)  # closed: the inner face on z = 0; the joint slides it outwards
        body = hand.add("body", name=name, gravcomp=1)
        body.add("joint", name=name, type="slide", axis=(0, 0, side), range=(0.0, g.finger_travel),
                 armature=0.1, damping=1.0)
        body.add("geom", name=f"{name}_pad", type="box", size=box.half, pos=box.centre + np.array([off, 0.0, 0.0]),
                 mass=g.finger_mass, rgba=(0.85, 0.45, 0.1, 1), group=GROUP_ROBOT, **ROBOT_COLLISION,
                 **PAD_CONTACT)
    tendon = root.tendon.add("fixed", name="opening")
    tendon.add("joint", joint="left_finger", coef=0.5)
    tendon.add("joint", joint="right_finger", coef=0.5)
    root.equality.add("joint", joint1="left_finger", joint2="right_finger", solref=(0.005, 1.0),
                      solimp=(0.95, 0.99, 0.001))
    root.actuator.add("position", name="gripper", tendon="opening", kp=g.grip_stiffness, kv=g.grip_damping,
                      ctrlrange=(0.0, g.finger_travel), forcerange=(-g.grip_force, g.grip_force))
    return root


def _flange_to_hand_quat() -> np.ndarray:
    """Rotation flange → hand (wxyz): hand x = flange z, hand z = R_z(−45°)·flange y, hand y = z × x."""
    x = np.array([0.0, 0.0, 1.0])
    z = np.array([np.sin(np.pi / 4), np.cos(np.pi / 4), 0.0])
    return quat_wxyz_from_matrix(frame_from_xz(x, z))


def build_robot(g: GripperGeometry = GRIPPER) -> mjcf.RootElement:
    """The arm with the gripper attached at its flange (names ``joint1..7``, ``gripper/tcp``, ...)."""
    arm = mjcf.from_path(str(ARM_XML))
    flange = arm.find("site", "flange")
    frame = flange.attach(build_gripper(g))
    frame.quat = _flange_to_hand_quat()
    return arm


def add_floor(root: mjcf.RootElement) -> None:
    """Add the floor (a plane 0.75 m under the table top) to a scene's MJCF: what falls off the table lands."""
    root.worldbody.add("geom", name="floor", type="plane", size=(3, 3, 0.1), pos=(0, 0, -0.75),
                       rgba=(0.35, 0.33, 0.3, 1), contype=1, conaffinity=3, group=GROUP_ROBOT)


def add_workcell(root: mjcf.RootElement, g: GripperGeometry = GRIPPER, place_bin: PlaceBin = BIN) -> None:
    """Add the robot (names prefixed ``arm7/``) on a pedestal, the place bin and a floor to a scene's MJCF."""
    world = root.worldbody
    site = world.add("site", name="robot_base", pos=BASE_POSITION)
    site.attach(build_robot(g))
    world.add("geom", name="pedestal", type="box", size=(0.09, 0.09, 0.35), pos=BASE_POSITION - (0, 0, 0.35),
              rgba=(0.3, 0.3, 0.32, 1), contype=0, conaffinity=0, group=GROUP_ROBOT)
    add_floor(root)
    cx, cy = place_bin.centre
    h, t, H = place_bin.half, place_bin.wall, place_bin.height
    common = dict(type="box", rgba=(0.2, 0.35, 0.6, 1), contype=1, conaffinity=3, group=GROUP_ROBOT)
    world.add("geom", name="bin_floor", size=(h + t, h + t, 0.025), pos=(cx, cy, -0.025), **common)
    for k, (dx, dy, sx, sy) in enumerate(((h + t / 2, 0, t / 2, h + t), (-h - t / 2, 0, t / 2, h + t),
                                          (0, h + t / 2, h, t / 2), (0, -h - t / 2, h, t / 2))):
        world.add("geom", name=f"bin_wall{k}", size=(sx, sy, H / 2), pos=(cx + dx, cy + dy, H / 2), **common)


@cache
def robot_only_model(g: GripperGeometry = GRIPPER) -> mujoco.MjModel:
    """The robot alone (base at the origin), for IK: no objects, so no free joints."""
    root = build_robot(g)
    return mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())


class RobotIndex:
    """Addresses of the robot's joints, actuators, sites and geoms in a compiled model.

    ``prefix`` is ``"arm7/"`` (the arm model's name) in a work-cell scene and ``""`` in the robot-only model.
    """

    def __init__(self, model: mujoco.MjModel, prefix: str = "arm7/") -> None:
        def jid(name: str) -> int:
            return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, prefix + name)

        joints = [jid(n) for n in ARM_JOINTS]
        fingers = [jid("gripper/" + n) for n in FINGER_JOINTS]
        if min(joints + fingers) < 0:
            raise ValueError(f"model has no robot with prefix {prefix!r}")
        self.arm_qpos = np.array([model.jnt_qposadr[j] for j in joints])
        self.arm_qvel = np.array([model.jnt_dofadr[j] for j in joints])
        self.finger_qpos = np.array([model.jnt_qposadr[j] for j in fingers])
        self.arm_actuators = np.array(
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, prefix + n) for n in ARM_JOINTS]
        )
        self.gripper_actuator = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, prefix + "gripper/gripper")
        self.tcp_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, prefix + "gripper/tcp")
        self.pad_geoms = np.array(
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, prefix + f"gripper/{n}_pad") for n in FINGER_JOINTS]
        )
        root_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, prefix + "link0")
        robot_bodies = [b for b in range(model.nbody) if descends(model, b, root_body)]
        self.geoms = np.flatnonzero(np.isin(model.geom_bodyid, robot_bodies))
        self.arm_limits = np.array([model.jnt_range[j] for j in joints])

    def opening(self, data: mujoco.MjData) -> float:
        """Current jaw opening (m): the sum of the two finger slides."""
        return float(data.qpos[self.finger_qpos].sum())


def descends(model: mujoco.MjModel, body: int, ancestor: int) -> bool:
    """Whether ``body`` is ``ancestor`` or lies below it in the model's body tree."""
    while body > 0:
        if body == ancestor:
            return True
        body = model.body_parentid[body]
    return False


def on_table(scene: Scene, i: int) -> bool:
    """Whether object ``i`` of a work-cell scene rests on the table top (not in the bin, not fallen off).
    The bin's inner side reaches 3 cm under the table's footprint, so an object in the bin is never on the
    table."""
    t = scene.object_position(i)
    return bool(-0.01 < t[2] < 0.5 and np.all(np.abs(t[:2]) < TABLE_HALF_SIZE) and not BIN.contains(t))
