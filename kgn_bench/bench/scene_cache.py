"""Settled trial scenes kept on disk, so that the detectors of one task share its set-up.

Setting a trial's scene up (dropping a pile, settling a packed round, spreading and settling single objects)
is the same physics for every detector: it depends on the task, the trial index and the code, never on the
detector. In GIGA's pile rounds it is about half of a trial's time. The first run of a trial saves the settled
scene's state (``sim.scene.SceneState``: MuJoCo's integration state and the retired objects) with the indices
of the round's objects; every later run of the same trial compiles the scene from the same objects and
restores that state instead of simulating the set-up again. What follows is the same, bit for bit
(``tests/test_scene_cache.py`` compares whole runs with and without the cache).

**Key.** A file is ``<root>/<key>/<index>.npz``; ``key`` is the SHA-256 of everything the set-up depends on:
the task's settings (all but where its trials run), the content of every imported object it names, the
project's source code (every ``kgn_bench`` module and the arm's MJCF, so any change of them makes new keys),
and the versions of MuJoCo, NumPy and SciPy and the machine's architecture. A stale file can therefore not be
found; a damaged or unreadable one is a miss and is written again.

**Where.** ``$KGN_BENCH_SCENE_CACHE`` if set (``0`` or ``off`` switch the cache off), else
``~/.cache/kgn-bench/scenes``. Files are a few kilobytes; written atomically (a temporary file renamed), so
workers that run the same trial at once are harmless. Loading never unpickles.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import tempfile
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import mujoco
import numpy as np
import scipy

from kgn_bench.config import TaskConfig
from kgn_bench.resources import arm_xml
from kgn_bench.shapes.library import object_sha256
from kgn_bench.sim.scene import SceneState

__all__ = ["ENV_VAR", "CachedScene", "cache_root", "load_scene", "save_scene", "scene_key"]

ENV_VAR = "KGN_BENCH_SCENE_CACHE"


@dataclass(frozen=True)
class CachedScene:
    """A settled trial scene: its state and the indices of the round's objects (``bench.trial.ARRANGEMENTS``)."""

    state: SceneState
    members: tuple[int, ...]


def cache_root() -> Path | None:
    """The cache's folder, or None when ``$KGN_BENCH_SCENE_CACHE`` switches it off."""
    env = os.environ.get(ENV_VAR)
    if env is not None and env.strip().lower() in ("0", "off", "false", "no"):
        return None
    return Path(env).expanduser() if env else Path.home() / ".cache" / "kgn-bench" / "scenes"


@lru_cache(maxsize=1)
def _code_sha256() -> str:
    """Every ``kgn_bench`` module and the arm's MJCF (``resources.arm_xml``), the scene's inputs that are files."""
    package = Path(__file__).resolve().parents[1]
    h = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        h.update(path.relative_to(package).as_posix().encode() + b"\0")
        h.update(hashlib.sha256(path.read_bytes()).digest())
    h.update(b"arm_xml\0" + hashlib.sha256(arm_xml().read_bytes()).digest())
    return h.hexdigest()


def scene_key(task: TaskConfig) -> str:
    """The SHA-256 naming ``task``'s settled scenes (module doc)."""
    config = task.to_dict()
    del config["resources"]
    content = {
        "task": config,
        "objects": {name: object_sha256(name) for name in dict.fromkeys(task.objects)},
        "code": _code_sha256(),
        "versions": [mujoco.__version__, np.__version__, scipy.__version__, platform.machine()],
    }
    return hashlib.sha256(json.dumps(content, sort_keys=True, default=str).encode()).hexdigest()


def _path(task: TaskConfig, index: int) -> Path | None:
    root = cache_root()
    return None if root is None else root / scene_key(task)[:32] / f"{index}.npz"


def load_scene(task: TaskConfig, index: int) -> CachedScene | None:
    """Trial ``index`` of ``task`` as a run saved it, or None (not saved, cache off, or a damaged file)."""
    path = _path(task, index)
    if path is None or not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as f:
            state = np.array(f["state"], dtype=float)
            retired = tuple(int(i) for i in f["retired"])
            members = tuple(int(i) for i in f["members"])
    except (OSError, ValueError, KeyError):
        return None
    return CachedScene(SceneState(state, retired), members)


def save_scene(task: TaskConfig, index: int, scene: CachedScene) -> None:
    """Keep trial ``index`` of ``task`` (atomically; a cache that cannot be written is skipped quietly)."""
    path = _path(task, index)
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{index}.", suffix=".npz", dir=path.parent)
    except OSError:
        return
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, state=scene.state.state, retired=np.array(scene.state.retired, dtype=np.int64),
                     members=np.array(scene.members, dtype=np.int64))
        os.replace(tmp, path)
    except OSError:
        Path(tmp).unlink(missing_ok=True)
