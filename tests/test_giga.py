"""GIGA's setting: the constants against their own definitions, the task files against the constants, and a
round of each GIGA protocol run in the harness with the floating Panda hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from kgn_bench import giga
from kgn_bench.bench.attempt import execute_floating
from kgn_bench.bench.trial import camera_pose, capture, check_cameras, run_trial
from kgn_bench.camera import INTRINSICS
from kgn_bench.config import load_task
from kgn_bench.detectors import make_detector
from kgn_bench.sim.control import IK
from kgn_bench.sim.floating_hand import FloatingHand

TASKS = Path(__file__).resolve().parents[1] / "tasks"


def test_the_workspace_cube_in_the_world_frame():
    assert giga.VOXEL_SIZE == pytest.approx(0.0075)
    assert giga.in_workspace(np.array([0.0, 0.0, 0.0]))  # the table centre
    assert giga.in_workspace(np.array([0.149, -0.149, 0.249]))
    assert not giga.in_workspace(np.array([0.16, 0.0, 0.05]))
    assert not giga.in_workspace(np.array([0.0, 0.0, -0.051]))  # below the cube's floor, 5 cm under the table
    assert giga.in_workspace(np.zeros((2, 3))).shape == (2,)


def test_the_camera_is_their_side_view():
    """GIGA's camera_on_sphere(origin = (0.15, 0.15, 0.10), r = 0.6, θ = π/3, φ = −π/2) in their cube's frame."""
    theta, phi, r = np.pi / 3, -np.pi / 2, 2 * giga.WORKSPACE_SIZE
    origin = np.array([0.15, 0.15, 0.10]) + giga.WORKSPACE_ORIGIN
    eye = origin + r * np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    for kind in ("pile", "packed"):
        task = load_task(TASKS / f"giga_{kind}.toml")
        T = camera_pose(task, 0)
        np.testing.assert_allclose(T[:3, 3], eye, atol=1e-9)
        forward = (origin - eye) / np.linalg.norm(origin - eye)
        np.testing.assert_allclose(T[:3, 2], forward, atol=1e-9)  # OpenCV z looks at their origin
        assert T[2, 1] < 0  # image y points down the world
        assert np.allclose(task.camera.target, giga.CAMERA_TARGET)
        cam = task.camera
        assert (cam.distance, cam.elevation_deg, cam.azimuth_deg) == (
            giga.CAMERA_DISTANCE, giga.CAMERA_ELEVATION_DEG, giga.CAMERA_AZIMUTH_DEG)
        assert cam.pinhole == INTRINSICS["giga"] and (cam.pinhole.fx, cam.pinhole.cx) == (540.0, 320.0)
        assert (cam.noise_model, cam.depth_noise, cam.far) == ("dex", 1.0, giga.CAMERA_FAR)


@pytest.mark.parametrize("kind", ["pile", "packed"])
def test_the_task_files_are_gigas_setting(kind):
    task = load_task(TASKS / f"giga_{kind}.toml")
    assert task.protocol == f"giga_{kind}" and task.spec.giga
    assert task.objects_per_scene == giga.OBJECTS_PER_ROUND
    assert task.execution.max_consecutive_failures == giga.MAX_CONSECUTIVE_FAILURES
    assert (task.execution.hand, task.execution.gripper, task.selector.mode) == ("floating", "panda", "top")
    assert task.execution.geometry.max_width == pytest.approx(0.08)
    assert len(task.objects) == 43 and task.objects[0].startswith("pb_")


@pytest.mark.parametrize("kind", ["pile", "packed"])
def test_a_giga_round_runs_with_the_floating_hand(kind):
    """One round of antipodal on three primitives: the objects are GIGA-sized, the hand's grasps are executed and
    counted, and the round ends by GIGA's rules."""
    task = load_task(TASKS / f"giga_{kind}.toml")
    from dataclasses import replace

    task = replace(task, objects=("cuboid", "stick", "semi_sphere"), trials=1)
    assert check_cameras(task) == 1
    record = run_trial(task, 0, make_detector("antipodal"), IK())
    assert 1 <= len(record.objects) <= 5 and record.placed == len(record.placed_objects)
    if kind == "pile":
        assert len(record.objects) == 5 and record.fell_at_setup == 5 - record.placed
    else:
        assert record.fell_at_setup == 0 and record.placed == len(record.objects)
    executed = [a for a in record.attempts if a.reason not in ("no_candidate", "unreachable")]
    assert executed and all(a.width is not None and a.width <= 0.08 for a in executed)
    assert all(a.reason in (None, "collision", "missed", "dropped_lift") for a in executed), record.attempts
    assert record.removed == sum(a.success for a in record.attempts) <= record.placed
    fails = 0
    for a in record.attempts[:-1]:  # no two failures in a row before the last attempt
        fails = 0 if a.success else fails + 1
        assert fails < 2
    first = record.attempts[0]  # made again up to its selection, then executed by the capture's own hand
    cap = capture(task, 0, make_detector("antipodal"), IK(), 1)
    assert first.selected is not None and cap.selection.index == first.selected
    assert isinstance(cap.hand, FloatingHand)
    assert execute_floating(cap.hand, cap.selection).reason == first.reason
