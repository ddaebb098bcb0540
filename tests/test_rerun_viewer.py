"""Tests of viz.rerun_viewer: merging, copying, opening and serving real rerun recordings."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest
import rerun.chunk

from kgn_bench.errors import OutputError
from kgn_bench.geometry import make_pose, rot_z
from kgn_bench.shapes.primitives import Cuboid
from kgn_bench.sim.scene import Scene, SceneObject
from kgn_bench.viz.recording import Recorder, RecordingError
from kgn_bench.viz.rerun_viewer import (
    copy_recording,
    merge_recordings,
    open_viewer,
    rerun_command,
    serve_web,
    web_viewer_url,
)


def _verify(path: Path) -> None:
    proc = subprocess.run([*rerun_command(), "rrd", "verify", str(path)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]


def _recordings(path: Path) -> dict[str, set[str]]:
    """Recording id → entity paths of every recording store in an .rrd."""
    reader = rerun.chunk.RrdReader(path)
    return {e.recording_id: set(reader.store(store=e).schema().entity_paths()) for e in reader.recordings()}


@pytest.fixture(scope="module")
def trials(tmp_path_factory):
    """Two short recordings of a real scene: geometry, ten states of its physics, an outcome line."""
    root = tmp_path_factory.mktemp("rrd")
    scene = Scene([SceneObject(Cuboid((0.05, 0.06, 0.07)), (0.8, 0.2, 0.2),
                               make_pose(rot_z(0.3), [0.02, -0.01, 0.1]))])
    paths = [root / "trial_0.rrd", root / "trial_1.rrd"]
    for i, path in enumerate(paths):
        with Recorder(path, f"trial_{i}") as rec:
            rec.log_geometry(scene.model)
            for _ in range(10):
                scene.step(10)
                rec.log_state(scene.model, scene.data)
            rec.log_outcome(f"attempt 1: success (trial {i})", time=float(scene.data.time))
    return paths


def test_merge_keeps_each_trial_as_its_own_recording(trials, tmp_path):
    out = tmp_path / "merged" / "all.rrd"
    merge_recordings(trials, out)
    _verify(out)
    recordings = _recordings(out)
    assert set(recordings) == {"trial_0", "trial_1"}
    for paths in recordings.values():
        assert {"/world/bodies/object_0", "/world/bodies/world/table", "/outcome"} <= paths
    assert [p.name for p in out.parent.iterdir()] == ["all.rrd"]  # no temporary file left behind


def test_merge_names_a_missing_or_corrupt_input(trials, tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nope\.rrd"):
        merge_recordings([trials[0], tmp_path / "nope.rrd"], tmp_path / "out.rrd")
    bad = tmp_path / "corrupt.rrd"
    bad.write_bytes(b"this is not an rrd file" * 10)
    with pytest.raises(RuntimeError, match=r"corrupt\.rrd"):
        merge_recordings([bad], tmp_path / "out.rrd")
    assert not (tmp_path / "out.rrd").exists()


def test_open_viewer_names_a_missing_recording(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing"):
        open_viewer(tmp_path / "missing.rrd")


def _free_port_pair() -> int:
    for port in range(19090, 19990, 2):
        with socket.socket() as a, socket.socket() as b:
            if a.connect_ex(("127.0.0.1", port)) != 0 and b.connect_ex(("127.0.0.1", port + 1)) != 0:
                return port
    raise RuntimeError("no free port pair")


def test_replay_web_serves_the_viewer_on_localhost(trials):
    port = _free_port_pair()
    cmd = [sys.executable, "-m", "kgn_bench.cli", "replay", str(trials[0]), "--web", "--port", str(port)]
    # A shell without job control starts background jobs with SIGINT ignored, and the child would inherit that
    # (`pytest &`); restore the default so the child's Python turns Ctrl-C into KeyboardInterrupt as at a terminal.
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        line = proc.stdout.readline()
        assert line.strip() == f"serving {trials[0]}: open {web_viewer_url(port)}"
        page = urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=10).read().decode()
        assert "rerun" in page.lower()
        with pytest.raises(RecordingError, match=f"port {port} on 127.0.0.1 is in use"):
            serve_web(trials[0], port=port, wait=False)
    finally:
        proc.send_signal(2)  # Ctrl-C: the command stops its server
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, 9)
            proc.wait()
            pytest.fail("replay --web did not stop within 30 s of Ctrl-C")
    assert proc.returncode == 0
    with socket.socket() as s:
        assert s.connect_ex(("127.0.0.1", port)) != 0  # nothing left listening


def test_copy_recording_is_atomic_and_names_a_bad_destination(trials, tmp_path):
    copy_recording(trials[0], tmp_path / "c.rrd")
    assert (tmp_path / "c.rrd").read_bytes() == trials[0].read_bytes()
    with pytest.raises(OutputError, match=r"^cannot write /sys/c\.rrd: "):
        copy_recording(trials[0], Path("/sys/c.rrd"))


def test_recordings_are_verified_by_the_cli(trials):
    for path in trials:
        _verify(path)
