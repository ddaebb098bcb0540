"""Tabletop scenes composed with dm_control's mjcf and compiled into MuJoCo.

World frame: origin at the centre of the table top, +z up; the table is a 1 m × 1 m × 4 cm
box whose top face is z = 0. Each object is a free body whose frame is the shape's object frame, so the
body pose *is* the object pose recorded in annotations (``T_world_obj``).

Geom groups: 0 = rendered objects and table, 1 = rendered robot and work cell (``sim/robot.py``),
3 = collision-only (hidden), 5 = the gripper proxy (hidden). Collision
bits: table and objects have ``contype = 1, conaffinity = 3``; the proxy has ``contype = 2,
conaffinity = 0``, so it touches objects but never moves them and is parked far away during physics.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import mujoco
import numpy as np
from dm_control import mjcf

from kgn_bench.camera import REALSENSE, Intrinsics, convert_camera_frame
from kgn_bench.errors import KGNBenchError
from kgn_bench.geometry import make_pose, matrix_from_quat_wxyz, quat_wxyz_from_matrix
from kgn_bench.shapes.base import GeomSpec, Shape

__all__ = ["GROUP_ROBOT", "GROUP_VISUAL", "TABLE_HALF_SIZE", "TABLE_THICKNESS", "PhysicsError", "Scene", "SceneObject",
           "SceneState"]

TABLE_HALF_SIZE = 0.5
TABLE_THICKNESS = 0.04
TIMESTEP = 0.002

OBJECT_FRICTION = (1.0, 0.005, 0.002)
OBJECT_CONDIM = 6
"""Objects get torsional and rolling friction: without rolling resistance a lying tube or stick never
comes to rest in MuJoCo's soft contact model (it drifts at mm/s, measured 8-60 mm in 2 s)."""
TABLE_FRICTION = (0.8, 0.005, 0.0001)
TABLE_RGBA = (0.5, 0.5, 0.5, 1.0)

GROUP_VISUAL, GROUP_ROBOT, GROUP_COLLISION, GROUP_PROXY = 0, 1, 3, 5
_PROXY_PARK = np.array([0.0, 0.0, 50.0])
_RETIRED_AT = np.array([20.0, 0.0, -30.0])  # world frame, m: where retired objects rest (Scene.retire_object)
_DIVERGENCE_WARNINGS = np.array(
    [mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC], dtype=int
)
_FULL_WARNINGS = np.array([mujoco.mjtWarning.mjWARN_CONTACTFULL, mujoco.mjtWarning.mjWARN_CNSTRFULL], dtype=int)
"""MuJoCo drops contacts or constraints when the arena is full and only warns: the physics is then wrong."""


ARENA_BASE_MB = 64
ARENA_MB_PER_GEOM = 2
"""MuJoCo's arena (contacts, constraints and the solver's stack) is sized from the scene: a base plus a
share per object collision geom, since the number of contacts grows with the pieces that can touch
(a pile of five household objects reached 3286 contacts and 19718 constraint rows, more than the default
13.6 MB arena holds). Linux commits the arena's pages only when used, so a large one costs nothing."""


class PhysicsError(KGNBenchError, RuntimeError):
    """The simulation produced non-finite state, objects left the table, or MuJoCo stopped with a fatal error."""


def _fatal_message(e: Exception, time: float) -> str:
    return f"MuJoCo stopped at t = {time:.3f} s: {str(e).strip().splitlines()[0]}"


def arena_megabytes(objects: list[SceneObject]) -> float:
    """The arena of a scene holding ``objects``: ``ARENA_BASE_MB + ARENA_MB_PER_GEOM × collision geoms``."""
    return ARENA_BASE_MB + ARENA_MB_PER_GEOM * sum(len(o.shape.collision_geoms()) for o in objects)


@dataclass
class SceneObject:
    """An object in a scene: its shape, colour (RGB in [0, 1]) and world pose ``T_world_obj``."""

    shape: Shape
    color: tuple[float, float, float]
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))


def _msh_bytes(mesh) -> bytes:
    """A mesh in MuJoCo's binary .msh format: int32 (nvertex, nnormal, ntexcoord, nface), then float32
    vertices and int32 faces. Much faster to serialise and parse than XML vertex lists."""
    v = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
    f = np.ascontiguousarray(mesh.faces, dtype=np.int32)
    header = np.array([len(v), 0, 0, len(f)], dtype=np.int32)
    return header.tobytes() + v.tobytes() + f.tobytes()


def _add_geom(body, spec: GeomSpec, name: str, *, visual: bool, collision: bool, density: float, rgba, assets) -> None:
    attrs: dict = dict(name=name, type=spec.kind, pos=spec.pos, quat=spec.quat, rgba=rgba)
    if spec.kind == "mesh":
        assets.add("mesh", name=name, file=mjcf.Asset(_msh_bytes(spec.mesh), ".msh"))
        attrs["mesh"] = name
    else:
        attrs["size"] = spec.size
    if collision:
        attrs.update(contype=1, conaffinity=3, condim=OBJECT_CONDIM, friction=OBJECT_FRICTION, density=density)
        attrs["group"] = GROUP_VISUAL if visual else GROUP_COLLISION
    else:
        attrs.update(contype=0, conaffinity=0, density=0.0, group=GROUP_VISUAL)
    body.add("geom", **attrs)


def build_mjcf(objects: list[SceneObject], intrinsics: Intrinsics = REALSENSE) -> mjcf.RootElement:
    """Compose the MJCF of a scene: table, lights, one fixed camera, the objects and the gripper proxy.

    The camera's intrinsics are set in pixels; MuJoCo's principal point is measured from the image
    centre in continuous (corner-origin) pixel coordinates, so ``principalpixel = (W/2 − cx − ½,
    H/2 − cy − ½)`` puts OpenCV's ``(cx, cy)`` where K says (tested by projection). Elements are added
    in this order (the MJCF text depends on it): options and visual settings, light, table, camera, the
    objects in list order, the proxy.
    """
    root = mjcf.RootElement(model="kgn_scene")
    _set_options(root, objects, intrinsics)
    world = root.worldbody
    _add_room(world, intrinsics)
    for i, obj in enumerate(objects):
        _add_object(world, i, obj, root.asset)
    proxy = world.add("body", name="proxy", mocap=True, pos=_PROXY_PARK)
    proxy.add("geom", name="proxy", type="box", size=(0.05, 0.01, 0.05), contype=2, conaffinity=0,
              group=GROUP_PROXY, rgba=(1, 0, 0, 0.3))
    return root


def _set_options(root: mjcf.RootElement, objects: list[SceneObject], intrinsics: Intrinsics) -> None:
    """The compiler, physics options, arena size (``arena_megabytes``), offscreen buffer and visual settings."""
    root.compiler.angle = "radian"
    root.option.timestep = TIMESTEP
    root.option.integrator = "implicitfast"
    root.option.cone = "elliptic"
    root.option.impratio = 10
    root.size.memory = f"{round(arena_megabytes(objects) * 1024)}K"
    vis_global = getattr(root.visual, "global")
    vis_global.offwidth = intrinsics.width
    vis_global.offheight = intrinsics.height
    root.visual.quality.offsamples = 0
    # Fix the scale MuJoCo derives the clip planes from (parked bodies would otherwise inflate it):
    # near = znear·extent = 1 cm, far = zfar·extent = 10 m.
    root.statistic.extent = 1.0
    root.statistic.center = (0.0, 0.0, 0.0)
    root.visual.map.znear = 0.01
    root.visual.map.zfar = 10.0
    root.visual.headlight.ambient = (0.35, 0.35, 0.35)
    root.visual.headlight.diffuse = (0.55, 0.55, 0.55)
    root.visual.headlight.specular = (0.1, 0.1, 0.1)


def _add_room(world, intrinsics: Intrinsics) -> None:
    """The light, the table (its top is the world plane z = 0) and the fixed camera (posed later by
    ``Scene.set_camera_pose``; intrinsics in pixels, see ``build_mjcf``)."""
    world.add("light", name="top", pos=(0.0, 0.0, 2.0), dir=(0.0, 0.0, -1.0), directional=True,
              diffuse=(0.35, 0.35, 0.35), specular=(0.05, 0.05, 0.05), castshadow=False)
    world.add(
        "geom", name="table", type="box", size=(TABLE_HALF_SIZE, TABLE_HALF_SIZE, TABLE_THICKNESS / 2),
        pos=(0.0, 0.0, -TABLE_THICKNESS / 2), rgba=TABLE_RGBA, friction=TABLE_FRICTION,
        contype=1, conaffinity=3, group=GROUP_VISUAL,
    )
    w, h = intrinsics.width, intrinsics.height
    world.add(
        "camera", name="camera", mode="fixed", pos=(0.0, 0.0, 1.0),
        focalpixel=(intrinsics.fx, intrinsics.fy),
        principalpixel=(w / 2.0 - intrinsics.cx - 0.5, h / 2.0 - intrinsics.cy - 0.5),
        sensorsize=(w * 1e-5, h * 1e-5), resolution=(w, h),
    )


def _add_object(world, i: int, obj: SceneObject, assets) -> None:
    """Object ``i``: a free body ``object_i`` at its world pose, its collision pieces (a density that gives the
    shape's mass) and, where they differ, its visual geoms (massless)."""
    shape = obj.shape
    pieces = shape.collision_geoms()
    density = shape.mass() / sum(p.volume() for p in pieces)
    rgba = (*obj.color, 1.0)
    body = world.add("body", name=f"object_{i}", pos=obj.pose[:3, 3], quat=quat_wxyz_from_matrix(obj.pose[:3, :3]))
    body.add("freejoint", name=f"object_{i}")
    visuals = shape.visual_geoms()
    shared = visuals is not None and visuals == pieces
    for k, piece in enumerate(pieces):
        _add_geom(body, piece, f"object_{i}_col{k}", visual=shared, collision=True, density=density,
                  rgba=rgba, assets=assets)
    if not shared:
        for k, vis in enumerate(visuals):
            _add_geom(body, vis, f"object_{i}_vis{k}", visual=True, collision=False, density=0.0,
                      rgba=rgba, assets=assets)


@dataclass(frozen=True)
class SceneState:
    """What ``Scene.restore`` needs to put a scene back where ``Scene.snapshot`` found it: MuJoCo's integration
    state (``mjSTATE_INTEGRATION``, a flat float64 array) and the objects retired from the scene."""

    state: np.ndarray
    retired: tuple[int, ...]


class Scene:
    """A compiled scene: the MuJoCo model and data plus the maps from objects to bodies and geoms."""

    def __init__(self, objects: list[SceneObject], intrinsics: Intrinsics = REALSENSE,
                 extend: Callable[[mjcf.RootElement], None] | None = None) -> None:
        """Compile ``objects`` into a scene; ``extend`` may add to the MJCF first (e.g. the robot work cell)."""
        self.objects = objects
        self.intrinsics = intrinsics
        root = build_mjcf(objects, intrinsics)
        if extend is not None:
            extend(root)
        self.model = mujoco.MjModel.from_xml_string(root.to_xml_string(), root.get_assets())
        self.data = mujoco.MjData(self.model)
        m = self.model
        self.body_ids = np.array(
            [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"object_{i}") for i in range(len(objects))], dtype=int
        )
        self.qpos_adr = np.array([m.jnt_qposadr[m.body_jntadr[b]] for b in self.body_ids], dtype=int)
        self.qvel_adr = np.array([m.jnt_dofadr[m.body_jntadr[b]] for b in self.body_ids], dtype=int)
        # geom id -> instance label (0 = table/background, i + 1 = object i)
        body_to_label = np.zeros(m.nbody, dtype=np.int32)
        body_to_label[self.body_ids] = np.arange(1, len(objects) + 1)
        self.geom_label = body_to_label[m.geom_bodyid]
        self.camera_id = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_CAMERA, "camera")
        self.proxy_geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "proxy")
        proxy_body = m.geom_bodyid[self.proxy_geom]
        self.proxy_mocap = m.body_mocapid[proxy_body]
        assert m.body_bvhnum[proxy_body] == 1, "the proxy body holds exactly one geom"
        self._proxy_bvh = int(m.body_bvhadr[proxy_body])
        self.table_geom = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "table")
        self.collision_geoms = np.flatnonzero(m.geom_contype == 1)
        self.retired: dict[int, np.ndarray] = {}  # object index -> its qpos at rest (retire_object)
        for i, obj in enumerate(objects):
            self.set_object_pose(i, obj.pose)
        self.forward()

    # -- object state -------------------------------------------------------------------------
    def set_object_pose(self, i: int, pose: np.ndarray) -> None:
        """Teleport object ``i`` to ``pose`` (T_world_obj) with zero velocity (kinematics not updated)."""
        a = self.qpos_adr[i]
        self.data.qpos[a : a + 3] = pose[:3, 3]
        self.data.qpos[a + 3 : a + 7] = quat_wxyz_from_matrix(pose[:3, :3])
        v = self.qvel_adr[i]
        self.data.qvel[v : v + 6] = 0.0

    def retire_object(self, i: int) -> None:
        """Take object ``i`` out of the scene for good: its geoms stop colliding (also with the gripper proxy)
        and it is held at rest at ``_RETIRED_AT`` + (i, 0, 0) m in the world frame, below the table and beyond
        the camera's far plane, so it makes no contacts and is neither seen nor on the table. MuJoCo keeps the
        body and its free joint; ``step`` puts it back there, at zero velocity, after every call (it touches
        nothing, so nothing else feels it)."""
        m = self.model
        mine = np.flatnonzero(self.geom_label == i + 1)
        m.geom_contype[mine] = 0
        m.geom_conaffinity[mine] = 0
        self.collision_geoms = self.collision_geoms[self.geom_label[self.collision_geoms] != i + 1]
        self.set_object_pose(i, make_pose(np.eye(3), _RETIRED_AT + np.array([float(i), 0.0, 0.0])))
        a = self.qpos_adr[i]
        self.retired[i] = self.data.qpos[a : a + 7].copy()
        self.forward()

    def object_pose(self, i: int) -> np.ndarray:
        """Current ``T_world_obj`` of object ``i`` from the simulator state."""
        a = self.qpos_adr[i]
        q = self.data.qpos[a : a + 7]
        return make_pose(matrix_from_quat_wxyz(q[3:]), q[:3])

    def object_position(self, i: int) -> np.ndarray:
        """Current world position (m) of object ``i``'s origin: ``object_pose(i)[:3, 3]`` without the rotation."""
        a = self.qpos_adr[i]
        return self.data.qpos[a : a + 3].copy()

    def snapshot(self) -> SceneState:
        """The scene's whole state, for ``restore`` into a scene built from the same objects and work cell."""
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        state = np.zeros(mujoco.mj_stateSize(self.model, spec))
        mujoco.mj_getState(self.model, self.data, state, spec)
        return SceneState(state, tuple(sorted(self.retired)))

    def restore(self, snap: SceneState) -> None:
        """Put the scene in the state ``snap`` (``snapshot`` of a scene compiled from the same objects and work
        cell): its objects retired, then MuJoCo's integration state (time, positions, velocities, controls,
        mocap targets, warm start) bit for bit, and the derived quantities recomputed."""
        spec = mujoco.mjtState.mjSTATE_INTEGRATION
        if len(snap.state) != mujoco.mj_stateSize(self.model, spec):
            raise ValueError(f"a snapshot of {len(snap.state)} numbers does not fit this scene's state of "
                             f"{mujoco.mj_stateSize(self.model, spec)}")
        for i in snap.retired:
            self.retire_object(i)
        mujoco.mj_setState(self.model, self.data, np.asarray(snap.state, dtype=float), spec)
        self.forward()

    def object_poses(self) -> np.ndarray:
        if not self.objects:
            return np.zeros((0, 4, 4))
        return np.stack([self.object_pose(i) for i in range(len(self.objects))])

    def object_speeds(self) -> tuple[np.ndarray, np.ndarray]:
        """Linear (m/s) and angular (rad/s) speed of every object."""
        lin = np.array([np.linalg.norm(self.data.qvel[v : v + 3]) for v in self.qvel_adr])
        ang = np.array([np.linalg.norm(self.data.qvel[v + 3 : v + 6]) for v in self.qvel_adr])
        return lin, ang

    def object_contacts(self, i: int, others: np.ndarray) -> bool:
        """True if object ``i`` currently penetrates any object whose index is in ``others``."""
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_collision(self.model, self.data)
        ncon = self.data.ncon
        if ncon == 0 or len(others) == 0:
            return False
        geoms = self.data.contact.geom[:ncon]
        labels = self.geom_label[geoms]
        a, b = labels[:, 0] - 1, labels[:, 1] - 1
        other = np.isin(b, others) & (a == i) | np.isin(a, others) & (b == i)
        return bool(np.any(other))

    def step(self, n: int) -> None:
        """Advance physics ``n`` steps; raises ``PhysicsError`` if the state diverged.

        MuJoCo resets the state itself when it meets NaN or huge values, counting a BADQPOS, BADQVEL or
        BADQACC warning; any new such warning (or a non-finite state) is a blow-up. A full arena (contacts
        or constraints dropped: CONTACTFULL, CNSTRFULL) and a MuJoCo fatal error are ``PhysicsError`` too.
        """
        warnings = self.data.warning.number[_DIVERGENCE_WARNINGS].copy()
        full = self.data.warning.number[_FULL_WARNINGS].copy()
        try:
            mujoco.mj_step(self.model, self.data, nstep=n)
        except mujoco.FatalError as e:
            raise PhysicsError(_fatal_message(e, self.data.time)) from None
        for i, qpos in self.retired.items():  # back to rest (raw state: a pose conversion per call costs)
            a, v = self.qpos_adr[i], self.qvel_adr[i]
            self.data.qpos[a : a + 7] = qpos
            self.data.qvel[v : v + 6] = 0.0
        if np.any(self.data.warning.number[_FULL_WARNINGS] > full):
            raise PhysicsError(f"MuJoCo's arena ({self.model.narena / 2**20:.0f} MB) is full at t = "
                               f"{self.data.time:.3f} s: contacts were dropped")
        if np.any(self.data.warning.number[_DIVERGENCE_WARNINGS] > warnings) or not (
            np.all(np.isfinite(self.data.qpos)) and np.all(np.isfinite(self.data.qvel))
        ):
            raise PhysicsError(f"simulation diverged (non-finite or huge state) at t = {self.data.time:.3f} s")

    def forward(self) -> None:
        """Recompute the derived state (kinematics, contacts, forces); ``PhysicsError`` on a MuJoCo fatal error."""
        try:
            mujoco.mj_forward(self.model, self.data)
        except mujoco.FatalError as e:
            raise PhysicsError(_fatal_message(e, self.data.time)) from None

    # -- camera -------------------------------------------------------------------------------
    def set_camera_pose(self, pose_cv: np.ndarray) -> None:
        """Place the scene camera at an OpenCV camera-to-world pose."""
        pose_mj = convert_camera_frame(pose_cv)
        self.model.cam_pos[self.camera_id] = pose_mj[:3, 3]
        self.model.cam_quat[self.camera_id] = quat_wxyz_from_matrix(pose_mj[:3, :3])
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)

    # -- gripper proxy ------------------------------------------------------------------------
    @contextmanager
    def proxy_only_collisions(self) -> Iterator[None]:
        """Within the block, only the gripper proxy generates contacts (object/table pairs are off)."""
        m = self.model
        saved = m.geom_contype.copy(), m.geom_conaffinity.copy()
        m.geom_contype[self.collision_geoms] = 0
        try:
            yield
        finally:
            m.geom_contype[:], m.geom_conaffinity[:] = saved
            self.data.mocap_pos[self.proxy_mocap] = _PROXY_PARK
            mujoco.mj_kinematics(m, self.data)

    def exclude_object_from_proxy(self, i: int | None) -> None:
        """Make object ``i`` invisible to the proxy (``None`` re-enables every object)."""
        m = self.model
        objects = self.collision_geoms[self.geom_label[self.collision_geoms] > 0]
        m.geom_conaffinity[objects] = 3
        if i is not None:
            mine = self.collision_geoms[self.geom_label[self.collision_geoms] == i + 1]
            m.geom_conaffinity[mine] = 0

    def proxy_hits_object(self, centre: np.ndarray, R: np.ndarray, half_extents: np.ndarray) -> bool:
        """Whether a proxy box (world centre, rotation, half extents) penetrates an enabled object."""
        m, d = self.model, self.data
        g = self.proxy_geom
        m.geom_size[g] = half_extents
        m.geom_rbound[g] = float(np.linalg.norm(half_extents))
        m.geom_aabb[g, 3:] = half_extents
        m.bvh_aabb[self._proxy_bvh, 3:] = half_extents  # midphase culls with the body's compiled box
        d.mocap_pos[self.proxy_mocap] = centre
        d.mocap_quat[self.proxy_mocap] = quat_wxyz_from_matrix(R)
        mujoco.mj_kinematics(m, d)
        mujoco.mj_collision(m, d)
        return d.ncon > 0
