"""The benchmark runner: trials in worker processes, one JSON line per finished trial, resumable.

A run folder holds ``run.json`` (the run's identity: task config, detector, seed, trial count; and the git
commit and package versions of the invocation that created it),
``trials.jsonl`` (append-only, one finished trial per line, in completion order), then ``summary.json``,
``summary.md`` and ``timing.json``, and with ``record`` the per-trial recordings merged into
``recording.rrd``. Rerunning the same command resumes: finished trials are kept, a line cut short by a
kill is dropped, and only missing trials run. Trial outcomes depend only on (task, seed, index), so the
summary is the same whatever the worker count or interruptions (every trial runs with the thread settings
of ``kgn_bench.threads``); ``timing.json`` holds the wall-clock figures of the last invocation that ran trials.

Before anything is written, the detector is built once in the calling process, so that an unknown name, a
constructor that raises or weights that do not load stop the run with one line. While a run writes to a
folder it holds an exclusive lock on ``.lock`` there; a second run into the same folder is refused.

``run_many`` runs several runs (a benchmark plan, a sweep) as one stream of jobs, on one local pool or on Ray:
the same files, without the idle workers at each run's end and the workers' start per run.

With ``backend`` ray (``pool.Backend``) the trials run as Ray tasks, on a cluster or a local Ray; the cluster is
joined and one of its workers builds the detector before anything is written, and the records come back to
this process, which writes the same files: a run may start on one backend and resume on the other.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import stat
import subprocess
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from kgn_bench.config import TaskConfig
from kgn_bench.environment import environment
from kgn_bench.errors import KGNBenchError, OutputError, warn
from kgn_bench.io import atomic_write_text, describe_os_error
from kgn_bench.objects.pybullet_set import ensure_objects
from kgn_bench.pool import LOCAL, Backend, run_jobs
from kgn_bench.progress import Progress
from kgn_bench.protocols import protocol
from kgn_bench.shapes.library import find_object, shadowed
from kgn_bench.shapes.mesh_object import check_object
from kgn_bench.threads import pin_worker_threads, trial_threads

from .records import RecordError, TrialRecord
from .stats import Rate, summarise, summary_markdown
from .trial import TIMING_KEYS, check_cameras, run_trial

__all__ = ["RunError", "RunResult", "read_trials", "run_benchmark", "run_many"]


class RunError(KGNBenchError, RuntimeError):
    """A run folder that cannot be used (it holds another run, or a corrupt file)."""


@dataclass
class RunResult:
    summary: dict[str, Any]
    timing: dict[str, Any]
    ran: int


def _git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], capture_output=True, text=True, timeout=5,
                             cwd=Path(__file__).resolve().parent)
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def _weights_identity(detector: str) -> str | None:
    """SHA-256 of a learned detector's weights file, None for other detectors (``run_benchmark`` has built the
    detector, and so loaded and verified the file, before it asks)."""
    from kgn_bench.detectors import shipped_weights

    path = shipped_weights(detector)
    if path is None:
        return None
    from kgn_bench.model.checkpoint import file_sha256

    return file_sha256(path)


CONTENT_KEYS = ("weights_sha256", "objects_sha256", "detector_fingerprint")
"""Identity entries about content rather than settings; a run folder written before one of them was recorded
resumes without it."""


def _detector_fingerprint(instance: Any) -> str | None:
    """A user detector's declared ``fingerprint`` (e.g. the SHA-256 of its weights), as a string; None when it
    declares none."""
    value = getattr(instance, "fingerprint", None)
    if callable(value):
        value = value()
    return None if value is None else str(value)


IDENTITY_DEFAULTS: dict[tuple[str, str], Any] = {("camera", "noise_model"): "d435",
                                                  ("camera", "intrinsics"): "realsense",
                                                  ("camera", "far"): 0.0,
                                                  ("execution", "hand"): "arm",
                                                  ("execution", "gripper"): "default"}
"""Task settings added after runs were recorded, left out of a run's identity while they hold the value every
earlier run had: runs recorded before the setting existed keep their identity (they resume, and the regression
check still compares them record by record with their baselines)."""


def run_identity(task: TaskConfig, detector: str, instance: Any = None) -> dict[str, Any]:
    """What makes two runs the same run (and so resumable into one folder): task, seed, config and content:
    for a learned detector the hash of its weights, for each imported object the hash of its files
    (``shapes.library.object_sha256``), and for a ``module:attribute`` detector ``instance``'s declared
    ``fingerprint`` (null when it declares none, so the record shows that nothing vouches for its weights)."""
    from kgn_bench.detectors import DETECTORS
    from kgn_bench.shapes.library import object_sha256

    config = task.to_dict()
    del config["resources"]  # where the trials run does not change them (config.ResourceConfig)
    for (section, key), default in IDENTITY_DEFAULTS.items():
        if config[section][key] == default:
            del config[section][key]
    if not task.clearance:  # one attempt a trial: nothing is left to remove (config.ExecutionConfig)
        del config["execution"]["remove_placed"]
    identity = {"task": task.name, "protocol": task.protocol, "detector": detector, "seed": task.seed,
                "trials": task.n_trials, "config": config}
    weights = _weights_identity(detector)
    if weights is not None:
        identity["weights_sha256"] = weights
    objects = {name: sha for name in dict.fromkeys(task.objects) if (sha := object_sha256(name)) is not None}
    if objects:
        identity["objects_sha256"] = objects
    if detector not in DETECTORS:
        identity["detector_fingerprint"] = _detector_fingerprint(instance)
    return identity


def _identity_change(existing: dict[str, Any], identity: dict[str, Any]) -> str | None:
    """What differs between a run folder's stored identity and this run's, in words (None if nothing). A
    content entry the folder did not record (written by an older version) is not compared."""
    mine = {k: v for k, v in existing.items() if k not in ("commit", "environment")}
    theirs = {k: v for k, v in identity.items() if k in mine or k not in CONTENT_KEYS}
    if mine == theirs:
        return None
    old, new = mine.get("objects_sha256") or {}, theirs.get("objects_sha256") or {}
    changed = sorted(n for n in old.keys() & new.keys() if old[n] != new[n])
    if changed:
        return f"object {', '.join(changed)} changed since the run started (its files differ)"
    if mine.get("weights_sha256") != theirs.get("weights_sha256"):
        return f"the weights of {identity['detector']} changed since the run started"
    if mine.get("detector_fingerprint") != theirs.get("detector_fingerprint"):
        return (f"the fingerprint of detector {identity['detector']} changed since the run started "
                f"({mine.get('detector_fingerprint')!r} → {theirs.get('detector_fingerprint')!r})")
    diff = [k for k in theirs if mine.get(k) != theirs[k]] + [k for k in mine if k not in theirs]
    return f"different {', '.join(dict.fromkeys(diff))}"


def read_trials(path: Path, repair: bool = True) -> list[TrialRecord]:
    """Finished trial records of ``trials.jsonl`` (of any record shape, ``records.TrialRecord.from_json``); a
    cut-short last line (from a kill) is skipped, and with ``repair`` (only for the run's writer, which holds
    its lock) removed from the file. ``RunError`` for a line that is not a record."""
    if not path.is_file():
        return []
    text = path.read_text()
    lines = text.splitlines(keepends=True)
    records, good = [], []
    for n, line in enumerate(lines):
        try:
            if not line.endswith("\n"):
                raise json.JSONDecodeError("unterminated", line, 0)
            records.append(json.loads(line))
            good.append(line)
        except json.JSONDecodeError:
            if n != len(lines) - 1:
                raise RunError(f"{path}: line {n + 1} is not valid JSON") from None
    if repair and len(good) != len(lines):
        atomic_write_text(path, "".join(good))
    seen: set[int] = set()
    unique = []
    for n, r in enumerate(records):
        try:
            record = TrialRecord.from_json(r)
        except RecordError as e:
            raise RunError(f"{path}: line {n + 1} is not a trial record ({e})") from None
        if record.index not in seen:
            seen.add(record.index)
            unique.append(record)
    return unique


def _prepare(out: Path, identity: dict[str, Any]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    run_file = out / "run.json"
    if run_file.is_file():
        try:
            existing = json.loads(run_file.read_text())
        except json.JSONDecodeError:
            raise RunError(f"{run_file} is corrupt; remove the folder or use another --out") from None
        change = _identity_change(existing, identity)
        if change is not None:
            raise RunError(f"{out} holds another run ({change}); use another --out")
    elif any(p.name != ".lock" for p in out.iterdir()):
        raise RunError(f"{out} is not empty and holds no run; use another --out")
    else:
        record = {**identity, "commit": _git_commit(), "environment": environment()}
        atomic_write_text(run_file, json.dumps(record, indent=2) + "\n")


@contextmanager
def run_lock(out: Path) -> Iterator[None]:
    """Hold the exclusive lock of the run folder ``out`` (``out/.lock``) for the block; ``RunError`` at once
    if another process holds it. The lock goes with the process, so a killed run leaves none behind. The file
    is opened without following a symbolic link (``RunError`` for one), so a planted link truncates nothing."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / ".lock"
    try:  # never through a symbolic link: a planted one would make the run truncate its target
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise RunError(f"{path} is a symbolic link; remove it (a run folder's lock must be a plain file)") from None
        raise
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise RunError(f"{path} is not a plain file; remove it")
    with open(fd, "a+") as f:
        try:
            fcntl.flock(f.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            holder = f.read().strip() or "another process"
            raise RunError(f"{out} is being written by another run ({holder}); wait for it or use another --out"
                           ) from None
        f.seek(0)
        f.truncate()
        f.write(f"pid {os.getpid()}\n")
        f.flush()
        try:
            yield
        finally:
            f.seek(0)
            f.truncate()
            fcntl.flock(f.fileno(), fcntl.LOCK_UN)


def build_detector(name: str):
    """The detector ``name`` built in this process; ``RunError`` with one line if it cannot be built (an
    unknown name, a constructor that raises, weights that are missing, corrupt or do not match their card)."""
    from kgn_bench.detectors import make_detector

    try:
        return make_detector(name)
    except KGNBenchError:
        raise
    except ValueError as e:
        raise RunError(str(e)) from None
    except Exception as e:  # a user's detector may raise anything
        first = str(e).strip().splitlines()[0] if str(e).strip() else ""
        raise RunError(f"detector {name!r} could not be built: {type(e).__name__}" + (f": {first}" if first else "")
                       ) from None


_WORKER: dict[str, Any] = {}


def _worker_init(detector: str) -> None:
    _worker_setup(detector)
    pin_worker_threads()


def _worker_setup(detector: str, instance: Any = None) -> None:
    """Make ``detector`` (built here once, or ``instance``) the one this process's trials use; a process
    keeps every detector it built, and one IK."""
    from kgn_bench.sim.control import IK

    built = _WORKER.setdefault("built", {})
    if instance is not None:
        built[detector] = instance
    elif detector not in built:
        built[detector] = build_detector(detector)
    if "ik" not in _WORKER:
        _WORKER["ik"] = IK()
    _WORKER.update(name=detector, detector=built[detector])


def _run_one(args: tuple[TaskConfig, int, str | None]) -> TrialRecord:
    task, index, record = args
    try:
        return run_trial(task, index, _WORKER["detector"], _WORKER["ik"], Path(record) if record else None)
    except KGNBenchError:
        raise
    except Exception as e:  # a defect, not a trial outcome: stop the run, naming the trial
        first = str(e).strip().splitlines()[0] if str(e).strip() else ""
        raise RunError(f"trial {index} of {task.name} failed: {type(e).__name__}" + (f": {first}" if first else "")
                       ) from e


def _running_rates(records: list[TrialRecord]) -> str:
    attempts = [a for r in records for a in r.attempts]
    text = f"success {Rate(sum(a.success for a in attempts), len(attempts)).value * 100:.0f}%"
    if records and protocol(records[0].protocol).clearance:
        clear = Rate(sum(r.removed for r in records), sum(r.placed for r in records))
        text += f" clear {clear.value * 100:.0f}%"
    return text


class _RunWriter:
    """The driver's side of one run folder while its trials come in: appends each record to ``trials.jsonl``
    (fsync'd, so a kill loses at most the line being written), shows the progress, and writes the summaries
    once the run is complete."""

    def __init__(self, task: TaskConfig, detector: str, out: Path, identity: dict[str, Any], record: bool,
                 progress: bool) -> None:
        self.task, self.detector, self.out, self.identity, self.record = task, detector, out, identity, record
        self.trials_path = out / "trials.jsonl"
        self.records = read_trials(self.trials_path)
        done = {r.index for r in self.records}
        self.todo = [i for i in range(task.n_trials) if i not in done]
        self.rec_dir = out / "recordings"
        if record:
            self.rec_dir.mkdir(exist_ok=True)
            for stale in self.rec_dir.glob("*.tmp"):
                stale.unlink()
        self.progress = progress
        self.bar: Progress | None = None

    def jobs(self) -> list[tuple[TaskConfig, int, str | None]]:
        return [(self.task, i, str(self.rec_dir / f"trial_{i:05d}.rrd.tmp") if self.record else None)
                for i in self.todo]

    @property
    def what(self) -> str:
        return f"{self.task.name} with {self.detector} ({len(self.records)} of {self.task.n_trials} trials done)"

    def add(self, rec: TrialRecord) -> None:
        """One finished trial: its line in ``trials.jsonl`` (and its recording moved into place)."""
        if self.record:
            tmp = self.rec_dir / f"trial_{rec.index:05d}.rrd.tmp"
            if tmp.is_file():
                os.replace(tmp, self.rec_dir / f"trial_{rec.index:05d}.rrd")
        line = json.dumps(rec.to_json(), sort_keys=True) + "\n"
        try:
            with open(self.trials_path, "a") as f:
                f.write(line)
                f.flush()
                os.fsync(f.fileno())
        except OSError as e:  # a cut-short line is dropped on the next resume
            raise OutputError(describe_os_error(e, self.trials_path)) from None
        self.records.append(rec)
        if self.bar is None:
            self.bar = Progress(len(self.todo), f"run {self.task.name} {self.detector}", unit="trials",
                                enabled=self.progress)
        self.bar.update(1, _running_rates(self.records))

    @property
    def complete(self) -> bool:
        return len(self.records) >= self.task.n_trials

    def finish(self, wall: float, workers: int) -> RunResult:
        """Write ``summary.json``, ``summary.md`` and (if trials ran) ``timing.json``; merge the recordings."""
        if self.bar is not None:
            self.bar.close()
        out, identity = self.out, self.identity
        run_meta = {k: identity[k] for k in ("task", "protocol", "detector", "seed")}
        summary = summarise(self.records, run_meta)
        atomic_write_text(out / "summary.json", json.dumps(summary, indent=2) + "\n")
        atomic_write_text(out / "summary.md", summary_markdown(summary))
        timing_file = out / "timing.json"
        if self.todo or not timing_file.is_file():  # a resume with nothing left to run keeps the run's figures
            timing = timing_summary(self.records, wall, len(self.todo), workers)
            atomic_write_text(timing_file, json.dumps(timing, indent=2) + "\n")
        else:
            timing = json.loads(timing_file.read_text())
        if self.record:
            parts = sorted(self.rec_dir.glob("trial_*.rrd"))
            if parts:
                from kgn_bench.viz.rerun_viewer import merge_recordings

                merge_recordings(parts, out / "recording.rrd")
        return RunResult(summary, timing, len(self.todo))


def _check_runs(runs: list[tuple[TaskConfig, str]], workers: int, progress: bool) -> dict[str, Any]:
    """Every check made before anything is written, for runs of (task, detector): each detector builds (an
    unknown name, a constructor that raises or weights that do not load stop here, in one line), each task's
    packaged objects are imported, each imported object's folder is intact (``check_object``), each camera
    sees the workspace; a bundled object that the user's library shadows with other content is a warning.
    Returns the built detectors by name."""
    built = {detector: build_detector(detector) for detector in dict.fromkeys(d for _, d in runs)}
    for task in {t.name: t for t, _ in runs}.values():
        ensure_objects(task.objects, workers=workers, progress=progress)  # packaged objects import on first use
        for name in dict.fromkeys(task.objects):  # a damaged library is an error here, not an outcome later
            if (folder := find_object(name)) is not None:
                check_object(folder)
        check_cameras(task)
        if mine := shadowed(task.objects):
            warn(f"task {task.name}: {len(mine)} bundled object(s) are shadowed by other content in "
                 f"{next(iter(mine.values())).parent} ({', '.join(mine)}); the run uses those copies")
    return built


def _open_run(stack: ExitStack, task: TaskConfig, detector: str, out: Path, record: bool,
              progress: bool, instance: Any = None) -> _RunWriter:
    """Lock the run folder ``out`` for the life of ``stack``, check or write its ``run.json``, and return the
    writer of its remaining trials."""
    out = Path(out)
    identity = json.loads(json.dumps(run_identity(task, detector, instance)))  # as it reads back from run.json
    stack.enter_context(run_lock(out))
    _prepare(out, identity)
    return _RunWriter(task, detector, out, identity, record, progress)


def run_benchmark(task: TaskConfig, detector: str, out: Path, workers: int = 1, record: bool = False,
                  progress: bool = True, backend: Backend = LOCAL) -> RunResult:
    """Run (or finish) ``task`` with ``detector`` into ``out``; writes the summaries; returns them."""
    if workers < 1:
        raise ValueError("workers must be ≥ 1")
    if record and backend.kind != "local":
        raise RunError("--record writes recordings on the workers' disks: use it with --backend local")
    backend = backend.reserving(task.resources.num_cpus, task.resources.num_gpus)
    cluster_ready = backend.prepare(_worker_init, (detector,), workers)  # Ray workers build the detector meanwhile
    instance = _check_runs([(task, detector)], workers, progress)[detector]
    cluster_ready()  # a cluster that cannot run the trials stops here too
    with ExitStack() as stack:
        writer = _open_run(stack, task, detector, out, record, progress, instance)
        start = time.perf_counter()
        _worker_setup(detector, instance)  # the in-process path uses the detector built above
        run_jobs(writer.jobs(), _run_one, writer.add, workers=workers, initializer=_worker_init,
                 initargs=(detector,), local=trial_threads, what=writer.what, backend=backend)
        return writer.finish(time.perf_counter() - start, workers)


def _run_any(args: tuple[int, str, TaskConfig, int]) -> tuple[int, TrialRecord]:
    """A trial of any run of ``run_many``: (run number, detector, task, index) -> (run number, record)."""
    k, detector, task, index = args
    _worker_setup(detector)
    return k, _run_one((task, index, None))


def run_many(runs: list[tuple[TaskConfig, str, Path]], workers: int = 1, progress: bool = True,
             backend: Backend = LOCAL) -> list[RunResult]:
    """Run (or finish) several runs, each (task, detector, folder), as ``run_benchmark`` would one after another,
    with the same files and the same records, but as one stream of jobs fed with the trials of every run in
    order, on one local pool of ``workers`` processes or ``workers`` Ray tasks in flight: a run's last trials
    overlap the next run's first, instead of leaving workers idle, and the workers start once (each builds the
    first run's detector, and any other the first time one of its trials comes). On Ray every job reserves the
    most CPUs and GPUs any of the tasks asks for. Every check of ``run_benchmark`` is made for every run before
    anything is written, and every folder is locked for the whole call. A run's ``timing.json`` ``wall_s`` is
    then the time it added to the call: from the previous run's completion (or the start) to its own. With one
    worker or for a single run, the runs go one after another through ``run_benchmark``."""
    if workers < 1:
        raise ValueError("workers must be ≥ 1")
    if workers == 1 or len(runs) <= 1:
        return [run_benchmark(t, d, o, workers=workers, progress=progress, backend=backend) for t, d, o in runs]
    backend = backend.reserving(max(t.resources.num_cpus for t, _, _ in runs),
                                max(t.resources.num_gpus for t, _, _ in runs))
    setup = (runs[0][1],)
    cluster_ready = backend.prepare(_worker_init, setup, workers)  # Ray workers build a detector meanwhile
    built = _check_runs([(t, d) for t, d, _ in runs], workers, progress)
    cluster_ready()
    with ExitStack() as stack:
        writers = [_open_run(stack, task, detector, out, False, progress, built[detector])
                   for task, detector, out in runs]
        results: list[RunResult | None] = [None] * len(writers)
        jobs = [(k, w.detector, task, i) for k, w in enumerate(writers) for task, i, _ in w.jobs()]
        clock = {"last": time.perf_counter()}

        def finish(k: int) -> None:
            now = time.perf_counter()
            results[k] = writers[k].finish(now - clock["last"] if writers[k].todo else 0.0, workers)
            clock["last"] = now

        for k, w in enumerate(writers):  # nothing left to run: summaries rewritten now, timing kept
            if not w.todo:
                finish(k)

        def arrived(result: tuple[int, TrialRecord]) -> None:
            k, rec = result
            writers[k].add(rec)
            if writers[k].complete:
                finish(k)

        run_jobs(jobs, _run_any, arrived, workers=workers, initializer=_worker_init, initargs=setup,
                 local=trial_threads, what=f"{len(writers)} runs ({sum(w.complete for w in writers)} complete)",
                 backend=backend)
    return [r for r in results if r is not None]


def timing_summary(records: list[TrialRecord], wall: float, ran: int, workers: int) -> dict[str, Any]:
    """Mean wall seconds per trial of each stage, and trials per minute of this invocation."""
    n = max(1, len(records))
    per_trial = {k: sum(r.timing.get(k, 0.0) for r in records) / n for k in TIMING_KEYS}
    sim = sum(a.sim_time for r in records for a in r.attempts) / n
    return {
        "trials_run": ran,
        "workers": workers,
        "wall_s": round(wall, 3),
        "trials_per_minute": round(60.0 * ran / wall, 2) if ran and wall > 0 else None,
        "per_trial_s": {k: round(v, 4) for k, v in per_trial.items()},
        "simulated_s_per_trial": round(sim, 3),
    }
