"""The command line (kgn_bench.cli.app): the parser's one-line argument errors with exit code 2, user errors
(KGNBenchError) as one line and exit 2, any other exception a defect with its traceback, and a --help that
loads nothing heavy."""

import subprocess
import sys
from pathlib import Path

import pytest

from kgn_bench.cli import main

CI_TASK = str(Path(__file__).resolve().parents[1] / "tasks" / "ci_oracle.toml")


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["data", "generate", "--mode", "multi", "--scenes", "0", "--out", "x"], "--scenes: must be ≥ 1"),
        (["data", "generate", "--mode", "triple", "--out", "x"], "invalid choice"),
        (["data", "generate", "--mode", "multi", "--seed", "abc", "--out", "x"], "expected an integer"),
        (["data", "generate", "--mode", "multi"], "--out"),
        (["data", "show", "/nonexistent", "--scene", "0", "--out", "a.png"], "no dataset.json"),
        (["bogus"], "invalid choice"),
        (["study", "pnp-noise", "--sigmas", "-1"], "noise levels must be non-negative"),
        (["run", CI_TASK, "--detector", "oracle", "--set", "camera.depth_noise"], "expected section.name=value"),
        (["run", CI_TASK, "--detector", "oracle", "--set", "camera.depth_noise=-2"], "depth_noise must be in"),
        (["sweep", CI_TASK, "--detector", "oracle", "--param", "camera.fov", "--values", "1"], "unknown setting"),
        (["experiment", "table1", "--multi", "/nonexistent", "--single", "/nonexistent"], "no complete"),
        (["replay", "run", "--web", "--port", "65535"], "--port: must be ≤ 65534"),
        (["replay", "GARBAGE"], "is not a rerun recording"),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(argv, fragment, capsys, tmp_path):
    if argv[:2] == ["data", "show"]:
        argv = [a if a != "/nonexistent" else str(tmp_path / "missing") for a in argv]
        fragment = "scene.json"
    if "GARBAGE" in argv:  # bytes that are not a recording are refused, not served
        (tmp_path / "bad.rrd").write_bytes(bytes(range(200)))
        argv = [a if a != "GARBAGE" else str(tmp_path / "bad.rrd") for a in argv]
    with pytest.raises(SystemExit) as e:
        rc = main(argv)
        raise SystemExit(rc)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("kgn-bench: error:") and fragment in err


# -- user errors and defects: only a KGNBenchError is one line; anything else is a bug with its traceback ----
@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["run", "{tmp}/missing.toml", "--detector", "oracle"], "no such task file"),
        (["run", "{tmp}/bad.toml", "--detector", "oracle"], "needs 'protocol'"),
        (["run", CI_TASK, "--detector", "oracle", "--address", "10.0.0.1:6379", "--out", "{tmp}/r"],
         "--address and --num-gpus need --backend ray"),
        (["run", CI_TASK, "--detector", "nope", "--out", "{tmp}/r"], "unknown detector 'nope'"),
        (["ship", "{tmp}/bad.pt", "--name", "x", "--out", "{tmp}/w"], "not a readable checkpoint"),
        (["eval", "vision", "--weights", "kgnv2", "--variant", "bogus", "--data", "{tmp}"], "unknown variant 'bogus'"),
        (["objects", "show", "teapot_x", "--out", "{tmp}/o.png"], "unknown object 'teapot_x'"),
        (["data", "generate", "--mode", "single", "--objects", "teapot_x", "--out", "{tmp}/g"],
         "unknown object 'teapot_x'"),
        (["objects", "check-labeller", "--shapes", "teapot_x", "--out", "{tmp}/l"], "unknown primitive 'teapot_x'"),
        (["perf", "detector", "--variant", "oracle"], "is privileged"),
        (["check", "{tmp}/no_run", "--baseline", "{tmp}/b.json"], "summary.json not found"),
    ],
)
def test_bad_inputs_are_one_line_and_exit_2(argv, fragment, tmp_path, capsys):
    (tmp_path / "bad.toml").write_text("[task]\nname = 'x'\n")
    (tmp_path / "bad.pt").write_bytes(b"not a checkpoint")
    assert main([a.replace("{tmp}", str(tmp_path)) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("kgn-bench: error:") and fragment in err


def test_a_bare_value_error_is_a_bug_not_a_user_error(tmp_path, monkeypatch):
    """A ValueError from numerical code is not turned into a one-line user error: it goes through ``main``."""
    from kgn_bench.eval import pnp_noise

    def broken(*args, **kwargs):
        raise ValueError("planted bug in the PnP solver")

    monkeypatch.setattr(pnp_noise, "solve_box_pnp_batch", broken)
    with pytest.raises(ValueError, match="planted bug"):
        main(["study", "pnp-noise", "--samples", "5", "--sigmas", "1", "--out", str(tmp_path / "f")])


def test_a_bug_shows_its_traceback_and_a_nonzero_exit_from_the_console_script(tmp_path):
    out = str(tmp_path / "f")
    code = ("import sys\n"
            "from kgn_bench.eval import pnp_noise\n"
            "def broken(*a, **k):\n"
            "    raise ValueError('planted bug in the PnP solver')\n"
            "pnp_noise.solve_box_pnp_batch = broken\n"
            "from kgn_bench.cli import main\n"
            f"sys.exit(main(['study', 'pnp-noise', '--samples', '5', '--sigmas', '1', '--out', {out!r}]))\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, stdin=subprocess.DEVNULL)
    assert proc.returncode == 1
    assert "Traceback (most recent call last)" in proc.stderr and "in broken" in proc.stderr
    assert proc.stderr.rstrip().splitlines()[-1] == "ValueError: planted bug in the PnP solver"
    assert "kgn-bench: error" not in proc.stderr


def test_the_package_runs_as_a_module_and_help_loads_nothing_heavy():
    code = ("import sys, kgn_bench.cli; kgn_bench.cli.build_parser(); "
            "print(','.join(m for m in ('torch', 'mujoco', 'numpy', 'cv2', 'trimesh') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == ""
    proc = subprocess.run([sys.executable, "-m", "kgn_bench.cli", "eval", "trial", "--help"], capture_output=True,
                          text=True, check=True)
    assert "--attempt" in proc.stdout and proc.stdout.startswith("usage: kgn-bench eval trial")


def test_objects_show_says_how_many_grasps_each_rest_pose_can_execute(object_library, tmp_path, capsys):
    assert main(["objects", "show", "test_block", "--out", str(tmp_path / "block.png")]) == 0
    out = capsys.readouterr().out
    assert (tmp_path / "block.png").stat().st_size > 10_000
    assert "per rest pose" in out and "rest pose 0: probability" in out and " grasps" in out


def test_import_set_says_its_throughput(monkeypatch, tmp_path, capsys):
    """``objects import-set`` ends with how many objects it imported, in how long, per object (the import
    itself is stubbed here: 43 real imports take half an hour)."""
    import kgn_bench.objects.pybullet_set as pybullet_set

    monkeypatch.setenv("KGN_BENCH_OBJECTS", str(tmp_path / "lib"))
    monkeypatch.setattr(pybullet_set, "import_set", lambda split, workers, progress: {"pb_mug": "broken mesh"})
    assert main(["objects", "import-set", "--split", "test", "--workers", "1", "--quiet"]) == 0
    out, err = capsys.readouterr()
    assert "pybullet test: 42 of 43 objects in the library, 42 imported now in" in out
    assert "s an object, 1 worker(s)), 1 refused" in out and "pb_mug refused: broken mesh" in err
