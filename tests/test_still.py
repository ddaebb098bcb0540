"""Stills from a real recorded pile round: one per attempt, the logged grasps projected into the image."""

from __future__ import annotations

import json

import numpy as np
import pytest

from kgn_bench.cli import main
from kgn_bench.viz.recording import SELECTED_COLOR, RecordingError
from kgn_bench.viz.still import draw_still, read_observations, save_still

CYAN = np.array(SELECTED_COLOR, dtype=np.uint8)


@pytest.fixture(scope="module")
def pile_run(tmp_path_factory):
    """One recorded oracle pile round (5 objects, raw mode)."""
    out = tmp_path_factory.mktemp("still") / "run"
    argv = ["run", "pile", "--detector", "oracle", "--trials", "1", "--workers", "1", "--record", "--quiet",
            "--out", str(out)]
    assert main(argv) == 0
    return out


def test_one_observation_per_attempt_with_its_candidates_and_outcome(pile_run):
    record = json.loads((pile_run / "trials.jsonl").read_text().splitlines()[0])
    observations = read_observations(pile_run / "recording.rrd", trial=0)
    assert len(observations) == len(record["attempts"]) >= 2
    times = [o.time for o in observations]
    assert times == sorted(times) and len(set(times)) == len(times)
    for number, (obs, attempt) in enumerate(zip(observations, record["attempts"], strict=True), start=1):
        assert obs.rgb.shape == (480, 640, 3) and obs.rgb.dtype == np.uint8
        assert obs.outcome.startswith(f"attempt {number}: ")
        assert (attempt["object"] or attempt["reason"]) in obs.outcome
        assert len(obs.candidates) == 4 * attempt["candidates"]  # a gripper sketch is 4 segments
        assert len(obs.selected) == (4 if attempt["selected"] is not None else 0)


def test_the_executed_grasp_is_drawn_inside_the_image_in_cyan(pile_run):
    obs = read_observations(pile_run / "recording.rrd")[0]
    assert not np.all(obs.rgb == CYAN, axis=-1).any()
    still = draw_still(obs)
    cyan = np.all(still == CYAN, axis=-1)
    rows, cols = np.nonzero(cyan)
    assert cyan.sum() > 50
    # the executed grasp is on the pile, near the image centre (the camera looks at the table's centre)
    assert abs(rows.mean() - 240) < 120 and abs(cols.mean() - 320) < 160
    assert np.array_equal(still[30:], draw_still(obs, caption="x")[30:])


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # rerun's note on the deliberately broken file
def test_cli_writes_a_png_and_names_a_missing_attempt_or_a_broken_file(pile_run, tmp_path, capsys):
    out = tmp_path / "still.png"
    assert main(["replay", str(pile_run), "--still", str(out), "--attempt", "2"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "attempt 2" in capsys.readouterr().out
    n = len(read_observations(pile_run / "recording.rrd"))
    with pytest.raises(RecordingError, match=f"has {n} attempts, no attempt {n + 1}"):
        save_still(pile_run / "recording.rrd", tmp_path / "x.png", attempt=n + 1)
    with pytest.raises(RecordingError, match="no recording of trial 3"):
        save_still(pile_run / "recording.rrd", tmp_path / "x.png", trial=3)
    broken = tmp_path / "broken.rrd"
    broken.write_bytes(b"not a recording" * 10)
    assert main(["replay", str(broken), "--still", str(tmp_path / "y.png")]) != 0
    assert "is not a rerun recording (.rrd)" in capsys.readouterr().err
    broken.write_bytes((pile_run / "recording.rrd").read_bytes()[:100])  # a recording cut short
    assert main(["replay", str(broken), "--still", str(tmp_path / "y.png")]) != 0
    assert "not a readable rerun recording" in capsys.readouterr().err
    assert not (tmp_path / "x.png").exists() and not (tmp_path / "y.png").exists()
