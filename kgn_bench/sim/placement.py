"""Random object placement on the table and physical settling in MuJoCo.

Five arrangements, all world frame (table top z = 0, table centre at the origin):

* ``place_objects`` (the reference's, used by the data and the ``single_object`` / ``multi_object`` tasks):
  each object gets a resting orientation drawn from its shape's ``rest_poses`` (by probability), a yaw
  ~U[0, 2π) about world z and a position ``xy ~ N(0, σ²I)`` (σ = 6.25 cm), just above the table. Objects are
  placed one by one, redrawing a position that would interpenetrate an already placed object; then gravity
  settles them and the settled poses are the recorded ones.
* ``pile_objects`` (VGN/GIGA's pile): an open box (``PileConfig``: inner half size, wall height) stands on the
  table; the objects are dropped into it one at a time, each in a uniformly random orientation at
  ``xy ~ U[−a, a]²`` above the current top of the pile, and left to come to rest; then the box is lifted away
  and the pile settles. Objects may roll off the table then: they are reported, not an error.
* ``pack_objects`` (VGN/GIGA's packed): every object stands upright (``upright_rotation``) with a random
  yaw at ``xy ~ U[−h, h]²``, redrawn while it would interpenetrate one already placed; ``h`` grows by 10 %
  after every ``tries_per_object`` failed draws, so ten objects still fit. Then gravity settles them.

* ``giga_pile`` and ``giga_pack``: GIGA's own pile and packed rounds, number for number (``kgn_bench.giga``; the
  objects' sizes are drawn before the scene is built, ``shapes.giga_objects``). Objects whose origin
  leaves GIGA's workspace cube are retired (``Scene.retire_object``), as GIGA deletes them; both return the
  objects still in play.

The box is a mocap body of the scene (``add_pile_box``), parked far above the work cell when not in use.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from kgn_bench import giga
from kgn_bench.geometry import frame_from_xz, make_pose, rot_z
from kgn_bench.sim.scene import GROUP_VISUAL, TABLE_HALF_SIZE, TIMESTEP, PhysicsError, Scene

__all__ = ["GIGA_PILE", "PILE_BOX", "PileConfig", "PlacementConfig", "SettleStats", "add_pile_box", "giga_pack",
           "giga_pile", "initial_pose", "off_table", "pack_objects", "pile_objects", "place_objects",
           "rectify_axisymmetric", "retire_outside_workspace", "settle", "settle_to_rest", "upright_rotation"]

PILE_BOX = "pile_box"
"""Name of the mocap body holding the pile box's walls."""
_BOX_PARK = np.array([0.0, 0.0, 40.0])


@dataclass(frozen=True)
class PlacementConfig:
    xy_sigma: float = 0.0625
    xy_limit: float = 0.3
    drop_height: float = 0.002
    tries_per_object: int = 100
    settle_time_max: float = 3.0
    settle_time_min: float = 0.2
    linear_tol: float = 2e-3
    angular_tol: float = 2e-2
    settle_damping: float = 0.02
    """Damping (N·s/m, N·m·s/rad) on the objects' free joints while settling only. Static rest poses do
    not depend on it; it removes the slow spin and roll that round contacts (a lying rod, a sphere
    pressed against a neighbour) otherwise accumulate numerically."""
    hold_time: float = 0.5
    hold_tol: float = 2e-3
    hold_rounds: int = 6
    """``settle_to_rest``: after each damped settle, ``hold_time`` s of undamped physics may move no object on
    the table more than ``hold_tol`` m; otherwise it settles again, at most ``hold_rounds`` times."""


@dataclass(frozen=True)
class PileConfig:
    """The pile and packed arrangements (m, s). ``box_half``: inner half size of the pile box; ``box_height``:
    its walls; ``drop_half``: objects are dropped at xy ~ U[−drop_half, drop_half]²; ``drop_gap``: their
    lowest point starts this far above the top of what is already in the box; ``drop_settle``: how long each
    dropped object may take to come to rest; ``packed_half``: half size of the square the packed objects stand
    in (grown by 10 % after each ``tries_per_object`` failed draws)."""

    box_half: float = 0.11
    box_height: float = 0.16
    wall: float = 0.01
    drop_half: float = 0.05
    drop_gap: float = 0.03
    drop_settle: float = 1.0
    packed_half: float = 0.08
    tries_per_object: int = 100


GIGA_PILE = PileConfig(box_half=giga.WORKSPACE_SIZE / 2.0, drop_half=giga.PILE_DROP_HALF, packed_half=giga.PACKED_HALF)
"""GIGA's numbers (``kgn_bench.giga``) for ``giga_pile`` and ``giga_pack``: the drop square's half side (5 cm),
the packed square's (7 cm, never widened), each drop's time to come to rest (``drop_settle`` = 1 s, GIGA's
timeout) and the pile box, whose inner walls stand on the workspace cube's sides (x, y = ±0.15 m). Its walls are
``box_height`` = 16 cm high, below the 20 cm drop height: an object dropped at ``|x|, |y| ≤ 5 cm`` has its origin
≥ 10 cm from every wall and 4 cm above its top, so it starts clear of the walls unless part of it lies ≥ 10.8 cm
from its origin; five objects at most 7 cm thick (``giga.MAX_EXTENT``) pile well below the top, and an object
that bounces off the pile meets a wall rather than leaving the cube. Build the scene with
``add_pile_box(root, GIGA_PILE)``."""


def add_pile_box(root, config: PileConfig = PileConfig()) -> None:
    """Add the pile box (four walls on a mocap body, parked out of the way) to a scene's MJCF ``root``."""
    box = root.worldbody.add("body", name=PILE_BOX, mocap=True, pos=_BOX_PARK)
    h, t, H = config.box_half, config.wall, config.box_height
    for k, (dx, dy, sx, sy) in enumerate(((h + t / 2, 0, t / 2, h + t), (-h - t / 2, 0, t / 2, h + t),
                                          (0, h + t / 2, h, t / 2), (0, -h - t / 2, h, t / 2))):
        box.add("geom", name=f"pile_wall{k}", type="box", size=(sx, sy, H / 2), pos=(dx, dy, H / 2),
                rgba=(0.6, 0.6, 0.65, 1), contype=1, conaffinity=3, group=GROUP_VISUAL)


def _move_box(scene: Scene, position: np.ndarray) -> None:
    body = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_BODY, PILE_BOX)
    if body < 0:
        raise ValueError("the scene has no pile box: build it with add_pile_box")
    scene.data.mocap_pos[scene.model.body_mocapid[body]] = position
    scene.forward()


def _top_of(scene: Scene, objects: np.ndarray) -> float:
    """World z of the highest point of the bounding spheres of ``objects``' geoms (0 with none)."""
    if len(objects) == 0:
        return 0.0
    geoms = np.flatnonzero(np.isin(scene.geom_label, objects + 1))
    return float(np.max(scene.data.geom_xpos[geoms, 2] + scene.model.geom_rbound[geoms]))


def _park(scene: Scene, objects: range | list[int]) -> None:
    """Put ``objects`` out of the way, object ``i`` at world (10 + 2i, 10, 1) m, upright and still (they fall
    freely from there while physics runs, off the table and ignored by the settle, until they are placed)."""
    for i in objects:
        scene.set_object_pose(i, make_pose(t=np.array([10.0 + 2.0 * i, 10.0, 1.0])))


def upright_rotation(shape) -> np.ndarray:
    """The rest orientation (``shape.rest_poses``) that keeps the shape's own +z most nearly up: every shape
    is modelled standing on its base with +z up (a cylinder or a can on its end, a mug on its foot)."""
    return max((r.R for r in shape.rest_poses()), key=lambda R: R[2, 2])


def off_table(scene: Scene) -> list[int]:
    """Objects whose origin is below the table top or outside its extent."""
    out = []
    for i in range(len(scene.objects)):
        t = scene.object_position(i)
        if t[2] < -0.01 or np.any(np.abs(t[:2]) > TABLE_HALF_SIZE):
            out.append(i)
    return out


_UNIT_CORNERS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)


def _footprint_radius(scene: Scene, i: int) -> float:
    """Radius (m) of a vertical cylinder about object ``i``'s origin that holds the corners of its geoms'
    bounding boxes (``geom_aabb``, in each geom's frame)."""
    geoms = np.flatnonzero(scene.geom_label == i + 1)
    aabb = scene.model.geom_aabb[geoms]  # (G, 6): centre, half sizes
    local = aabb[:, None, :3] + _UNIT_CORNERS[None] * aabb[:, None, 3:]
    R = scene.data.geom_xmat[geoms].reshape(-1, 3, 3)
    world = np.einsum("gij,gkj->gki", R, local) + scene.data.geom_xpos[geoms, None]
    return float(np.max(np.linalg.norm(world[..., :2] - scene.object_pose(i)[:2, 3], axis=-1)))


def _nested(scene: Scene, i: int) -> bool:
    """Whether object ``i``'s origin lies inside the footprint of an object placed before it, or one of theirs
    inside its own: a small object dropped inside a ring or an open cylinder touches nothing, but is not packed
    beside it. (Kinematics must be current: ``object_contacts`` just ran them.)"""
    xy = scene.object_pose(i)[:2, 3]
    r_i = _footprint_radius(scene, i)
    for j in range(i):
        d = float(np.linalg.norm(scene.object_pose(j)[:2, 3] - xy))
        if d < max(r_i, _footprint_radius(scene, j)):
            return True
    return False


def pile_objects(scene: Scene, rng: np.random.Generator, config: PileConfig = PileConfig(),
                 placement: PlacementConfig = PlacementConfig()) -> None:
    """Drop the objects one by one into the pile box, then lift the box away and let the pile settle."""
    n = len(scene.objects)
    _park(scene, range(n))
    _move_box(scene, np.zeros(3))
    for i in range(n):
        R = Rotation.random(random_state=rng).as_matrix()
        xy = rng.uniform(-config.drop_half, config.drop_half, size=2)
        z = _top_of(scene, np.arange(i)) + config.drop_gap - scene.objects[i].shape.lowest_point(R)
        scene.set_object_pose(i, make_pose(R, np.array([xy[0], xy[1], z])))
        scene.forward()
        settle(scene, replace(placement, settle_time_max=config.drop_settle), strict=False)
    _move_box(scene, _BOX_PARK)
    settle_to_rest(scene, placement)


def pack_objects(scene: Scene, rng: np.random.Generator, config: PileConfig = PileConfig(),
                 placement: PlacementConfig = PlacementConfig()) -> None:
    """Stand the objects upright, tightly, in the packed square; ``PhysicsError`` if one finds no spot."""
    n = len(scene.objects)
    _park(scene, range(n))
    for i in range(n):
        shape = scene.objects[i].shape
        upright = upright_rotation(shape)
        for attempt in range(10 * config.tries_per_object):
            half = config.packed_half * 1.1 ** (attempt // config.tries_per_object)
            R = rot_z(rng.uniform(0.0, 2.0 * np.pi)) @ upright
            xy = rng.uniform(-half, half, size=2)
            z = -shape.lowest_point(R) + placement.drop_height
            scene.set_object_pose(i, make_pose(R, np.array([xy[0], xy[1], z])))
            if not scene.object_contacts(i, np.arange(i)) and not _nested(scene, i):
                break
        else:
            raise PhysicsError(f"no free spot for object {i} ({shape.name}) in the packed square")
    scene.forward()
    settle_to_rest(scene, placement)


def _settle_and_cull(scene: Scene, objects: list[int], placement: PlacementConfig) -> list[int]:
    """GIGA's "wait for rest, delete the objects outside the workspace, until none is deleted": ``settle_to_rest``,
    then retire every one of ``objects`` whose origin (world frame) left the workspace cube (``giga.in_workspace``),
    again while any was retired. Returns the ones left."""
    while True:
        settle_to_rest(scene, placement)
        if not retire_outside_workspace(scene, objects):
            return [i for i in objects if i not in scene.retired]


def _pile_box_half(scene: Scene) -> float:
    """Inner half size (m) of the scene's pile box, read from its first wall (``add_pile_box``)."""
    g = mujoco.mj_name2id(scene.model, mujoco.mjtObj.mjOBJ_GEOM, "pile_wall0")
    if g < 0:
        raise ValueError("the scene has no pile box: build it with add_pile_box(root, GIGA_PILE)")
    return float(scene.model.geom_pos[g, 0] - scene.model.geom_size[g, 0])


def giga_pile(scene: Scene, rng: np.random.Generator, placement: PlacementConfig = PlacementConfig()) -> list[int]:
    """GIGA's pile of all the scene's objects; returns the objects in play (the others are retired).

    World frame (table top z = 0, the workspace cube's centre line is the z axis). The pile box (``GIGA_PILE``,
    ``ValueError`` for another box) stands on the table around the cube. Each object in turn, in index order: a
    uniformly random rotation ``R`` (Haar measure on SO(3)), its origin at ``(x, y, PILE_DROP_HEIGHT)`` = (x, y,
    0.2 m) with ``x, y ~ U(−PILE_DROP_HALF, PILE_DROP_HALF)`` = U(−5, 5) cm (``kgn_bench.giga``), then
    ``GIGA_PILE.drop_settle`` = 1 s at most to come to rest (``settle``). Where the pile already reaches the drop
    point (GIGA does not look), the object starts 1 cm higher at a time until it touches no earlier object. Then
    the box is lifted away, and ``settle_to_rest``, retiring every object whose origin left the workspace cube
    (``giga.in_workspace``), is repeated until none is retired. The objects' sizes are the scene's
    (``shapes.giga_objects``: GIGA draws each scale at the drop, from U(0.8, 1.0)); the draws are made in
    another order than GIGA's."""
    if abs(_pile_box_half(scene) - GIGA_PILE.box_half) > 1e-9:
        raise ValueError(f"giga_pile needs GIGA's pile box (inner half size {GIGA_PILE.box_half} m), the scene's is "
                         f"{_pile_box_half(scene):.3f} m: build it with add_pile_box(root, GIGA_PILE)")
    n = len(scene.objects)
    _park(scene, range(n))
    _move_box(scene, np.zeros(3))
    drop = replace(placement, settle_time_max=GIGA_PILE.drop_settle)
    for i in range(n):
        R = Rotation.random(random_state=rng).as_matrix()
        xy = rng.uniform(-GIGA_PILE.drop_half, GIGA_PILE.drop_half, size=2)
        pose = make_pose(R, np.array([xy[0], xy[1], giga.PILE_DROP_HEIGHT]))
        scene.set_object_pose(i, pose)
        while scene.object_contacts(i, np.arange(i)) and pose[2, 3] < 1.0:
            pose[2, 3] += 0.01
            scene.set_object_pose(i, pose)
        scene.forward()
        settle(scene, drop, strict=False)
    _move_box(scene, _BOX_PARK)
    return _settle_and_cull(scene, list(range(n)), placement)


def giga_pack(scene: Scene, rng: np.random.Generator, count: int = giga.OBJECTS_PER_ROUND,
              placement: PlacementConfig = PlacementConfig()) -> list[int]:
    """GIGA's packed round: the scene's objects are the candidates, tried in index order (``shapes.scaled.giga_names``
    draws ``PACKED_TRIES`` of them) while fewer than ``count`` objects stand and fewer than ``PACKED_TRIES`` were
    tried. Returns the objects in play; every other object is retired (``Scene.retire_object``).

    World frame (table top z = 0, the workspace cube's centre line is the z axis). A candidate stands in its
    canonical orientation turned about the world z axis, ``R = R_z(ψ)`` with ``ψ ~ U(0, 2π)`` (every shape is
    modelled standing on its base with +z up), its origin at ``x, y ~ U(−PACKED_HALF, PACKED_HALF)`` =
    U(−7, 7) cm and at the height that puts its lowest point ``placement.drop_height`` = 2 mm above the table
    (``z = 0.002 − lowest_point(R)``). If it then touches an object already standing, it is taken away (retired)
    and does not count; otherwise ``settle_to_rest``, retiring every standing object whose origin left the
    workspace cube (``giga.in_workspace``), is repeated until none is retired. The objects' sizes are the scene's
    (``shapes.giga_objects``: GIGA draws each scale, from U(0.7, 0.9), at the try); the draws are made in
    another order than GIGA's."""
    n = len(scene.objects)
    _park(scene, range(n))
    standing: list[int] = []
    tried = 0
    while len(standing) < count and tried < min(n, giga.PACKED_TRIES):
        i, tried = tried, tried + 1
        R = rot_z(rng.uniform(0.0, 2.0 * np.pi))
        xy = rng.uniform(-GIGA_PILE.packed_half, GIGA_PILE.packed_half, size=2)
        z = placement.drop_height - scene.objects[i].shape.lowest_point(R)
        scene.set_object_pose(i, make_pose(R, np.array([xy[0], xy[1], z])))
        if scene.object_contacts(i, np.asarray(standing, dtype=int)):
            scene.retire_object(i)
            continue
        _park(scene, range(tried, n))  # the candidates still waiting start their fall again
        scene.forward()
        standing = _settle_and_cull(scene, [*standing, i], placement)
    for i in range(tried, n):
        scene.retire_object(i)
    return standing


@dataclass
class SettleStats:
    sim_time: float
    steps: int


def initial_pose(scene: Scene, i: int, rng: np.random.Generator, sigma: float, config: PlacementConfig) -> np.ndarray:
    """A random resting pose for object ``i``: rest orientation, random yaw, xy ~ N(0, σ²) clipped to the
    placement area, lowest point ``drop_height`` above the table top."""
    shape = scene.objects[i].shape
    rest = shape.rest_poses()
    k = rng.choice(len(rest), p=np.array([r.probability for r in rest]))
    R = rot_z(rng.uniform(0.0, 2.0 * np.pi)) @ rest[k].R
    while True:
        xy = rng.normal(0.0, sigma, size=2)
        if np.all(np.abs(xy) <= config.xy_limit):
            break
    z = -shape.lowest_point(R) + config.drop_height
    return make_pose(R, np.array([xy[0], xy[1], z]))


def place_objects(scene: Scene, rng: np.random.Generator, config: PlacementConfig = PlacementConfig()) -> None:
    """Place every object without interpenetration; later tries widen σ by 10 % each.

    Objects not yet placed are parked far from the table. Raises ``PhysicsError`` if an object finds no
    free spot within ``tries_per_object`` draws.
    """
    n = len(scene.objects)
    _park(scene, range(n))
    for i in range(n):
        for attempt in range(config.tries_per_object):
            sigma = config.xy_sigma * (1.0 + 0.1 * attempt)
            pose = initial_pose(scene, i, rng, sigma, config)
            scene.set_object_pose(i, pose)
            if not scene.object_contacts(i, np.arange(i)):
                break
        else:
            raise PhysicsError(f"no free spot for object {i} ({scene.objects[i].shape.name}) after "
                               f"{config.tries_per_object} tries")
    scene.forward()


def settle(scene: Scene, config: PlacementConfig = PlacementConfig(), strict: bool = True) -> SettleStats:
    """Let gravity act until every object is at rest (speeds under tolerance) or the time limit.

    Raises ``PhysicsError`` if the state diverges or (``strict``) an object leaves the table top; objects
    that left it are not counted when judging rest (they may still be falling to the floor).
    """
    chunk = 10
    steps = 0
    max_steps = int(config.settle_time_max / TIMESTEP)
    min_steps = int(config.settle_time_min / TIMESTEP)
    dofs = np.concatenate([np.arange(a, a + 6) for a in scene.qvel_adr]) if len(scene.qvel_adr) else np.zeros(0, int)
    saved = scene.model.dof_damping[dofs].copy()
    scene.model.dof_damping[dofs] = config.settle_damping
    try:
        while steps < max_steps:
            scene.step(chunk)
            steps += chunk
            if steps >= min_steps:
                lin, ang = scene.object_speeds()
                judged = np.ones(len(lin), dtype=bool)
                if not strict:
                    judged[off_table(scene)] = False
                if np.all(lin[judged] < config.linear_tol) and np.all(ang[judged] < config.angular_tol):
                    break
    finally:
        scene.model.dof_damping[dofs] = saved
    for i in off_table(scene) if strict else ():
        t = scene.object_position(i)
        raise PhysicsError(f"object {i} ({scene.objects[i].shape.name}) left the table at {np.round(t, 3)}")
    for i in range(len(scene.objects)):
        scene.data.qvel[scene.qvel_adr[i] : scene.qvel_adr[i] + 6] = 0.0
    scene.forward()
    return SettleStats(sim_time=steps * TIMESTEP, steps=steps)


def settle_to_rest(scene: Scene, config: PlacementConfig = PlacementConfig()) -> SettleStats:
    """``settle`` (not strict), then check that the objects stay where they came to rest: ``hold_time`` s of
    physics without the settling damping may move no object still on the table more than ``hold_tol``
    (its origin's displacement, world frame); otherwise settle again from the moving state, at most
    ``hold_rounds`` times. A settle judges rest from the speeds of one instant and then zeroes them, so a
    pile caught in a momentary balance (a ring on its rim against a rod, a sphere on a slope the damping
    slowed) would otherwise start to topple once the trial begins, and the first grasp would close on the
    place where an object was. Returns the total time simulated."""
    steps = 0
    hold_steps = max(1, int(config.hold_time / TIMESTEP))
    for _ in range(config.hold_rounds):
        steps += settle(scene, config, strict=False).steps
        before = np.array([scene.object_position(i) for i in range(len(scene.objects))])
        scene.step(hold_steps)
        steps += hold_steps
        moved = np.linalg.norm([scene.object_position(i) for i in range(len(scene.objects))] - before, axis=1)
        gone = off_table(scene)
        moved[gone] = 0.0
        if np.all(moved <= config.hold_tol):
            break
    for i in range(len(scene.objects)):
        scene.data.qvel[scene.qvel_adr[i] : scene.qvel_adr[i] + 6] = 0.0
    scene.forward()
    return SettleStats(sim_time=steps * TIMESTEP, steps=steps)


def rectify_axisymmetric(scene: Scene, max_axis_z: float = 0.9) -> None:
    """Turn lying axisymmetric objects about their own axis so that their +x points down.

    A solid of revolution looks the same after any turn about its axis, so this only fixes the phase of
    the frame: the side family's θ = 0 grasp then approaches from above (the reference implementation's
    stick rectification). Objects whose axis is within ``arccos(max_axis_z)`` of vertical are left as
    they are. The physical state is updated so the body pose stays the recorded pose.
    """
    down = np.array([0.0, 0.0, -1.0])
    for i, obj in enumerate(scene.objects):
        if not obj.shape.axisymmetric:
            continue
        T = scene.object_pose(i)
        axis = T[:3, 2]
        if abs(axis[2]) > max_axis_z:
            continue
        x = down - axis * (down @ axis)
        x /= np.linalg.norm(x)
        R = frame_from_xz(x, axis)
        scene.set_object_pose(i, make_pose(R, T[:3, 3]))
    scene.forward()


def retire_outside_workspace(scene: Scene, objects: list[int] | None = None) -> list[int]:
    """Take every one of ``objects`` (default: every object not retired yet) whose origin has left GIGA's
    workspace cube (``giga.in_workspace``) out of the scene (``Scene.retire_object``), as GIGA deletes them;
    returns their indices."""
    candidates = range(len(scene.objects)) if objects is None else objects
    out = [i for i in candidates if i not in scene.retired and not giga.in_workspace(scene.object_position(i))]
    for i in out:
        scene.retire_object(i)
    return out
