"""The command line: one-line errors with exit code 2, and the show command on a real dataset."""

import subprocess
import sys

import pytest

from kgn_bench.cli import main


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["data", "generate", "--mode", "multi", "--scenes", "0", "--out", "x"], "--scenes: must be ≥ 1"),
        (["data", "generate", "--mode", "triple", "--out", "x"], "invalid choice"),
        (["data", "generate", "--mode", "multi", "--seed", "abc", "--out", "x"], "expected an integer"),
        (["data", "generate", "--mode", "multi"], "--out"),
        (["data", "show", "/nonexistent", "--scene", "0", "--out", "a.png"], "no dataset.json"),
        (["bogus"], "invalid choice"),
    ],
)
def test_bad_arguments_give_one_line_and_exit_2(argv, fragment, capsys, tmp_path):
    if argv[:2] == ["data", "show"]:
        argv = [a if a != "/nonexistent" else str(tmp_path / "missing") for a in argv]
        fragment = "scene.json"
    with pytest.raises(SystemExit) as e:
        rc = main(argv)
        raise SystemExit(rc)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("kgn-bench: error:") and fragment in err


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
