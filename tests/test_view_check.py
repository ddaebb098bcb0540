"""The workspace view check on the rendered segmentation of the real work cell."""

import numpy as np
import pytest

from kgn_bench.bench.trial import check_cameras
from kgn_bench.camera import orbit_pose
from kgn_bench.config import apply_override, load_task
from kgn_bench.sim.control import IK
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.robot import PARK_Q, add_workcell
from kgn_bench.sim.scene import Scene
from kgn_bench.sim.view_check import ViewError, check_view, workspace_points


def _task(**camera):
    task = load_task("single_object")
    for key, value in camera.items():
        task = apply_override(task, f"camera.{key}", value)
    return task


@pytest.fixture(scope="module")
def cell():
    from kgn_bench.sim.control import Executor

    scene = Scene([], extend=add_workcell)
    Executor(scene, IK()).reset(PARK_Q)
    with SceneRenderer(scene) as renderer:
        yield scene, renderer


def test_the_default_and_other_clear_views_pass(cell):
    scene, renderer = cell
    for d, el, az in ((0.8, 60, 90), (1.0, 35, 0), (0.6, 90, 0), (0.8, 30, 180)):
        check_view(renderer, scene, orbit_pose(d, np.deg2rad(el), np.deg2rad(az)), np.zeros(3))


def test_a_camera_inside_the_arm_is_refused_naming_the_arm(cell):
    scene, renderer = cell
    with pytest.raises(ViewError, match="the arm blocks the view") as e:
        check_view(renderer, scene, orbit_pose(0.8, np.deg2rad(35), np.deg2rad(90)), np.zeros(3), "cam")
    assert str(e.value).startswith("cam: ") and "\n" not in str(e.value)


def test_a_camera_looking_away_is_refused(cell):
    scene, renderer = cell
    with pytest.raises(ViewError, match="cannot see the workspace"):
        check_view(renderer, scene, orbit_pose(0.8, np.deg2rad(60), np.deg2rad(90)), np.array([0.6, 0.0, 0.0]))
    assert workspace_points(np.zeros(3)).shape == (81, 3)


def test_task_cameras_are_checked_per_trial_and_named():
    assert check_cameras(_task()) == 1  # a fixed camera: one check
    with pytest.raises(ViewError, match=r"single_object: the camera \(distance 0.80 m, elevation 35°, azimuth 90°\)"):
        check_cameras(_task(elevation_deg="35"))
    # a range that reaches into the arm is refused, naming the first trial whose camera is blocked
    with pytest.raises(ViewError, match=r"the camera of trial \d+ \(distance"):
        check_cameras(_task(elevation_deg="30,90", azimuth_deg="60,120"))
    ranged = _task(elevation_deg="45,90", azimuth_deg="-60,60", distance="0.6,1.0")
    assert check_cameras(ranged) == ranged.n_trials


def test_a_run_with_a_blocked_camera_is_refused_before_anything_is_written(tmp_path):
    from kgn_bench.bench.runner import run_benchmark

    with pytest.raises(ViewError, match="the arm blocks the view"):
        run_benchmark(_task(elevation_deg="35"), "oracle", tmp_path / "run", progress=False)
    assert not (tmp_path / "run").exists()
