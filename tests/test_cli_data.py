"""kgn-bench data (kgn_bench.cli.data): show on a real dataset, generate's refusal from the console script."""

import subprocess
import sys

from kgn_bench.cli import main


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
