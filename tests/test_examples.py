"""The README's own-detector example (examples/top_down.py) plugs into the harness by module:attribute."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from kgn_bench.cli import main

ROOT = Path(__file__).resolve().parents[1]


def test_top_down_example_runs_as_module_attribute(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(ROOT / "examples"))
    out = tmp_path / "run"
    rc = main(["run", str(ROOT / "tasks" / "ci_oracle.toml"), "--detector", "top_down:TopDown", "--trials", "1",
               "--workers", "1", "--quiet", "--out", str(out)])
    assert rc == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["detector"] == "top_down:TopDown" and summary["attempts"] == 6
    assert summary["failures"]["detector_error"] == 0
    assert summary["rates"]["success"]["k"] >= 3  # a real, if naive, grasping policy
    sys.modules.pop("top_down", None)


def test_readme_shows_the_example_verbatim():
    code = (ROOT / "examples" / "top_down.py").read_text()
    body = code[code.index("import numpy"):]
    assert body.strip() in (ROOT / "README.md").read_text()


def test_own_mesh_example_imports_and_runs(tmp_path, monkeypatch):
    """examples/my_object.toml as its comment says: dm_control's dog humerus imported with `objects add`,
    then a single-object trial on it (oracle, 1 trial; FAST-like import settings)."""
    import dm_control

    monkeypatch.setenv("KGN_BENCH_OBJECTS", str(tmp_path / "lib"))
    stl = Path(dm_control.__file__).parent / "suite" / "dog_assets" / "BONEhumerus_L.stl"
    assert main(["objects", "add", str(stl), "--name", "dog_humerus", "--hulls", "4", "--verify", "24",
                 "--licence", "Apache-2.0"]) == 0
    out = tmp_path / "run"
    assert main(["run", str(ROOT / "examples" / "my_object.toml"), "--detector", "oracle", "--trials", "1",
                 "--workers", "1", "--quiet", "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"] == 1 and summary["failures"]["physics_error"] == 0
