"""pyproject.toml's explicit package list names every package folder, so a wheel carries all the code."""

from pathlib import Path

import tomllib

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_folder_is_listed():
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    folders = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "kgn_bench").rglob("*.py")}
    missing = sorted(folders - listed)
    assert not missing, f"pyproject.toml [tool.setuptools] packages lacks {missing}"
