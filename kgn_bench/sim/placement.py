"""Random object placement on the table and physical settling in MuJoCo.

Each object gets a resting orientation drawn from its shape's ``rest_poses`` (by probability), a yaw
~U[0, 2π) about world z and a position ``xy ~ N(0, σ²I)`` (σ = 6.25 cm, as the reference implementation), just
above the table. Objects are placed one by one, redrawing a position that would interpenetrate an
already placed object; then gravity settles them and the settled poses are the recorded ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kgn_bench.geometry import frame_from_xz, make_pose, rot_z
from kgn_bench.sim.scene import TABLE_HALF_SIZE, TIMESTEP, PhysicsError, Scene

__all__ = ["PlacementConfig", "SettleStats", "initial_pose", "place_objects", "rectify_axisymmetric", "settle"]


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
    for i in range(n):
        scene.set_object_pose(i, make_pose(t=np.array([10.0 + 2.0 * i, 10.0, 1.0])))
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


def settle(scene: Scene, config: PlacementConfig = PlacementConfig()) -> SettleStats:
    """Let gravity act until every object is at rest (speeds under tolerance) or the time limit.

    Raises ``PhysicsError`` if the state diverges or an object leaves the table top.
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
                if np.all(lin < config.linear_tol) and np.all(ang < config.angular_tol):
                    break
    finally:
        scene.model.dof_damping[dofs] = saved
    for i in range(len(scene.objects)):
        t = scene.object_pose(i)[:3, 3]
        if t[2] < -0.01 or np.any(np.abs(t[:2]) > TABLE_HALF_SIZE):
            raise PhysicsError(f"object {i} ({scene.objects[i].shape.name}) left the table at {np.round(t, 3)}")
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
