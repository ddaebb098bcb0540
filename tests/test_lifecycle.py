"""Process lifetime under signals: SIGTERM/SIGHUP stop a command as Ctrl-C does, with its workers; workers
die with their parent, even when it is killed with SIGKILL. Real processes, real signals."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from kgn_bench.lifecycle import Stopped, interrupts_as_keyboard

KGN_BENCH = str(Path(sys.executable).parent / "kgn-bench")


def test_sigterm_and_sighup_raise_keyboard_interrupt_inside_the_block_only():
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGTERM, signal.SIGHUP)}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        with pytest.raises(Stopped) as e, interrupts_as_keyboard():
            os.kill(os.getpid(), sig)
            time.sleep(1)
        assert e.value.signum == sig and isinstance(e.value, KeyboardInterrupt)
    assert {sig: signal.getsignal(sig) for sig in before} == before  # the previous handlers are back


def _wait_for(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.1)


def _gone(pids: list[int]) -> bool:
    return not [p for p in pids if psutil.pid_exists(p) and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]


def _lines(path: Path) -> int:
    return path.read_text().count("\n") if path.is_file() else 0


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_a_stopped_run_leaves_no_process_and_resumes(sig, tmp_path):
    out = tmp_path / "run"
    cmd = [KGN_BENCH, "run", "ci_oracle", "--detector", "oracle", "--workers", "2", "--quiet", "--out", str(out)]
    main = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    proc = psutil.Process(main.pid)
    _wait_for(lambda: _lines(out / "trials.jsonl") >= 1 or main.poll() is not None, 180, "a first trial")
    assert main.poll() is None, "the run ended before it could be stopped"
    children = [c.pid for c in proc.children(recursive=True)]
    assert len(children) >= 2  # the two workers (and multiprocessing's resource tracker)
    os.kill(main.pid, sig)
    rc = main.wait(timeout=30)
    assert rc == (143 if sig == signal.SIGTERM else -9)
    if sig == signal.SIGTERM:
        assert main.stderr.read().strip() == "kgn-bench: stopped by SIGTERM"
    _wait_for(lambda: _gone(children), 5, "the workers to die")
    done = _lines(out / "trials.jsonl")
    assert done < json.loads((out / "run.json").read_text())["trials"]
    assert subprocess.run(cmd, capture_output=True, timeout=300).returncode == 0  # the lock went with the process
    records = [json.loads(line) for line in (out / "trials.jsonl").read_text().splitlines()]
    assert sorted(r["index"] for r in records) == list(range(len(records))) and len(records) >= done


def test_a_stopped_dataset_generation_leaves_no_process(tmp_path):
    out = tmp_path / "data"
    cmd = [KGN_BENCH, "data", "generate", "--mode", "multi", "--scenes", "40", "--views", "2", "--workers", "2",
           "--quiet", "--out", str(out)]
    main = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    proc = psutil.Process(main.pid)
    _wait_for(lambda: len(proc.children()) >= 2 or main.poll() is not None, 60, "the workers")
    time.sleep(2)
    children = [c.pid for c in proc.children(recursive=True)]
    main.send_signal(signal.SIGHUP)
    assert main.wait(timeout=30) == 128 + signal.SIGHUP
    _wait_for(lambda: _gone(children), 5, "the workers to die")


def test_a_stopped_import_stops_its_coacd_child_and_leaves_no_folder(tmp_path):
    import trimesh

    mesh = tmp_path / "torus.ply"
    trimesh.creation.torus(0.05, 0.015, major_sections=160, minor_sections=50).export(mesh)
    library = tmp_path / "library"
    cmd = [KGN_BENCH, "objects", "add", str(mesh), "--name", "ring_x", "--root", str(library)]
    main = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    proc = psutil.Process(main.pid)
    _wait_for(lambda: proc.children() or main.poll() is not None, 120, "CoACD's child")
    assert main.poll() is None, main.stderr.read()
    children = [c.pid for c in proc.children(recursive=True)]
    main.terminate()
    assert main.wait(timeout=30) == 143
    _wait_for(lambda: _gone(children), 5, "CoACD's child to die")
    assert not library.exists() or not list(library.iterdir())  # no temporary folder left behind


def _loader_workers(proc: psutil.Process) -> list[psutil.Process]:
    """The training process's DataLoader workers: its Python children other than multiprocessing's tracker."""
    out = []
    for c in proc.children():
        try:
            if "resource_tracker" not in " ".join(c.cmdline()):
                out.append(c)
        except psutil.Error:  # ended (or a zombie) meanwhile
            pass
    return out


def test_a_training_stopped_by_a_group_signal_stops_cleanly_and_resumes(tmp_path, tiny_dataset):
    """A SIGTERM for the whole process group (a scheduler stopping a job) reaches the DataLoader's worker
    first here: the worker ignores it, the training process stops with one line and its worker, and the rerun
    finishes the schedule from the last checkpoint."""
    root, _ = tiny_dataset
    config = tmp_path / "train_stop.toml"
    config.write_text(f'[train]\nvariant = "kgnv2"\ndata = "{root}"\nout = "{tmp_path / "run"}"\nepochs = 3\n'
                      'batch_size = 2\nlr = 1e-3\nlr_steps = [2]\nworkers = 1\neval_every = 10\neval_views = 1\n'
                      '[augment]\ninput_size = [640, 640]\n')  # large crops: an epoch of seconds, not a blink
    cmd = [KGN_BENCH, "train", str(config), "--quiet", "--threads", "1"]
    main = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    proc = psutil.Process(main.pid)
    _wait_for(lambda: (_lines(tmp_path / "run" / "history.jsonl") >= 1 and _loader_workers(proc))
              or main.poll() is not None, 180, "the second epoch's loader worker")
    assert main.poll() is None, main.stderr.read()
    workers = _loader_workers(proc)
    workers[0].send_signal(signal.SIGTERM)  # the group's signal, as it reaches the worker
    time.sleep(1.0)
    assert workers[0].is_running() and workers[0].status() != psutil.STATUS_ZOMBIE
    os.killpg(main.pid, signal.SIGTERM)
    assert main.wait(timeout=60) == 143
    assert main.stderr.read().strip() == "kgn-bench: stopped by SIGTERM"
    _wait_for(lambda: _gone([w.pid for w in workers]), 10, "the loader worker to end")
    assert subprocess.run(cmd, capture_output=True, timeout=300).returncode == 0
    history = [json.loads(line) for line in (tmp_path / "run" / "history.jsonl").read_text().splitlines()]
    assert [h["epoch"] for h in history] == [1, 2, 3]
