"""The one Dask cluster helper (:func:`render_inspect.batch.dask_client`): the worker count
budgeted by cores, tasks and memory; an existing ``distributed.Client`` (a notebook's)
used and left open; ``--scheduler`` endpoints that are not Dask schedulers, or schedulers
without workers, refused within a bounded time with one line and nothing written; numba
threads set inside each task (never through the workers' environment); a quiet Ctrl-C.
Real clusters throughout: LocalClusters of process workers, ``dask scheduler`` processes,
TCP servers that accept and stay silent or send garbage."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from render_inspect.batch import cluster_info, dask_client, plan_workers
from render_inspect.batch import _cluster
from render_inspect.core.errors import InputError
from render_inspect.pipeline import run_sweep

REPO = Path(__file__).resolve().parents[1]
DASK = Path(sys.executable).parent / "dask"
GIB = 2 ** 30

ONE = """
name = "one"
scene = "sts_sinusoidal_grid"
[set]
"machine.preset" = "ideal"
"material.preset" = "ideal"
"simulation.region" = [-0.02, -0.02, 0.02, 0.02]
"simulation.pixel" = 0.002
"process.workpiece_radius" = 0.05
[grid]
"tool.nose_radius" = [0.2]
"""


def _env():
    """This checkout first on the path (the command runs the code under test)."""
    return {**os.environ, "PYTHONPATH": str(REPO)}


def _cli(*args):
    return [sys.executable, "-m", "render_inspect.cli", *map(str, args)]


# ------------------------------------------------------------------ worker budget
def test_workers_are_capped_by_cores_tasks_and_memory():
    budget = (8 * GIB, "test budget")
    assert plan_workers(48, tasks=1, cpus=2, budget=budget) == (1, ["2 CPU cores", "1 task to run"])
    assert plan_workers(None, tasks=100, cpus=16, budget=budget)[0] == 16
    n, why = plan_workers(None, tasks=100, cpus=16, memory_per_task=GIB, budget=budget)
    # 8 GiB hold 6 workers of 1 GiB + 256 MiB (the worker process itself)
    assert n == 6 and "the memory budget of 8 GiB (test budget) holds 6 workers" in why[0]
    assert plan_workers(3, tasks=10, cpus=4, budget=budget) == (3, [])
    # a task larger than the budget still gets one worker (the point itself is refused
    # by its own memory check)
    assert plan_workers(4, tasks=4, cpus=4, memory_per_task=100 * GIB, budget=budget)[0] == 1


def test_workers_option_is_checked():
    for bad in (0, -1, 1025, 2.5, True, "3"):
        with pytest.raises(InputError, match=r"--workers must be an integer in \[1, 1024\]"):
            with dask_client(workers=bad):
                pass
    with pytest.raises(InputError, match="exclude each other"):
        with dask_client(workers=2, scheduler="tcp://127.0.0.1:9"):
            pass
    with pytest.raises(InputError, match="client must be a distributed.Client, got str"):
        with dask_client(client="tcp://127.0.0.1:8786"):
            pass


@pytest.mark.slow
def test_a_local_cluster_has_dask_memory_limits_and_numba_threads_per_task():
    """The LocalCluster's workers: memory limits (Dask's own memory management is on),
    SIGINT ignored, no NUMBA_NUM_THREADS in their environment; a task that compiles a new
    parallel kernel runs with the thread count set inside it."""
    def task_info():
        import numba
        import numpy as np

        @numba.njit(parallel=True, cache=False)
        def fresh(a):  # compiled in the worker, in the task's thread
            s = 0.0
            for i in numba.prange(a.size):
                s += a[i]
            return s

        return {"env": os.environ.get("NUMBA_NUM_THREADS"), "threads": numba.get_num_threads(),
                "config": int(numba.config.NUMBA_NUM_THREADS),
                "sum": fresh(np.ones(1000)),
                "sigint": signal.getsignal(signal.SIGINT) == signal.SIG_IGN}

    budget = (4 * GIB, "test budget")
    with dask_client(workers=2, tasks=2, budget=budget) as c:
        info = cluster_info(c)
        assert info["kind"] == "local" and info["workers"] == 2
        assert info["threads"] == max(1, (os.cpu_count() or 1) // 2)
        assert info["memory_limit_bytes"] == 2 * GIB
        limits = {w["memory_limit"] for w in c.scheduler_info()["workers"].values()}
        assert limits == {2 * GIB}
        got = c.submit(_cluster.call_with_threads, 1, task_info, pure=False).result()
    assert got["env"] is None and got["sum"] == 1000.0 and got["sigint"]
    assert got["threads"] == 1 and got["config"] == (os.cpu_count() or 1)


# ------------------------------------------------------------------ existing clients
@pytest.mark.slow
def test_an_existing_client_is_used_and_left_open(tmp_path):
    """``run_sweep(client=...)`` (a TypeError before) and the client open in the process
    (``get_client()`` in a notebook) run the points; the client stays open."""
    from distributed import Client, LocalCluster

    (tmp_path / "one.toml").write_text(ONE)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                      dashboard_address=":0") as cluster:
        with Client(cluster, set_as_default=False) as client:
            info = run_sweep(tmp_path / "one.toml", tmp_path / "a", client=client)
            assert info["done"] == 1 and info["cluster"]["kind"] == "client"
            assert client.status == "running"
        with Client(cluster) as notebook:  # the default client, as in a notebook
            info = run_sweep(tmp_path / "one.toml", tmp_path / "b")
            assert info["done"] == 1 and info["cluster"]["kind"] == "client"
            assert notebook.status == "running"


# ------------------------------------------------------------------ --scheduler
class _Server:
    """A TCP server on 127.0.0.1 that accepts and then stays silent or sends garbage."""

    def __init__(self, mode: str):
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.port = self.sock.getsockname()[1]
        self.mode = mode
        self.conns = []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self):
        while True:
            try:
                c, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(c)
            if self.mode == "garbage":
                c.sendall(b"\xff" * 32 + bytes(range(256)))

    def close(self):
        for c in self.conns:
            c.close()
        self.sock.close()


@pytest.mark.parametrize("mode, message", [
    ("silent", r"no Dask scheduler answered within 2 s \(it accepted the connection but sent no "
               r"handshake\)"),
    ("garbage", r"not a Dask scheduler: it answered with data that is not Dask's protocol"),
])
def test_endpoints_that_are_not_schedulers_are_refused_in_bounded_time(tmp_path, monkeypatch,
                                                                      mode, message):
    monkeypatch.setattr(_cluster, "CONNECT_TIMEOUT_S", 2)
    (tmp_path / "one.toml").write_text(ONE)
    srv = _Server(mode)
    try:
        t0 = time.monotonic()
        with pytest.raises(InputError, match=message):
            run_sweep(tmp_path / "one.toml", tmp_path / "out",
                      scheduler=f"tcp://127.0.0.1:{srv.port}")
        assert time.monotonic() - t0 < 10
        with pytest.raises(InputError, match=message):  # the tiled simulation's path too
            with dask_client(scheduler=f"127.0.0.1:{srv.port}"):
                pass
    finally:
        srv.close()
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_the_command_line_says_the_same_within_the_documented_time(tmp_path):
    """The documented 15 s: an endpoint that accepts and never answers ends the command
    within about 20 s, with one line and exit code 1."""
    (tmp_path / "one.toml").write_text(ONE)
    srv = _Server("silent")
    try:
        t0 = time.monotonic()
        res = subprocess.run(_cli("sweep", "one.toml", "--out", "out", "--scheduler",
                                  f"tcp://127.0.0.1:{srv.port}"), cwd=tmp_path, capture_output=True,
                             text=True, timeout=120, env=_env())
        elapsed = time.monotonic() - t0
    finally:
        srv.close()
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert "no Dask scheduler answered within 15 s" in res.stderr
    assert elapsed < 15 + 20  # the probe's 15 s and the start-up
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_a_scheduler_without_workers_is_one_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(_cluster, "WORKER_WAIT_S", 3)
    sched_file = tmp_path / "scheduler.json"
    proc = subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0",
                             "--no-dashboard", "--scheduler-file", str(sched_file)],
                            cwd=tmp_path, env=_env(), stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        t0 = time.monotonic()
        while not sched_file.exists():
            assert time.monotonic() - t0 < 60, "the scheduler did not start"
            time.sleep(0.2)
        time.sleep(0.5)
        address = json.loads(sched_file.read_text())["address"]
        (tmp_path / "one.toml").write_text(ONE)
        with pytest.raises(InputError, match=rf"the Dask cluster at {address} has no worker "
                                             rf"after 3 s; start some with `dask worker {address}`"):
            run_sweep(tmp_path / "one.toml", tmp_path / "out", scheduler=address)
        assert not (tmp_path / "out").exists()
    finally:
        proc.terminate()
        proc.wait(timeout=30)


# ------------------------------------------------------------------ Ctrl-C
@pytest.mark.slow
def test_ctrl_c_during_a_sweep_is_one_line(tmp_path):
    """SIGINT to the whole process group (what Ctrl-C in a terminal does) while a
    LocalCluster's workers run points: exit 130, one line, no traceback of Dask's."""
    (tmp_path / "many.toml").write_text(ONE.replace(
        '"simulation.pixel" = 0.002', '"simulation.pixel" = 0.00025').replace(
        '"tool.nose_radius" = [0.2]', '"tool.nose_radius" = [0.2, 0.25, 0.3, 0.35, 0.4, 0.45, '
                                      '0.5, 0.55, 0.6, 0.65, 0.7, 0.75, 0.8, 0.85]'))
    proc = subprocess.Popen(_cli("sweep", "many.toml", "--out", "out", "--workers", "2"),
                            cwd=tmp_path, env=_env(), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        t0 = time.monotonic()
        log = tmp_path / "out" / "results.jsonl"
        while not (log.exists() and log.read_text().strip()):
            assert time.monotonic() - t0 < 200 and proc.poll() is None, "no point finished"
            time.sleep(0.2)
        os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "ERROR" not in err, err
    tail = [ln for ln in err.splitlines() if "interrupted" in ln]
    assert tail == [ln for ln in err.splitlines()[-1:]] and "run the same command again" in tail[0]
