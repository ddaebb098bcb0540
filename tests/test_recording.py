"""Rerun recordings of a real scene: every Recorder method, `rerun rrd verify`, entity paths, merging."""

from __future__ import annotations

import subprocess
from pathlib import Path

import mujoco
import numpy as np
import pytest
import rerun as rr
import rerun.chunk

from kgn_bench.camera import orbit_pose
from kgn_bench.geometry import make_pose, rot_y, rot_z
from kgn_bench.gripper import GRIPPER
from kgn_bench.shapes.primitives import Cuboid
from kgn_bench.sim.render import SceneRenderer
from kgn_bench.sim.scene import Scene, SceneObject
from kgn_bench.viz.recording import Recorder, gripper_sketch, sanitize_path_part, score_colors
from kgn_bench.viz.rerun_viewer import rerun_command

EXPECTED_PATHS = {
    "/world/camera",
    "/world/camera/rgb",
    "/world/camera/depth",
    "/world/points",
    "/world/candidates",
    "/world/selected",
    "/outcome",
    "/world/bodies/object_0",
    "/world/bodies/object_0/object_0_col0",
    "/world/bodies/world/table",
}


def _scene() -> Scene:
    box = Cuboid((0.05, 0.06, 0.07))
    return Scene([SceneObject(box, (0.8, 0.2, 0.2), make_pose(rot_z(0.3), [0.02, -0.01, 0.1]))])


def _verify(path: Path) -> None:
    proc = subprocess.run([*rerun_command(), "rrd", "verify", str(path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]


def _recordings(path: Path) -> dict[str, set[str]]:
    """Recording id → entity paths of every recording store in an .rrd, read from the file's manifest."""
    reader = rerun.chunk.RrdReader(path)
    return {e.recording_id: set(reader.store(store=e).schema().entity_paths()) for e in reader.recordings()}


def _write_trial(path: Path, name: str, scene: Scene, view, camera_pose: np.ndarray, seed: int) -> None:
    """A short trial: geometry, 20 states of real physics at 20 Hz, one observation, candidates, outcome."""
    rng = np.random.default_rng(seed)
    m, d = scene.model, scene.data
    steps_per_state = round(0.05 / m.opt.timestep)
    with Recorder(path, name) as rec:
        rec.log_geometry(m)
        assert rec.body_paths == ["world/bodies/object_0"]
        for _ in range(20):
            scene.step(steps_per_state)
            mujoco.mj_kinematics(m, d)
            rec.log_state(m, d)
        rec.log_observation(view.rgb, view.depth, scene.intrinsics.K, camera_pose, time=float(d.time))
        poses = np.stack([make_pose(rot_y(np.pi / 2) @ rot_z(a), [0.0, 0.0, 0.15]) for a in rng.uniform(0, 3, 5)])
        rec.log_candidates(poses, rng.uniform(0.02, 0.1, 5), rng.normal(size=5), selected=2, time=float(d.time))
        rec.log_outcome("attempt 1: success (cuboid)", time=float(d.time) + 0.5)


@pytest.fixture(scope="module")
def trials(tmp_path_factory):
    """Two recordings of the same real scene (one real render shared by both)."""
    root = tmp_path_factory.mktemp("rrd")
    scene = _scene()
    camera_pose = orbit_pose(0.7, np.deg2rad(60), 0.4)
    with SceneRenderer(scene) as renderer:
        view = renderer.render(camera_pose)
    paths = [root / "trial_0.rrd", root / "trial_1.rrd"]
    for i, path in enumerate(paths):
        mujoco.mj_resetData(scene.model, scene.data)
        scene.set_object_pose(0, scene.objects[0].pose)
        _write_trial(path, f"trial_{i}", scene, view, camera_pose, seed=i)
    return paths


def test_recording_verifies_and_holds_every_entity(trials):
    path = trials[0]
    _verify(path)
    recordings = _recordings(path)
    assert list(recordings) == ["trial_0"]
    missing = EXPECTED_PATHS - recordings["trial_0"]
    assert not missing, f"missing entity paths {missing} in {sorted(recordings['trial_0'])}"
    assert "/world/bodies/proxy" not in recordings["trial_0"]  # hidden geom group 5


def test_state_needs_geometry_and_closed_recorder_refuses(tmp_path):
    scene = _scene()
    rec = Recorder(tmp_path / "r.rrd", "r")
    with pytest.raises(RuntimeError, match="log_geometry"):
        rec.log_state(scene.model, scene.data)
    rec.log_geometry(scene.model)
    assert rr.get_global_data_recording() is None and rr.get_thread_local_data_recording() is None
    times = []
    for _ in range(250):  # more than one buffer of states: sent in two column batches
        scene.step(1)
        rec.log_state(scene.model, scene.data)
        times.append(scene.data.time)
    rec.log_candidates(np.zeros((0, 4, 4)), np.zeros(0), np.zeros(0), selected=None, time=0.0)
    with pytest.raises(RuntimeError, match="already"):
        rec.log_geometry(scene.model)
    with pytest.raises(IndexError):
        rec.log_candidates(np.eye(4)[None], np.array([0.05]), np.array([1.0]), selected=1, time=0.0)
    rec.close()
    rec.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        rec.log_outcome("late", time=1.0)
    _verify(tmp_path / "r.rrd")
    assert _recordings(tmp_path / "r.rrd")["r"] >= {"/world/bodies/object_0", "/world/candidates", "/world/selected"}
    chunks = [ch for ch in rerun.chunk.RrdReader(tmp_path / "r.rrd").store().stream()
              if ch.entity_path == "/world/bodies/object_0"]
    logged = np.concatenate([ch.to_record_batch().column("sim_time").cast("int64").to_numpy() for ch in chunks])
    np.testing.assert_allclose(np.sort(logged), np.array(times) * 1e9, atol=1.0)  # seconds → ns


def test_gripper_sketch_identity_pose():
    L = GRIPPER.finger_length
    s = gripper_sketch(np.eye(4)[None], np.array([0.08]))
    assert s.shape == (1, 4, 2, 3)
    expected = np.array(
        [
            [[-L, 0, 0.04], [0, 0, 0.04]],  # left finger: base → tip
            [[-L, 0, -0.04], [0, 0, -0.04]],  # right finger
            [[-L, 0, 0.04], [-L, 0, -0.04]],  # palm
            [[-L, 0, 0], [-L - 0.04, 0, 0]],  # stem
        ]
    )
    np.testing.assert_allclose(s[0], expected, atol=1e-15)


def test_gripper_sketch_transforms_by_each_pose():
    # Top-down grasp: approach +x_grasp = −z_world, closing axis z_grasp = +y_world, TCP at (0.1, 0.2, 0.3).
    R = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]])
    poses = np.stack([np.eye(4), make_pose(R, [0.1, 0.2, 0.3])])
    s = gripper_sketch(poses, np.array([0.0, 0.06]))
    L = GRIPPER.finger_length
    np.testing.assert_allclose(s[0, 0], [[-L, 0, 0], [0, 0, 0]], atol=1e-15)  # closed jaw: fingers meet
    np.testing.assert_allclose(s[1, 0, 1], [0.1, 0.23, 0.3], atol=1e-15)  # left fingertip
    np.testing.assert_allclose(s[1, 1, 1], [0.1, 0.17, 0.3], atol=1e-15)  # right fingertip
    np.testing.assert_allclose(s[1, 2], [[0.1, 0.23, 0.3 + L], [0.1, 0.17, 0.3 + L]], atol=1e-15)
    np.testing.assert_allclose(s[1, 3, 1], [0.1, 0.2, 0.3 + L + 0.04], atol=1e-15)
    with pytest.raises(ValueError):
        gripper_sketch(poses, np.array([0.05]))


def test_score_colors_and_path_parts():
    c = score_colors(np.array([-3.0, 7.0, 2.0]))
    np.testing.assert_array_equal(c, [[255, 0, 0], [0, 255, 0], [255, 255, 0]])
    np.testing.assert_array_equal(score_colors(np.array([4.0, 4.0])), [[0, 255, 0], [0, 255, 0]])
    with pytest.raises(ValueError):
        score_colors(np.array([0.0, np.nan]))
    assert sanitize_path_part("robot/link 3") == "robot_link_3"
