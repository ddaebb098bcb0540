"""The files and viewers of rerun recordings (.rrd): merge per-trial recordings into a run's one, copy one
atomically, open one in the rerun viewer or serve it with rerun's web viewer on localhost.

Every command goes through the rerun CLI installed with rerun-sdk (``rerun_command``). The recordings are
written by ``viz.recording.Recorder``.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from kgn_bench.io import atomic_write

from .recording import RecordingError

__all__ = ["copy_recording", "merge_recordings", "open_viewer", "rerun_command", "serve_web", "stop_server",
           "web_viewer_url"]

_ANSI_ESCAPE = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")


def rerun_command() -> list[str]:
    """The command line that runs the installed rerun CLI (the ``rerun`` script next to ``sys.executable``,
    else the binary shipped in the ``rerun_cli`` package, else ``rerun`` on ``PATH``)."""
    exe_dir = Path(sys.executable).parent
    for candidate in (exe_dir / "rerun", exe_dir / "rerun.exe"):
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return [str(candidate)]
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin is not None:
        for candidate in (Path(spec.origin).parent / "rerun", Path(spec.origin).parent / "rerun.exe"):
            if candidate.is_file():
                return [str(candidate)]
    found = shutil.which("rerun")
    if found is None:
        raise RuntimeError("rerun CLI not found: install rerun-sdk in this environment")
    return [found]


def merge_recordings(parts: list[Path], out: Path) -> None:
    """Merge per-trial .rrd files into one .rrd at ``out`` with ``rerun rrd merge``.

    Each part keeps its own recording (store) in the result, keyed by its recording id, so parts must
    have distinct ids (``Recorder`` names). ``out`` is written to a temporary file beside it and moved into
    place with ``os.replace``. Raises ``FileNotFoundError`` for a missing part and ``RuntimeError`` naming
    the files if the CLI fails.
    """
    parts = [Path(p) for p in parts]
    out = Path(out)
    if not parts:
        raise ValueError("merge_recordings needs at least one input recording")
    for p in parts:
        if not p.is_file():
            raise FileNotFoundError(f"recording to merge does not exist: {p}")
    out.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(prefix=f".{out.name}.", suffix=".rrd", dir=out.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        cmd = [*rerun_command(), "rrd", "merge", *map(str, parts), "-o", str(tmp)]
        proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
        if proc.returncode != 0 or tmp.stat().st_size == 0:
            log = _ANSI_ESCAPE.sub("", proc.stderr or proc.stdout or "")
            tail = "\n".join(log.strip().splitlines()[-10:])
            last = tail.splitlines()[-1] if tail else "no message"
            names = ", ".join(p.name for p in parts[:5]) + (", ..." if len(parts) > 5 else "")
            raise RecordingError(f"merging {len(parts)} recordings ({names}) into {out} failed (rerun rrd merge "
                                 f"exit {proc.returncode}: {last})")
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; a recording is read like any result
        os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)


def copy_recording(path: Path, dest: Path) -> None:
    """Copy a recording to ``dest`` atomically (``OutputError`` naming ``dest`` if it cannot be written)."""
    with open(path, "rb") as src:
        atomic_write(dest, lambda f: shutil.copyfileobj(src, f, 1 << 20))


def web_viewer_url(port: int) -> str:
    """The address that opens the web viewer on ``port`` connected to the recording's server on ``port + 1``."""
    return f"http://127.0.0.1:{port}/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3A{port + 1}%2Fproxy"


def serve_web(path: Path, port: int = 9090, wait: bool = True) -> subprocess.Popen:
    """Serve ``path`` to a browser from this machine: rerun's own web viewer (shipped in the rerun-sdk wheel,
    no internet needed) over HTTP on 127.0.0.1:``port``, and the recording over gRPC on ``port + 1``. Prints
    the address to open (on a headless server, forward the two ports, e.g. ``ssh -L 9090:localhost:9090 -L
    9091:localhost:9091 host``). With ``wait`` it serves until interrupted; otherwise it returns the server
    process (stop it with ``stop_server``). ``RecordingError`` if the server does not start (a port in use, a
    broken recording)."""
    import socket
    import time

    for p in (port, port + 1):
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", p)) == 0:
                raise RecordingError(f"port {p} on 127.0.0.1 is in use; choose another with --port")
    cmd = [*rerun_command(), "--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(port),
           "--port", str(port + 1), str(path)]
    env = {**os.environ, "RERUN_ANALYTICS": "false"}
    import signal

    def terminate(signum, frame):
        raise KeyboardInterrupt

    # A `kill` stops the server too, not only Ctrl-C. The handler is in place before the server starts, and the
    # server is stopped on every way out of here but a clean `wait=False` start, so an interrupt that lands
    # while the viewer is still starting cannot leave it running in its own session.
    previous = signal.signal(signal.SIGTERM, terminate) if wait else None
    log = tempfile.TemporaryFile()
    proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=env, start_new_session=True)
    started = False
    try:
        deadline = time.monotonic() + 20.0
        while time.monotonic() < deadline:
            if proc.poll() is not None:
                log.seek(0)
                err = _ANSI_ESCAPE.sub("", log.read().decode(errors="replace"))
                last = err.strip().splitlines()[-1] if err.strip() else f"exit {proc.returncode}"
                raise RecordingError(f"the rerun web viewer did not start: {last}")
            with socket.socket() as sock:
                if sock.connect_ex(("127.0.0.1", port)) == 0:
                    break
            time.sleep(0.1)
        else:
            raise RecordingError(f"the rerun web viewer did not answer on port {port} within 20 s")
        print(f"serving {path}: open {web_viewer_url(port)}", flush=True)
        started = True
        if wait:
            proc.wait()
    except KeyboardInterrupt:
        if not started:
            raise
    finally:
        if wait or not started:
            stop_server(proc)
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return proc


def stop_server(proc: subprocess.Popen) -> None:
    """Stop a server started in its own session and everything it started (the ``rerun`` launcher runs the
    viewer binary as a child)."""
    import signal

    try:
        os.killpg(proc.pid, signal.SIGTERM)
    except ProcessLookupError:
        return
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def open_viewer(path: Path) -> None:
    """Open the recording ``path`` in the rerun viewer (a detached ``rerun`` process); returns at once."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"recording does not exist: {path}")
    subprocess.Popen([*rerun_command(), str(path)], start_new_session=True, stdin=subprocess.DEVNULL)
