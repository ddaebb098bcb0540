"""Packaged files: found through importlib.resources, tasks by their bundled names."""

from pathlib import Path

import pytest

from kgn_bench.config import ConfigError, load_task, resolve_task
from kgn_bench.resources import arm_xml, bundled_tasks, weights_dir

ROOT = Path(__file__).resolve().parents[1]


def test_packaged_files_are_the_repository_files():
    assert arm_xml().read_bytes() == (ROOT / "assets" / "arm7.xml").read_bytes()
    names = {p.name for p in weights_dir().glob("*.pt")}
    assert {"kgnv2.pt", "kgn.pt"} <= names
    assert all((weights_dir() / n).with_suffix(".md").is_file() for n in names)
    assert set(bundled_tasks()) == {p.stem for p in (ROOT / "tasks").glob("*.toml")}


def test_a_task_is_named_by_path_or_bundled_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # outside the repository
    assert resolve_task("single_object") == bundled_tasks()["single_object"]
    assert resolve_task("single_object.toml") == bundled_tasks()["single_object"]
    assert resolve_task("tasks/single_object.toml") == bundled_tasks()["single_object"]
    assert load_task("multi_household").name == "multi_household"
    mine = tmp_path / "single_object.toml"  # a file of one's own wins over the bundled name
    mine.write_text('[task]\nname = "mine"\nprotocol = "single_object"\n')
    assert load_task("single_object.toml").name == "mine"
    with pytest.raises(ConfigError, match=r"^nope: no such task file and no bundled task .*single_object"):
        resolve_task("nope")
    with pytest.raises(ConfigError, match="no such task file"):
        resolve_task("elsewhere/single_object.toml")  # a path that names a folder is a path, not a name
