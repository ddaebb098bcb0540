"""One grasp attempt in the real work cell: a thin upright plate taken from above, squeezed with the gripper's
force limit, lifted, carried and released in the bin; and the failure reasons of attempts that cannot hold."""

import mujoco
import numpy as np
import pytest

from kgn_bench.bench.attempt import execute_grasp, held_object
from kgn_bench.bench.selector import Selection
from kgn_bench.config import ExecutionConfig
from kgn_bench.geometry import make_pose
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.primitives import Cuboid
from kgn_bench.sim.control import IK, Executor
from kgn_bench.sim.robot import BIN, PARK_Q, add_workcell
from kgn_bench.sim.scene import Scene, SceneObject

PLATE = Cuboid((0.012, 0.06, 0.06))  # 1.2 cm thick, standing on its 6 cm × 1.2 cm edge
# top-down grasp frame closing along world x (the plate's thin side): approach x = −z, closing z = +x
DOWN_X = np.stack([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]], axis=1)
EXEC = ExecutionConfig()


@pytest.fixture(scope="module")
def ik():
    return IK()


def _cell(ik):
    scene = Scene([SceneObject(PLATE, (0.8, 0.3, 0.2), make_pose(t=[0.0, 0.0, 0.03]))], extend=add_workcell)
    executor = Executor(scene, ik)
    executor.reset(PARK_Q)
    executor.wait(0.2)
    return scene, executor


def _selection(ik, tcp_z, width=PLATE.size[0]):
    grasp = make_pose(DOWN_X, [0.0, 0.0, tcp_z])
    pre = grasp.copy()
    pre[:3, 3] -= EXEC.pregrasp_distance * grasp[:3, 0]
    r_pre = ik.solve(pre)
    r_grasp = ik.solve(grasp, r_pre.q)
    assert r_pre.ok and r_grasp.ok
    return Selection(index=0, scores=np.ones(1), grasp=grasp, candidate=grasp, pregrasp=pre,
                     width=float(GRIPPER.opening(width)), q_pregrasp=r_pre.q, q_grasp=r_grasp.q)


def _pad_normal_forces(scene, executor):
    """Total normal force (N) on each pad from its contacts with the plate."""
    d, forces = scene.data, []
    f6 = np.zeros(6)
    for pad in executor.robot.pad_geoms:
        total = 0.0
        for c in range(d.ncon):
            if pad in d.contact.geom[c] and scene.geom_label[d.contact.geom[c]].max() == 1:
                mujoco.mj_contactForce(scene.model, d, c, f6)
                total += f6[0]
        forces.append(total)
    return np.array(forces)


def test_the_force_limit_sets_the_squeeze_on_a_thin_plate(ik):
    scene, executor = _cell(ik)
    sel = _selection(ik, tcp_z=0.04)  # fingertips 2 cm down the 6 cm plate
    executor.set_gripper(sel.width, 0.2)
    executor.move_joints(sel.q_pregrasp)
    executor.move_linear(sel.grasp, EXEC.approach_time)
    executor.set_gripper(0.0, 0.4)
    executor.wait(0.25)
    assert held_object(scene, executor) == 0
    assert executor.robot.opening(scene.data) == pytest.approx(PLATE.size[0], abs=2e-3)
    # each finger pushes with half the tendon's force: the limit, not a gain times the plate's thickness
    np.testing.assert_allclose(_pad_normal_forces(scene, executor), GRIPPER.grip_force / 2, rtol=0.15)


def test_a_plate_taken_from_above_ends_in_the_bin(ik):
    scene, executor = _cell(ik)
    result = execute_grasp(scene, executor, _selection(ik, tcp_z=0.04), EXEC)
    assert result.reason is None and result.object == 0 and result.detail == ""
    assert BIN.contains(scene.object_pose(0)[:3, 3])


def test_jaws_closing_beside_the_plate_miss(ik):
    scene, executor = _cell(ik)
    sel = _selection(ik, tcp_z=0.04)
    sel.grasp[:3, 3] += [0.05, 0.0, 0.0]  # 5 cm to the side: the plate is outside the jaws
    sel.pregrasp[:3, 3] += [0.05, 0.0, 0.0]
    sel.q_pregrasp, sel.q_grasp = ik.solve(sel.pregrasp).q, ik.solve(sel.grasp).q
    result = execute_grasp(scene, executor, sel, EXEC)
    assert result.reason == "missed" and result.object is None and "jaws closed to" in result.detail
    assert np.linalg.norm(scene.object_pose(0)[:2, 3]) < 0.01  # the plate stayed where it was
