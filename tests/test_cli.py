"""The command line: one-line errors with exit code 2, and the show command on a real dataset."""

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


def test_study_pnp_noise_writes_the_csv_and_the_figure(tmp_path, capsys):
    import cv2

    assert main(["study", "pnp-noise", "--samples", "50", "--sigmas", "1", "--out", str(tmp_path / "fig2")]) == 0
    lines = (tmp_path / "fig2.csv").read_text().splitlines()
    assert len(lines) == 1 + 2 * 13  # header + 2 boxes × 13 distances
    img = cv2.imread(str(tmp_path / "fig2.png"))
    assert img is not None and img.shape[1] > 1000
    assert "scale_normalized" in capsys.readouterr().out


def test_show_writes_a_png(tiny_dataset, tmp_path, capsys):
    root, _ = tiny_dataset
    out = tmp_path / "view.png"
    assert main(["data", "show", str(root), "--scene", "0", "--view", "1", "--out", str(out)]) == 0
    import cv2

    img = cv2.imread(str(out))
    assert img.shape == (480, 1280, 3)
    assert main(["data", "show", str(root), "--scene", "0", "--view", "9", "--out", str(out)]) == 2
    assert "views 0..1" in capsys.readouterr().err


def test_generate_refusal_exits_2_from_the_console_script(tmp_path):
    (tmp_path / "junk.txt").write_text("x")
    proc = subprocess.run(
        [sys.executable, "-m", "kgn_bench.cli", "data", "generate", "--mode", "single", "--scenes", "1",
         "--out", str(tmp_path)],
        capture_output=True, text=True, stdin=subprocess.DEVNULL,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "not empty" in proc.stderr


HISTORY = [{"epoch": 1, "total": 3.5, "hm": 1.0, "seconds": 60.0,
            "eval": {"1 cm / 20°": {"gsr": 0.25, "gcr": None, "osr": 0.5}}, "eval_views": 2}]


def test_export_eval_and_show_commands(tiny_dataset, tmp_path, capsys, small_model):
    import json

    from kgn_bench.model.checkpoint import load_checkpoint

    root, _ = tiny_dataset
    small_model(tmp_path / "final.pt", optimizer={"state": {}}, epoch=1, history=HISTORY, git_commit="abc1234",
                train={"name": "train_x", "train": {"batch_size": 8}})
    assert main(["ship", str(tmp_path / "final.pt"), "--name", "mine", "--out", str(tmp_path / "w")]) == 0
    shipped = load_checkpoint(tmp_path / "w" / "mine.pt")
    assert "optimizer" not in shipped and shipped["epoch"] == 1
    card = (tmp_path / "w" / "mine.md").read_text()
    assert "| variant | `kgnv2`, scale head: absolute distance |" in card and "abc1234" in card
    assert "GSR 25.0 % GCR n/a OSR 50.0 %" in card

    weights = str(tmp_path / "w" / "mine.pt")
    assert main(["eval", "vision", "--weights", weights, "--data", str(root), "--views", "2",
                 "--out", str(tmp_path / "ev"), "--quiet"]) == 0
    summary = json.loads((tmp_path / "ev" / "vision.json").read_text())
    assert summary["images"] == 2 and summary["variant"] == "kgnv2" and len(summary["thresholds"]) == 3
    assert (tmp_path / "ev" / "vision.md").read_text().startswith("Vision metrics over 2 images")

    assert main(["eval", "show", "--weights", weights, "--data", str(root), "--scene", "0",
                 "--out", str(tmp_path / "pred.png")]) == 0
    import cv2

    img = cv2.imread(str(tmp_path / "pred.png"))
    assert img.shape == (480, 1280, 3)

    # the wrong decoding variant for these weights: one line, exit 2
    capsys.readouterr()
    assert main(["eval", "vision", "--weights", weights, "--variant", "kgn", "--data", str(root)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds 'kgnv2' weights" in err


TINY = '[task]\nname = "tiny"\nprotocol = "single_object"\ntrials = 1\n[objects]\nset = ["cuboid"]\n'


def _unwritable_cases(tmp_path, tiny_dataset):
    """(argv, the path named in the error) for each command given an output it cannot write."""
    task = tmp_path / "tiny.toml"
    task.write_text(TINY)
    afile = tmp_path / "a_file"
    afile.write_text("keep")
    rrd = tmp_path / "r.rrd"
    rrd.write_bytes(b"x")
    run = tmp_path / "done"
    assert main(["run", str(task), "--detector", "oracle", "--out", str(run), "--quiet"]) == 0
    root, _ = tiny_dataset
    ro = "/sys/kgn_bench_out"  # sysfs: not writable, even by root
    return [
        (["run", str(task), "--detector", "oracle", "--out", str(afile), "--quiet"], str(afile)),
        (["run", str(task), "--detector", "oracle", "--out", ro, "--quiet"], ro),
        (["data", "generate", "--mode", "single", "--scenes", "1", "--out", ro, "--quiet"], ro),
        (["eval", "vision", "--weights", "kgnv2", "--data", str(root), "--views", "1", "--out", ro, "--quiet"], ro),
        (["report", str(run), "--out", str(afile)], str(afile)),
        (["benchmark", "--detectors", "oracle", "--tasks", "single_object", "--runs", ro, "--quiet"], ro),
        (["replay", str(rrd), "--save", f"{ro}/copy.rrd"], ro),
        (["check", str(run), "--baseline", f"{ro}/b.json", "--update-baseline"], ro),
        (["experiment", "table1", "--out", str(afile)], str(afile)),
    ]


def test_an_unwritable_output_is_one_line_before_any_work(tmp_path, tiny_dataset, capsys):
    for argv, named in _unwritable_cases(tmp_path, tiny_dataset):
        capsys.readouterr()
        before = sorted(p.name for p in tmp_path.iterdir())
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("kgn-bench: error: ") and err.count("\n") == 1 and named in err, (argv, err)
        assert "is a file" in err or "not writable" in err, err
        assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written
    assert (tmp_path / "a_file").read_text() == "keep"


def test_too_many_workers_is_a_warning(tmp_path, capsys):
    from kgn_bench.threads import available_cores

    task = tmp_path / "tiny.toml"
    task.write_text(TINY)
    assert main(["run", str(task), "--detector", "oracle", "--workers", "99", "--out", str(tmp_path / "r"),
                 "--quiet"]) == 0
    err = capsys.readouterr().err
    assert err == (f"kgn-bench: warning: --workers 99 is more than the {available_cores()} core(s) of this machine; "
                   f"trials will queue and run slower than with --workers {available_cores()}\n")


def test_eval_vision_decodes_with_the_weights_own_variant(tiny_dataset, tmp_path, capsys):
    import json

    root, _ = tiny_dataset
    assert main(["eval", "vision", "--weights", "kgn", "--data", str(root), "--views", "1", "--out",
                 str(tmp_path / "e"), "--quiet"]) == 0
    assert json.loads((tmp_path / "e" / "vision.json").read_text())["variant"] == "kgn"
    assert main(["eval", "vision", "--weights", "kgn", "--variant", "kgn_depth", "--data", str(root), "--views",
                 "1", "--quiet"]) == 0  # kgn weights serve kgn_depth
    capsys.readouterr()
    assert main(["eval", "vision", "--weights", "kgn", "--variant", "kgnv2", "--data", str(root), "--quiet"]) == 2
    assert "holds 'kgn' weights, but 'kgnv2' needs 'kgnv2' weights" in capsys.readouterr().err


def test_trials_help_says_what_it_counts(capsys):
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "per object for single_object tasks" in text and "scenes for multi_object tasks" in text


def test_a_bundled_task_runs_by_name_from_anywhere(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["run", "ci_oracle", "--detector", "oracle", "--trials", "1", "--out", "r", "--quiet"]) == 0
    assert "# ci_oracle: oracle" in capsys.readouterr().out


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
