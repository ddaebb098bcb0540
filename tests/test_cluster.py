"""The Ray backend (``kgn_bench.cluster`` behind ``pool.run_jobs``) on real Ray instances and real trials.

A local Ray started in this process gives the local pool's trial records and summary bytes, resumes a run the
local pool began (and the other way round), generates a byte-identical dataset, and raises a job's own error.
A Ray head started with ``ray start --head`` on 127.0.0.1 (2 CPUs) and joined with ``--address`` runs the CI
regression task with the oracle, with one worker killed mid-trial, to the local run's summary bytes and
records; a driver killed mid-run has its jobs stopped there, and the same command resumes to the same summary.
A cluster that cannot be reached, or whose workers lack a module the detector needs, is one line with nothing
written. After the module no Ray process is left.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import socket
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

import psutil
import pytest

from kgn_bench import cluster
from kgn_bench.bench.runner import read_trials, run_benchmark
from kgn_bench.cli import main
from kgn_bench.config import load_task
from kgn_bench.data.generate import generate_dataset
from kgn_bench.pool import Backend, run_jobs
from kgn_bench.threads import available_cores

ROOT = Path(__file__).resolve().parents[1]
TASKS = ROOT / "tasks"
RAY = str(Path(sys.executable).parent / "ray")
DAEMONS = ("raylet", "gcs_server")
LOCAL_RAY = Backend("ray")


def _ray_daemons() -> list[psutil.Process]:
    found = []
    for p in psutil.process_iter(["name", "cmdline"]):
        cmd = p.info["cmdline"] or []
        if p.info["name"] in DAEMONS or (cmd and Path(cmd[0]).name in DAEMONS):
            found.append(p)
    return found


@pytest.fixture(scope="module", autouse=True)
def no_ray_left():
    """After the module (and the head's teardown): this process left Ray, and no raylet or GCS is running."""
    yield
    cluster.shutdown()
    deadline = time.monotonic() + 20
    while _ray_daemons() and time.monotonic() < deadline:
        time.sleep(0.5)
    assert not _ray_daemons(), f"Ray processes left: {[p.pid for p in _ray_daemons()]}"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _records(out: Path) -> list[dict]:
    return sorted(({k: v for k, v in r.to_json().items() if k != "timing"} for r in read_trials(out / "trials.jsonl")),
                  key=lambda r: r["index"])


def _same_run(a: Path, b: Path) -> None:
    assert (a / "summary.json").read_bytes() == (b / "summary.json").read_bytes()
    assert (a / "summary.md").read_bytes() == (b / "summary.md").read_bytes()
    assert _records(a) == _records(b)


def _keep_lines(path: Path, n: int) -> None:
    lines = path.read_text().splitlines(keepends=True)
    path.write_text("".join(lines[:n]))


def test_nothing_imports_ray_without_the_ray_backend():
    code = ("import sys, kgn_bench.cli, kgn_bench.bench.runner, kgn_bench.bench.sweep, kgn_bench.bench.benchmark, "
            "kgn_bench.data.generate; from kgn_bench.pool import run_jobs; run_jobs([1, -2], abs, print, workers=2); "
            "print('ray' in sys.modules, 'kgn_bench.cluster' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert sorted(out[:2]) == ["1", "2"] and out[2:] == ["False", "False"]


# -- a local Ray in this process -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def task():
    """ci_oracle with two objects: two single-object trials."""
    return replace(load_task(TASKS / "ci_oracle.toml"), objects=("cuboid", "sphere"))


@pytest.fixture(scope="module")
def local_run(task, tmp_path_factory):
    out = tmp_path_factory.mktemp("cluster") / "local"
    run_benchmark(task, "oracle", out, workers=1, progress=False)
    return out


def test_a_local_ray_gives_the_local_pools_records(task, local_run, tmp_path):
    import ray

    out = tmp_path / "ray"
    result = run_benchmark(task, "oracle", out, workers=2, progress=False, backend=LOCAL_RAY)
    assert result.ran == 2
    assert ray.is_initialized() and ray.cluster_resources()["CPU"] == available_cores()  # started here
    _same_run(local_run, out)
    assert len((out / "trials.jsonl").read_text().splitlines()) == 2


def test_a_local_rays_workers_inherit_the_worker_env_and_the_driver_keeps_its_own(monkeypatch):
    cluster.shutdown()
    monkeypatch.setenv("OMP_NUM_THREADS", "7")
    got = []
    job_env = lambda _: (os.environ.get("OMP_NUM_THREADS"), os.environ.get("MUJOCO_GL"),  # noqa: E731 (by value)
                         dict(__import__("ray").get_runtime_context().runtime_env))
    run_jobs([0, 1, 2], job_env, got.append, workers=2, backend=LOCAL_RAY)
    # one thread per trial and the driver's GL on every worker, with no runtime environment of their own (so
    # the workers Ray prestarted run the jobs), while this process keeps its own thread setting
    assert got == [("1", os.environ.get("MUJOCO_GL", "egl"), {})] * 3
    assert os.environ["OMP_NUM_THREADS"] == "7"


def test_a_run_resumes_across_backends(task, local_run, tmp_path):
    half = tmp_path / "local_then_ray"
    shutil.copytree(local_run, half)
    _keep_lines(half / "trials.jsonl", 1)
    assert run_benchmark(task, "oracle", half, workers=1, progress=False, backend=LOCAL_RAY).ran == 1
    _same_run(local_run, half)
    back = tmp_path / "ray_then_local"
    shutil.copytree(half, back)
    _keep_lines(back / "trials.jsonl", 1)
    assert run_benchmark(task, "oracle", back, workers=1, progress=False).ran == 1
    _same_run(local_run, back)


def test_several_runs_go_to_ray_as_one_stream_with_the_local_records(task, local_run, tmp_path):
    """``run_many`` (a benchmark plan, a sweep) on Ray: two detectors' runs in one stream, the workers set up
    with the first detector and building the second at its first trial; each run as the local pool's."""
    from kgn_bench.bench.runner import run_many

    run_benchmark(task, "random", tmp_path / "local_random", workers=1, progress=False)
    runs = [(task, det, tmp_path / "ray" / det) for det in ("oracle", "random")]
    results = run_many(runs, workers=2, progress=False, backend=LOCAL_RAY)
    assert [r.ran for r in results] == [2, 2]
    _same_run(local_run, tmp_path / "ray" / "oracle")
    _same_run(tmp_path / "local_random", tmp_path / "ray" / "random")


def test_a_dataset_generated_on_ray_is_byte_identical(tiny_dataset, tmp_path):
    root, config = tiny_dataset
    other = tmp_path / "ray"
    stats = generate_dataset(config, other, workers=2, progress=False, backend=LOCAL_RAY)
    assert stats.scenes == config.scenes
    files = sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(other) for p in other.rglob("*") if p.is_file())
    assert len(files) == 3 + 3 * (1 + 3 * config.views)  # manifest, splits; per scene: scene.json, 3 images a view
    for f in files:
        assert (root / f).read_bytes() == (other / f).read_bytes(), f


def test_a_jobs_own_error_is_raised_as_it_is():
    got = []
    with pytest.raises(ValueError, match="invalid literal"):
        run_jobs(["1", "2", "x"], int, got.append, workers=1, backend=LOCAL_RAY)
    assert set(got) <= {1, 2}


def test_a_job_whose_worker_dies_on_every_retry_is_one_line_and_the_finished_results_are_kept():
    """The lambda is pickled by value, so the workers need not import this test module."""
    got = []
    die = lambda job: os._exit(1) if job == "die" else int(job)  # noqa: E731
    with pytest.raises(cluster.ClusterError) as e:
        run_jobs(["1", "2", "die", "3"], die, got.append, workers=1, backend=LOCAL_RAY, what="the test jobs")
    assert str(e.value) == (f"a Ray worker died while running the test jobs (WorkerCrashedError, after "
                            f"{cluster.MAX_RETRIES} retries); the finished ones are kept, rerun the same command "
                            "to resume")
    assert got == [1, 2]  # in submission order with one job in flight; "3" was never started


def test_an_unreachable_cluster_is_one_line_and_writes_nothing(tmp_path, capsys):
    address = f"127.0.0.1:{_free_port()}"
    for argv in (["run", str(TASKS / "ci_oracle.toml"), "--detector", "oracle", "--out", str(tmp_path / "run")],
                 ["data", "generate", "--mode", "single", "--scenes", "2", "--out", str(tmp_path / "data")]):
        assert main([*argv, "--backend", "ray", "--address", address, "--quiet"]) == 2
        err = capsys.readouterr().err.strip()
        assert err == (f"kgn-bench: error: the Ray cluster at {address} cannot be reached (Connection refused); "
                       "start it with `ray start --head` or pass another --address")
    assert not list(tmp_path.iterdir())
    assert main(["run", "ci_oracle", "--detector", "oracle", "--address", address]) == 2  # needs --backend ray
    assert capsys.readouterr().err.strip() == "kgn-bench: error: --address and --num-gpus need --backend ray"


@pytest.mark.parametrize("reply", [b"HTTP/1.0 400 Bad Request\r\n\r\n", None])
def test_a_port_where_something_else_listens_fails_in_seconds(reply, tmp_path, capsys):
    """An HTTP server, or a server that accepts and stays silent, is not a Ray head: one line, not a hang."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    address = f"127.0.0.1:{server.getsockname()[1]}"
    held = []

    def serve():
        conn, _ = server.accept()
        held.append(conn)
        if reply is not None:
            conn.recv(1024)
            conn.sendall(reply)

    threading.Thread(target=serve, daemon=True).start()
    start = time.monotonic()
    argv = ["run", str(TASKS / "ci_oracle.toml"), "--detector", "oracle", "--out", str(tmp_path / "run")]
    assert main([*argv, "--backend", "ray", "--address", address, "--quiet"]) == 2
    assert time.monotonic() - start < 20
    assert capsys.readouterr().err.strip() == (f"kgn-bench: error: {address} answers, but not as a Ray head (no gRPC "
                                               "reply); pass the head's address (`ray start --head` prints it)")
    assert not list(tmp_path.iterdir())
    server.close()


def test_workers_that_lack_the_detectors_module_are_one_line_and_nothing_is_written(tmp_path, monkeypatch, capsys):
    """The module is importable here (on this process's sys.path) but not on the Ray workers."""
    (tmp_path / "here_only").mkdir()
    (tmp_path / "here_only" / "only_here_detector.py").write_text(
        "from kgn_bench.detectors.oracle import OracleDetector as Detector\n")
    monkeypatch.syspath_prepend(str(tmp_path / "here_only"))
    out = tmp_path / "run"
    argv = ["run", "ci_oracle", "--detector", "only_here_detector:Detector", "--backend", "ray", "--quiet",
            "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("kgn-bench: error: the Ray workers cannot run kgn-bench (") and "\n" not in err
    assert "only_here_detector" in err and "install the same kgn-bench on every node" in err
    assert not out.exists()


# -- a Ray head started with `ray start --head`, joined with --address -----------------------------------


@pytest.fixture(scope="module")
def ray_head():
    """``ray start --head`` on 127.0.0.1 with 2 CPUs and token authentication (a token of this module):
    ``(address, env)``, ``env`` being what a driver needs to join it; ``ray stop --force`` afterwards."""
    cluster.shutdown()  # the local Ray of the tests above is not needed any more
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(32)}
    port = _free_port()
    try:
        subprocess.run([RAY, "start", "--head", "--num-cpus", "2", "--port", str(port), "--include-dashboard=false",
                        "--disable-usage-stats"], check=True, capture_output=True, timeout=180, env=env)
        yield f"127.0.0.1:{port}", env
    finally:
        subprocess.run([RAY, "stop", "--force"], capture_output=True, timeout=120, env=env)


def _kill_one_job_worker(started: Path, killed: list[int], stop: threading.Event) -> None:
    """Once the run has started (``run.json``), SIGKILL the first Ray worker seen running a job, a second
    into its trial."""
    while not stop.is_set() and not started.is_file():
        time.sleep(0.1)
    while not stop.is_set():
        for p in psutil.process_iter(["name", "cmdline"]):
            title = " ".join(p.info["cmdline"] or []) + " " + (p.info["name"] or "")
            if "ray::kgn_bench_job" in title:
                time.sleep(1.0)
                try:
                    p.kill()
                    killed.append(p.pid)
                except psutil.NoSuchProcess:
                    continue
                return
        time.sleep(0.1)


def test_the_ci_regression_task_on_a_ray_head_matches_the_local_run_with_a_worker_killed(ray_head, tmp_path,
                                                                                          session_run):
    """The driver is a `kgn-bench run --backend ray --address` process of its own, as on a real cluster; the
    local run (the local pool, 2 workers) is the session's; 4 of the task's scenes."""
    address, env = ray_head
    task = str(TASKS / "ci_regression.toml")
    local, on_ray = session_run("ci_regression", "oracle", trials=4), tmp_path / "ray"
    killed: list[int] = []
    stop = threading.Event()
    killer = threading.Thread(target=_kill_one_job_worker, args=(on_ray / "run.json", killed, stop), daemon=True)
    killer.start()
    try:
        driver = subprocess.run([str(Path(sys.executable).parent / "kgn-bench"), "run", task, "--detector", "oracle",
                                 "--trials", "4", "--quiet", "--backend", "ray", "--address", address, "--out",
                                 str(on_ray)],
                                capture_output=True, text=True, timeout=400, env=env)
    finally:
        stop.set()
        killer.join()
    assert driver.returncode == 0, driver.stderr
    assert killed, "no Ray worker was running a trial"
    assert "2 in flight on Ray" in driver.stdout  # --workers defaults to the head's 2 CPUs
    _same_run(local, on_ray)
    assert len((on_ray / "trials.jsonl").read_text().splitlines()) == 4  # the killed trial once, after its retry
    assert json.loads((on_ray / "run.json").read_text())["trials"] == 4


def _job_workers() -> list[psutil.Process]:
    return [p for p in psutil.process_iter(["cmdline"]) if "ray::kgn_bench_job" in " ".join(p.info["cmdline"] or [])]


def test_a_driver_killed_mid_run_resumes_with_the_same_command(ray_head, tmp_path):
    """The driver is SIGKILLed after its first trial: the head stops its jobs, and the same command finishes the
    run to the local pool's summary bytes."""
    address, env = ray_head
    local, out = tmp_path / "local", tmp_path / "ray"
    run_benchmark(load_task(TASKS / "ci_oracle.toml"), "oracle", local, workers=1, progress=False)
    cmd = [str(Path(sys.executable).parent / "kgn-bench"), "run", "ci_oracle", "--detector", "oracle", "--workers",
           "1", "--quiet", "--backend", "ray", "--address", address, "--out", str(out)]
    driver = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    trials = out / "trials.jsonl"
    deadline = time.monotonic() + 120
    while not (trials.is_file() and trials.read_text().count("\n") >= 1) and time.monotonic() < deadline:
        assert driver.poll() is None, "the driver ended before its first trial"
        time.sleep(0.05)
    driver.kill()
    driver.wait()
    done = trials.read_text().count("\n")
    assert 1 <= done < 6
    deadline = time.monotonic() + 30
    while _job_workers() and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not _job_workers(), "the killed driver's jobs still run on the head"
    resumed = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert resumed.returncode == 0, resumed.stderr
    assert f"{6 - done} trials in" in resumed.stdout
    _same_run(local, out)
    assert len(trials.read_text().splitlines()) == 6


def test_worker_env_carries_the_object_library(monkeypatch):
    from kgn_bench.cluster import WORKER_ENV, worker_env

    monkeypatch.delenv("KGN_BENCH_OBJECTS", raising=False)
    assert "KGN_BENCH_OBJECTS" not in worker_env() and set(WORKER_ENV) <= set(worker_env())
    monkeypatch.setenv("KGN_BENCH_OBJECTS", "/shared/objects")
    assert worker_env()["KGN_BENCH_OBJECTS"] == "/shared/objects"
