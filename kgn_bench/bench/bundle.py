"""Results bundles: one versioned folder per detector that a lab can publish, and that ``kgn-bench report``
reads like run folders (``kgn-bench export RUN… --out DIR``).

A bundle ``DIR/<detector>/`` holds:

* ``bundle.json``: ``format`` ``kgn-bench-results``, ``version``, the detector, and per task the run's
  summary, the SHA-256 of its task config (canonical JSON), the SHA-256 of its records (``fingerprint``),
  the commit and the environment it ran in;
* ``tasks/<task>.json``: the task config as it ran (``run.json``'s ``config``), so a reader can rerun it;
* ``attempts/<task>.csv``: one row per attempt, like VGN's ``grasps.csv``: trial and attempt index, the
  object aimed at, the executed grasp (world frame: position ``x y z`` in m, unit quaternion ``qw qx qy qz``),
  the jaw opening ``width`` (m), the selector's ``score``, ``success`` (0/1), the failure ``reason`` and the
  number of ``candidates``; pose and width are empty where nothing was executed;
* ``card.md``: the detector's card: a learned detector's model card (data, recipe, wall time, weights
  SHA-256), otherwise a short card of the built-in or user detector.

A bundle names its source runs nowhere: it stands alone. Reading one checks the format and version.
"""

from __future__ import annotations

import csv
import io
import json
import re
import shutil
import tempfile
from pathlib import Path
from typing import Any

from kgn_bench.errors import KGNBenchError
from kgn_bench.io import atomic_write_text

from .check import read_run
from .fingerprint import canonical_sha256
from .records import TrialRecord

__all__ = ["ATTEMPT_COLUMNS", "FORMAT", "VERSION", "BundleError", "export_bundles", "is_bundle", "read_bundle"]

FORMAT = "kgn-bench-results"
VERSION = 1

ATTEMPT_COLUMNS = ("trial", "attempt", "object", "x", "y", "z", "qw", "qx", "qy", "qz", "width", "score", "success",
                   "reason", "candidates")
"""Columns of ``attempts/<task>.csv``."""


class BundleError(KGNBenchError, ValueError):
    """Runs that cannot be bundled (unfinished, two of one task for a detector) or a folder that is not a
    readable bundle."""


def _safe(name: str) -> str:
    """A file name for a detector or task name (``module:attribute`` → ``module_attribute``)."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name).strip(".") or "_"


def _attempt_rows(records: list[TrialRecord]) -> str:
    """``ATTEMPT_COLUMNS`` of every attempt, trials in index order; the pose and width are empty where nothing
    was executed or the record is older than them."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(ATTEMPT_COLUMNS)
    for record in sorted(records, key=lambda r: r.index):
        for k, a in enumerate(record.attempts):
            pose = a.grasp or [""] * 7
            writer.writerow([record.index, k, a.object or "", *pose, "" if a.width is None else a.width,
                             "" if a.score is None else a.score, int(bool(a.success)), a.reason or "",
                             a.candidates])
    return buf.getvalue()


def _card(detector: str) -> str:
    """The detector's card: the shipped model card of a learned detector, else a generated one."""
    from kgn_bench.detectors import DETECTORS, shipped_weights

    weights = shipped_weights(detector) if detector in DETECTORS else None
    if weights is not None and weights.with_suffix(".md").is_file():
        return weights.with_suffix(".md").read_text()
    if detector in DETECTORS:
        doc = (DETECTORS[detector].__doc__ or "").strip().split("\n\n")[0]
        return f"# {detector}\n\nBuilt-in detector of kgn-bench.\n\n{doc}\n"
    return (f"# {detector}\n\nA user's detector (`module:attribute`); its code and weights are not part of this "
            "bundle. Describe them here before publishing.\n")


def export_bundles(runs: list[Path], out: Path, overwrite: bool = False) -> list[Path]:
    """Write one bundle per detector of ``runs`` (finished run folders) under ``out``; returns their folders.
    Each bundle is written to a temporary folder beside it and moved into place, so a reader never sees a
    half-written one; an existing bundle is replaced only with ``overwrite``."""
    loaded = [(Path(r), read_run(r)) for r in runs]
    by_detector: dict[str, list[tuple[Path, Any]]] = {}
    for folder, run in loaded:
        by_detector.setdefault(run.summary["detector"], []).append((folder, run))
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for detector, items in sorted(by_detector.items()):
        tasks = [run.summary["task"] for _, run in items]
        dup = sorted({t for t in tasks if tasks.count(t) > 1})
        if dup:
            raise BundleError(f"two runs of {dup[0]} with {detector}: a bundle holds one run per task")
        target = out / _safe(detector)
        if target.exists() and not overwrite:
            raise BundleError(f"{target} exists; use --overwrite to replace it")
        tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}-", dir=out))
        tmp.chmod(0o755)  # mkdtemp's 0700 would keep a published bundle from its readers
        try:
            _write_bundle(tmp, detector, items)
            if target.exists():
                shutil.rmtree(target)
            tmp.rename(target)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp)
        written.append(target)
    return written


def _write_bundle(folder: Path, detector: str, items: list[tuple[Path, Any]]) -> None:
    (folder / "tasks").mkdir()
    (folder / "attempts").mkdir()
    entries = []
    for _, run in sorted(items, key=lambda item: item[1].summary["task"]):
        task = run.summary["task"]
        config = run.run.get("config", {})
        records = run.records
        atomic_write_text(folder / "tasks" / f"{_safe(task)}.json", json.dumps(config, indent=2) + "\n")
        atomic_write_text(folder / "attempts" / f"{_safe(task)}.csv", _attempt_rows(records))
        entries.append({
            "task": task, "protocol": run.summary.get("protocol"), "config": f"tasks/{_safe(task)}.json",
            "config_sha256": canonical_sha256(config), "attempts": f"attempts/{_safe(task)}.csv",
            "records_sha256": canonical_sha256([t.sha256 for t in run.fingerprint.trials]),
            "commit": run.run.get("commit"), "environment": run.run.get("environment"), "summary": run.summary})
    atomic_write_text(folder / "card.md", _card(detector))
    document = {"format": FORMAT, "version": VERSION, "detector": detector, "card": "card.md", "runs": entries}
    atomic_write_text(folder / "bundle.json", json.dumps(document, indent=1) + "\n")


def is_bundle(path: Path) -> bool:
    """Whether ``path`` is a bundle folder (it holds ``bundle.json``)."""
    return (Path(path) / "bundle.json").is_file()


def read_bundle(path: Path) -> list[dict[str, Any]]:
    """The run summaries of a bundle, each with ``run`` (``<bundle>:<task>``) and ``environment`` set as
    ``report.load_summaries`` sets them for a run folder; ``BundleError`` for a foreign or damaged bundle."""
    path = Path(path)
    try:
        document = json.loads((path / "bundle.json").read_text())
    except (OSError, json.JSONDecodeError) as e:
        raise BundleError(f"{path / 'bundle.json'}: not readable ({e})") from None
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise BundleError(f"{path / 'bundle.json'}: not a kgn-bench results bundle")
    if document.get("version") != VERSION:
        raise BundleError(f"{path / 'bundle.json'}: bundle version {document.get('version')!r}, this kgn-bench "
                          f"reads version {VERSION}")
    out = []
    for entry in document.get("runs", []):
        summary = entry.get("summary")
        if not isinstance(summary, dict) or not {"task", "detector", "rates", "failures"} <= set(summary):
            raise BundleError(f"{path / 'bundle.json'}: a run entry without a summary")
        out.append({**summary, "run": f"{path}:{summary['task']}", "environment": entry.get("environment")})
    return out
