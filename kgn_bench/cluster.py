"""The Ray backend of ``pool.run_jobs``: the same jobs, one Ray task each, on a cluster or on a local Ray.

Only ``pool.run_jobs`` calls it, and only for ``--backend ray``: nothing else imports this module, and this
module imports ``ray`` only inside its functions, so the package works without the ``ray`` extra.

Each job is one Ray task (``num_cpus`` / ``num_gpus`` from the ``Backend``). The job's environment sets the
trial thread counts and ``MUJOCO_GL`` (``WORKER_ENV``, through the ``runtime_env`` of ``ray.init``; through
each task's when the process was connected to Ray before, by its own ``ray.init``), and a worker
process runs ``initializer(*initargs)`` once, lazily, before its first job (the per-process state the local
pool builds in its ``spawn``ed workers: a module-level cache keyed by the initializer and its arguments).
Results come back to the driver as they finish and go to ``on_result`` there, so the driver writes the same
files as the local pool. A worker that dies mid-job (killed, out of memory) has its job rerun on another
worker, up to ``MAX_RETRIES`` times; a job is a pure function of its arguments, so the rerun gives the same
result. Before any job runs, ``connect`` joins the cluster (or starts a local Ray) and runs the initializer
on the workers that will run the jobs, while the caller does its own checks: a cluster that cannot be
reached, or whose workers lack the package, its assets or the detector's weights, is one ``ClusterError``
line before the caller writes anything.
"""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from kgn_bench import kernels
from kgn_bench.errors import KGNBenchError
from kgn_bench.threads import TRIAL_THREADS, available_cores

__all__ = ["MAX_RETRIES", "WORKER_ENV", "ClusterError", "connect", "job_slots", "run_ray_jobs", "shutdown"]

J = TypeVar("J")
R = TypeVar("R")

MAX_RETRIES = 3
"""Reruns of a job whose worker died (Ray's ``max_retries``); an exception raised by the job is not retried."""

_THREADS = str(TRIAL_THREADS)
WORKER_ENV = {
    "OMP_NUM_THREADS": _THREADS, "MKL_NUM_THREADS": _THREADS, "OPENBLAS_NUM_THREADS": _THREADS,
    "NUMEXPR_NUM_THREADS": _THREADS, "LP_NUM_THREADS": _THREADS,
}
"""Environment of every Ray worker (plus ``MUJOCO_GL`` and ``PYOPENGL_PLATFORM`` of the driver): one thread per
library from the process start, as ``threads.pin_worker_threads`` sets it in a local pool worker."""

INSTALL_HINT = "pip install 'kgn-bench[ray]'"


class ClusterError(KGNBenchError, RuntimeError):
    """A Ray cluster that cannot be used: Ray not installed, an address that cannot be reached, workers that
    lack the package or its assets, or a worker that died more often than ``MAX_RETRIES``."""


def worker_env() -> dict[str, str]:
    """``WORKER_ENV`` with this process's ``MUJOCO_GL`` (default ``egl``), ``PYOPENGL_PLATFORM`` and kernel
    switches (``kernels``: a worker computes with the driver's kernel set, whatever its CPU), and its
    object library ``KGN_BENCH_OBJECTS`` when set (imported objects must be at that path on every node: a
    shared filesystem, or the same import run on each)."""
    gl = os.environ.get("MUJOCO_GL", "egl")
    env = {**WORKER_ENV, "MUJOCO_GL": gl, "PYOPENGL_PLATFORM": os.environ.get("PYOPENGL_PLATFORM", gl)}
    # the driver's kernel set: its switches, so that each worker caps its libraries as they load (OpenCV's,
    # which depends on the worker's CPU, is set by the worker's own import of kgn_bench, before OpenCV loads)
    kernel_vars = (kernels.KERNELS_VAR, *kernels.PORTABLE_ENV)
    env.update({k: os.environ[k] for k in kernel_vars if k in os.environ})
    if os.environ.get("KGN_BENCH_OBJECTS"):
        env["KGN_BENCH_OBJECTS"] = os.environ["KGN_BENCH_OBJECTS"]
    return env


def _ray():
    try:
        import ray
    except ImportError:
        raise ClusterError(f"--backend ray needs Ray: {INSTALL_HINT}") from None
    return ray


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return f"{type(e).__name__}: {text.splitlines()[0]}" if text else type(e).__name__


_HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
"""HTTP/2's client connection preface followed by an empty SETTINGS frame: what a gRPC client sends first."""


def _check_reachable(address: str, timeout: float = 5.0) -> None:
    """A ``host:port`` address must accept a TCP connection and answer as a gRPC server does, with an HTTP/2
    SETTINGS frame (Ray's GCS and client server speak gRPC); Ray itself would retry for minutes against a port
    where nothing, or something else, listens."""
    host, sep, port = address.rpartition(":")
    if address.startswith("ray://"):
        host, sep, port = address[len("ray://"):].rpartition(":")
    if not sep or not port.isdigit():
        return  # "auto" or another form Ray resolves itself
    try:
        with socket.create_connection((host, int(port)), timeout=timeout) as sock:
            sock.sendall(_HTTP2_PREFACE)
            reply = b""
            while len(reply) < 9:
                chunk = sock.recv(9 - len(reply))
                if not chunk:
                    break
                reply += chunk
    except TimeoutError:
        reply = b""
    except OSError as e:
        raise ClusterError(f"the Ray cluster at {address} cannot be reached ({e.strerror or type(e).__name__}); "
                           "start it with `ray start --head` or pass another --address") from None
    if len(reply) < 9 or reply[3] != 0x04:  # frame type 4: SETTINGS
        raise ClusterError(f"{address} answers, but not as a Ray head (no gRPC reply); pass the head's address "
                           "(`ray start --head` prints it)")


_STATE: dict[str, Any] = {}  # in a Ray worker process: the initializer key it ran
_SESSION: dict[str, Any] = {}  # in the driver: the address this process is connected to


@contextmanager
def _environ(env: dict[str, str]) -> Iterator[None]:
    """This process's environment with ``env`` added, restored on exit."""
    before = {k: os.environ.get(k) for k in env}
    os.environ.update(env)
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _job(work: Callable[[Any], Any] | None, initializer: Callable[..., None] | None, initargs: tuple[Any, ...],
         job: Any) -> Any:
    """The body of every Ray task: set the worker up once per (initializer, initargs), then run the job
    (``work`` None: only the set-up, the probe of ``connect``)."""
    key = (initializer, initargs)
    if initializer is not None and _STATE.get("key") != key:
        initializer(*initargs)
        _STATE["key"] = key
    if work is None:
        import kgn_bench
        from kgn_bench.resources import arm_xml

        return {"version": kgn_bench.__version__, "assets": arm_xml().is_file()}
    return work(job)


def _remote(ray, num_cpus: float, num_gpus: float):
    fn = _SESSION.get("remote")
    if fn is None:
        fn = _SESSION["remote"] = ray.remote(_job)
    # worker_env reaches the workers through the job when this process joined (its runtime environment, or the
    # local Ray's inherited one); a per-task environment would leave the workers Ray started already idle and
    # start new ones for it (Ray gives a task only a worker of its own environment)
    env = {} if _SESSION.get("job_env") == worker_env() else {"runtime_env": {"env_vars": worker_env()}}
    return fn.options(num_cpus=num_cpus, num_gpus=num_gpus, max_retries=MAX_RETRIES, retry_exceptions=False,
                      name="kgn_bench_job", **env)


def _unwrap(ray, e: BaseException) -> BaseException:
    """The job's own exception inside a ``RayTaskError``, else a ``ClusterError`` for Ray's own failures."""
    if isinstance(e, ray.exceptions.RayTaskError):
        cause = getattr(e, "cause", None)
        if isinstance(cause, BaseException) and not isinstance(cause, ray.exceptions.RayError):
            return cause
    return e


def _start_local_node(ray) -> Any:
    """Start a Ray head of this machine's cores for this process alone and connect to it; returns the head
    (``ray._private.node.Node``) for ``shutdown`` to stop, or None when ``ray.init`` started a usual local Ray.

    The head is the one ``ray.init(address="local")`` starts (GCS, raylet, the agents, the minimal API server,
    a reaper that stops them all if this process dies) without its two Python daemons that a one-command Ray
    never uses: the autoscaler monitor (there is no node to add) and the log monitor (the driver reads no
    worker output, ``log_to_driver=False``). On 2 cores that saves about 1 CPU-s at start and 1 s at stop
    (results/perf.md). The head is started through Ray's private ``Node``; should a Ray release change it, the
    usual ``ray.init`` starts the Ray instead. Never one that `ray start` left running on this machine."""
    import atexit

    try:
        from ray._private.authentication.authentication_token_setup import ensure_token_if_auth_enabled
        from ray._private.node import Node
        from ray._private.parameter import RayParams

        ensure_token_if_auth_enabled({}, create_token_if_missing=True)  # as ray.init does for a new local Ray
        params = RayParams(num_cpus=available_cores(), include_dashboard=False, include_log_monitor=False,
                           no_monitor=True)
    except (ImportError, TypeError):
        ray.init(address="local", num_cpus=available_cores(), include_dashboard=False, log_to_driver=False,
                 configure_logging=False)
        return None
    node = Node(params, head=True, shutdown_at_exit=False, spawn_reaper=True, ray_init_cluster=True)
    atexit.unregister(shutdown)  # once; it runs before Ray's own exit hook (registered earlier), which only
    atexit.register(shutdown)  # disconnects from this head
    try:
        ray.init(address=node.address, log_to_driver=False, configure_logging=False)
    except BaseException:
        node.kill_all_processes(check_alive=False, allow_graceful=True, wait=True)
        raise
    return node


def _join(ray, address: str | None) -> None:
    """Connect this process to ``address`` (None: ``RAY_ADDRESS``, else a new local Ray), unless it is already."""
    address = address or os.environ.get("RAY_ADDRESS") or None
    if ray.is_initialized() and _SESSION.get("address", address) != address:
        shutdown()
    if not ray.is_initialized():
        if address:
            _check_reachable(address)
        env = worker_env()
        try:
            if address:  # the nodes' workers were started by `ray start`: the job's runtime environment sets env
                ray.init(address=address, log_to_driver=False, configure_logging=False,
                         runtime_env={"env_vars": env})
            else:  # the new Ray's raylet inherits env, and so does every worker it starts, the prestarted ones too
                with _environ(env):
                    node = _start_local_node(ray)
        except Exception as e:  # ConnectionError, RuntimeError, ...: Ray's many ways of saying "not there"
            where = f"at {address}" if address else "(local)"
            hint = ("; a cluster with token authentication needs RAY_AUTH_MODE=token and its token (RAY_AUTH_TOKEN)"
                    if address and os.environ.get("RAY_AUTH_MODE") is None else "")
            raise ClusterError(f"the Ray cluster {where} cannot be used: {_first_line(e)}{hint}") from None
        _SESSION.clear()
        _SESSION.update(address=address, job_env=env, node=None if address else node)


def job_slots(address: str | None, num_cpus: float = 1.0, num_gpus: float = 0.0) -> int:
    """How many jobs of ``num_cpus`` CPUs (and ``num_gpus`` GPUs) the cluster at ``address`` runs at once (≥ 1):
    the default of ``--workers`` with ``--backend ray``. Joins the cluster (``ClusterError`` if it cannot)."""
    ray = _ray()
    _join(ray, address)
    resources = ray.cluster_resources()
    slots = resources.get("CPU", 0.0) // num_cpus
    if num_gpus:
        slots = min(slots, resources.get("GPU", 0.0) // num_gpus)
    return max(1, int(slots))


def connect(address: str | None, initializer: Callable[..., None] | None = None, initargs: Iterable[Any] = (),
            num_cpus: float = 1.0, num_gpus: float = 0.0, workers: int = 1) -> Callable[[], None]:
    """Join the Ray cluster at ``address`` (None: ``RAY_ADDRESS``, else start a local Ray with this machine's
    cores) unless this process is already connected there, and start ``initializer(*initargs)`` on as many
    workers as ``workers`` jobs will run at once (at most the cluster's CPUs / ``num_cpus``), so that they are
    set up while the caller does its own checks, not at their first job. Returns the wait for the first of
    those set-ups, which raises ``ClusterError`` in one line if the workers cannot run the jobs (the others
    would fail their first job the same way); a cluster that cannot be reached raises here."""
    ray = _ray()
    _join(ray, address)
    key = (initializer, tuple(initargs), num_cpus, num_gpus)
    if _SESSION.get("probed") == key:
        return lambda: None
    remote = _remote(ray, num_cpus, num_gpus)
    slots = int(ray.cluster_resources().get("CPU", 0.0) // num_cpus)
    refs = [remote.remote(None, initializer, tuple(initargs), None) for _ in range(max(1, min(workers, slots)))]
    ref = refs[0]
    _SESSION.setdefault("warming", []).extend(refs[1:])

    def wait() -> None:
        try:
            info = ray.get(ref)
        except Exception as e:
            _drain(ray)  # the other set-ups fail the same way: collect them, or Ray prints each at exit
            cause = _unwrap(ray, e)
            raise ClusterError(f"the Ray workers cannot run kgn-bench ({_first_line(cause)}); install the same "
                               f"kgn-bench on every node ({INSTALL_HINT}) or ship it in a runtime_env") from None
        if not info.get("assets"):
            raise ClusterError(f"the Ray workers' kgn-bench {info.get('version')} has no assets (arm7.xml); install "
                               "the wheel, which carries them, on every node")
        _SESSION["probed"] = key

    return wait


def _drain(ray, timeout: float = 30.0) -> None:
    """Collect the results of the extra worker set-ups ``connect`` started (their errors included: the jobs
    report those themselves), cancelling any still running after ``timeout`` s."""
    refs = _SESSION.pop("warming", [])
    if not refs:
        return
    done, pending = ray.wait(refs, num_returns=len(refs), timeout=timeout)
    for ref in pending:
        ray.cancel(ref, force=True)
    for ref in done + pending:
        try:
            ray.get(ref, timeout=timeout)
        except Exception:  # a set-up's error is the jobs' to report
            pass


def shutdown() -> None:
    """Leave the cluster (a local Ray this process started stops with it)."""
    import sys

    ray = sys.modules.get("ray")
    if ray is not None and ray.is_initialized():
        _drain(ray, timeout=0.0)
        ray.shutdown()
    node = _SESSION.get("node")
    if node is not None:  # a head of _start_local_node: ray.shutdown only disconnected from it
        node.kill_all_processes(check_alive=False, allow_graceful=True, wait=True)
    _SESSION.clear()


def run_ray_jobs(jobs: Sequence[J], work: Callable[[J], R], on_result: Callable[[R], Any], *, address: str | None,
                 workers: int, initializer: Callable[..., None] | None = None, initargs: Iterable[Any] = (),
                 num_cpus: float = 1.0, num_gpus: float = 0.0, what: str = "jobs") -> None:
    """``pool.run_jobs`` on Ray: at most ``workers`` jobs in flight, each result to ``on_result`` as it
    arrives. A job's exception cancels the rest and is raised here as it is; a worker that died more than
    ``MAX_RETRIES`` times raises ``ClusterError`` naming ``what`` (finished results are kept)."""
    initargs = tuple(initargs)
    connect(address, initializer, initargs, num_cpus, num_gpus)()
    ray = _ray()
    remote = _remote(ray, num_cpus, num_gpus)
    queue = list(jobs)[::-1]
    pending: list[Any] = []
    try:
        while queue or pending:
            while queue and len(pending) < workers:
                pending.append(remote.remote(work, initializer, initargs, queue.pop()))
            ready, pending = ray.wait(pending, num_returns=1)
            try:
                result = ray.get(ready[0])
            except ray.exceptions.RayTaskError as e:
                cause = _unwrap(ray, e)
                if cause is e:
                    raise ClusterError(f"a Ray task failed while running {what}: {_first_line(e)}") from None
                raise cause from None
            except ray.exceptions.RayError as e:  # the worker died more than MAX_RETRIES times, the node left
                raise ClusterError(f"a Ray worker died while running {what} ({type(e).__name__}, after "
                                   f"{MAX_RETRIES} retries); the finished ones are kept, rerun the same command "
                                   "to resume") from None
            on_result(result)
    except BaseException:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise
    finally:
        _drain(ray)
