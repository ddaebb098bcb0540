"""The files that ship with the package: the arm's MJCF, the trained weights with their model cards, and
the task files, found with ``importlib.resources`` so that a wheel install works like a source checkout.

In the repository they live at the top level (``assets/``, ``tasks/``); ``pyproject.toml`` maps them into
the package as ``kgn_bench.assets`` and ``kgn_bench.tasks`` (``config.resolve_task`` finds a task by name).
"""

from __future__ import annotations

from importlib.resources import as_file, files
from pathlib import Path

__all__ = ["arm_xml", "bundled_tasks", "weights_dir"]


def _package_dir(package: str) -> Path:
    """The folder of a data package on the file system (wheels and checkouts are both plain folders)."""
    with as_file(files(package)) as path:
        return Path(path)


def arm_xml() -> Path:
    """The 7-DoF arm with its parallel-jaw gripper (MJCF)."""
    return _package_dir("kgn_bench.assets") / "arm7.xml"


def weights_dir() -> Path:
    """The shipped weights (``<name>.pt``) and their model cards (``<name>.md``)."""
    return _package_dir("kgn_bench.assets") / "weights"


def bundled_tasks() -> dict[str, Path]:
    """Every bundled task and plan file by name (the file name without ``.toml``)."""
    folder = _package_dir("kgn_bench.tasks")
    return {p.stem: p for p in sorted(folder.glob("*.toml"))}

