"""Dask distributed for batch work: a LocalCluster of process workers on this machine by
default, or an existing cluster by its scheduler's address.

Process workers are started with ``spawn``: a script that starts a LocalCluster must
guard its entry point with ``if __name__ == "__main__":`` (the ``render-inspect``
command does).
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import logging
import os
import re
import signal
import socket
import time

from .. import __version__
from ..core.errors import InputError

__all__ = ["dask_client", "check_workers_option", "dashboard_text", "MAX_WORKERS"]

log = logging.getLogger("render_inspect")

MAX_WORKERS = 1024
#: Seconds to wait for the scheduler of an existing cluster to answer.
CONNECT_TIMEOUT_S = 15
#: Seconds to wait for at least one worker on an existing cluster.
WORKER_WAIT_S = 60
_ADDRESS = re.compile(r"^(?:(tcp|tls|inproc|ucx|ws|wss)://)?[^\s:/]+(?::\d{1,5})?$")


def check_workers_option(workers) -> int | None:
    """``--workers N``: None or an integer in [1, MAX_WORKERS]."""
    if workers is None:
        return None
    try:
        n = int(workers)
    except (TypeError, ValueError):
        n = None
    if n is None or n != workers or not 1 <= n <= MAX_WORKERS:
        raise InputError(f"--workers must be an integer in [1, {MAX_WORKERS}], got {workers!r}")
    return n


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def dashboard_text(client) -> str:
    """The dashboard's address, or why there is none."""
    try:
        import bokeh  # noqa: F401
    except ImportError:
        return "not available (install bokeh for the Dask dashboard: pip install 'render_inspect[dashboard]')"
    link = client.dashboard_link
    return link or "not available"


def _check_remote_workers(client, address: str) -> None:
    deadline = time.monotonic() + WORKER_WAIT_S
    while not client.scheduler_info().get("workers"):
        if time.monotonic() > deadline:
            raise InputError(f"--scheduler {address}: the cluster has no worker after "
                             f"{WORKER_WAIT_S} s; start some with `dask worker {address}`")
        time.sleep(0.5)
    versions = client.run(importlib.metadata.version, "render_inspect", on_error="return")
    bad = {w: v for w, v in versions.items() if v != __version__}
    if bad:
        w, v = next(iter(bad.items()))
        why = f"has render_inspect {v}" if isinstance(v, str) else "cannot import render_inspect"
        raise InputError(f"--scheduler {address}: worker {w} {why}; every worker needs "
                         f"render_inspect {__version__} (pip install render_inspect=={__version__} "
                         f"with the same extras), {len(bad)} of {len(versions)} workers differ")


@contextlib.contextmanager
def dask_client(*, scheduler: str | None = None, workers: int | None = None,
                tasks: int | None = None):
    """A ``distributed.Client``: to the cluster at ``scheduler``, or to a new LocalCluster
    of ``workers`` process workers (one thread each) on 127.0.0.1.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``).  Its workers must have the
        same version of render_inspect installed (checked).
    workers : int, optional
        Process workers of the LocalCluster; default: the CPU count, at most ``tasks``.
        Each worker's numba threads are the CPU count divided by the workers.
    tasks : int, optional
        The number of tasks to run (caps the default worker count).

    Yields
    ------
    distributed.Client
    """
    workers = check_workers_option(workers)
    if scheduler is not None and workers is not None:
        raise InputError(f"--scheduler and --workers exclude each other: the cluster at "
                         f"{scheduler} has its own workers (got --workers {workers})")
    import distributed

    if scheduler is not None:
        address = str(scheduler).strip()
        if not _ADDRESS.match(address):
            raise InputError(f"--scheduler must be a scheduler address like tcp://host:8786, "
                             f"got {scheduler!r}")
        try:
            client = distributed.Client(address, timeout=f"{CONNECT_TIMEOUT_S}s")
        except (OSError, TimeoutError) as err:
            raise InputError(f"--scheduler {address}: no Dask scheduler answered within "
                             f"{CONNECT_TIMEOUT_S} s ({type(err).__name__}); start one with "
                             f"`dask scheduler` and give its tcp:// address") from None
        try:
            _check_remote_workers(client, address)
            yield client
        finally:
            client.close()
        return
    cpus = os.cpu_count() or 1
    n = workers if workers is not None else max(1, min(cpus, tasks or cpus))
    threads = max(1, cpus // n)
    dash = "127.0.0.1:8787" if _port_free(8787) else "127.0.0.1:0"
    try:
        import bokeh  # noqa: F401
    except ImportError:
        dash = None
    env = {"NUMBA_NUM_THREADS": str(threads), "OMP_NUM_THREADS": str(threads)}
    known = set(map(id, _local_clusters()))
    try:
        cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                           host="127.0.0.1", dashboard_address=dash,
                                           silence_logs=logging.ERROR, env=env)
    except KeyboardInterrupt:  # (safety) stopped while the cluster starts
        _abandon(c for c in _local_clusters() if id(c) not in known)
        raise
    try:
        client = distributed.Client(cluster)
        try:
            yield client
        finally:
            client.close()
    except KeyboardInterrupt:
        _end_local_workers(cluster)
        raise
    finally:
        cluster.close()


def _local_clusters() -> list:
    from distributed.deploy.spec import SpecCluster

    return list(getattr(SpecCluster, "_instances", ()))


def _abandon(clusters) -> None:
    """(safety) Clusters whose start was interrupted: end their workers and forget them, so
    that nothing tries to close a half-started cluster at exit (which prints tracebacks);
    the messages of their unfinished start are not shown."""
    from distributed.deploy.spec import SpecCluster

    for name in ("asyncio", "distributed", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    for cluster in list(clusters):
        _end_local_workers(cluster)
        with contextlib.suppress(Exception):
            SpecCluster._instances.discard(cluster)


def _end_local_workers(cluster) -> None:
    """(safety) The run was stopped (Ctrl-C, SIGTERM): end the LocalCluster's worker
    processes at once instead of waiting seconds for the points they are running (a
    point's folder is written whole or not at all; the next run into the sweep's folder
    removes what a stopped point left)."""
    for nanny in list(getattr(cluster, "workers", {}).values()):
        proc = getattr(getattr(nanny, "process", None), "process", None)
        pid = getattr(proc, "pid", None)
        if pid:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGTERM)
