"""Dask for batch work: the one place a command gets its ``distributed.Client``.

:func:`dask_client` gives, in this order of preference:

1. the client the caller passes (``client=``: a ``distributed.Client`` of a notebook or a
   script, used as it is and left open);
2. the cluster whose scheduler listens at ``scheduler`` (``--scheduler tcp://host:8786``):
   the address is probed first with a bounded time and a bounded read, so that an
   endpoint that is not a Dask scheduler (or does not answer) is one clear error within
   :data:`CONNECT_TIMEOUT_S`; a cluster with no worker after :data:`WORKER_WAIT_S` is
   another; every worker must run the same version of render_inspect (checked);
3. the client already open in this process (``distributed.get_client()`` in a notebook),
   when ``use_open_client``;
4. a new ``LocalCluster`` of process workers on 127.0.0.1, with the dashboard (when
   bokeh is installed), Dask's own memory management (each worker's memory limit is its
   share of the memory budget: Dask pauses a worker near it and restarts one beyond it),
   and as many workers as fit: ``--workers`` (default the CPU count), at most the CPU
   count, the tasks to run and the memory budget divided by a task's estimate
   (:func:`plan_workers`; the log says which limit applied).

Each task that computes with numba runs through :func:`call_with_threads`, which sets
its numba thread count (the CPU count divided by the LocalCluster's workers): the count is
set inside the task, never through ``NUMBA_NUM_THREADS`` in the workers' environment
(numba reads that variable once, when it is imported; a different value set later makes
every later compilation in that worker fail).

A LocalCluster's workers ignore Ctrl-C (the command that started them handles it and shuts
them down), and the shutdown after an interruption is quiet: one line, no tracebacks of
Dask's own.

Process workers are started with ``spawn``: a script that starts a LocalCluster must
guard its entry point with ``if __name__ == "__main__":`` (the ``render-inspect``
command does).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Callable, Iterator
import contextlib
import importlib.metadata
import logging
import os
import re
import signal
import socket
import struct
import threading
import time
import weakref

from .. import __version__
from ..core.errors import InputError
from ..core.limits import format_bytes, memory_budget
from ..core.units import MIB_TO_BYTES
from ._cluster_stop import abandon, end_local_workers, local_clusters
from ._worker_heap import heap_kept

__all__ = ["dask_client", "check_workers_option", "dashboard_text", "MAX_WORKERS",
           "plan_workers", "cluster_info", "call_with_threads", "wait_for_workers",
           "CONNECT_TIMEOUT_S", "WORKER_WAIT_S", "WORKER_BASE_BYTES", "open_client",
           "check_scheduler"]

log = logging.getLogger("render_inspect")

#: the largest ``--workers`` accepted at all (the count actually started is capped
#: further by :func:`plan_workers`)
MAX_WORKERS = 1024
#: seconds to wait for the scheduler of an existing cluster to answer
CONNECT_TIMEOUT_S = 15
#: seconds to wait for at least one worker on an existing cluster
WORKER_WAIT_S = 30
#: memory of one idle worker process with render_inspect's modules imported (measured:
#: 230 - 260 MB resident on the two-core CI machine, numba, scipy and zarr loaded)
WORKER_BASE_BYTES = 256 * MIB_TO_BYTES
#: the largest first message a scheduler's handshake can plausibly be (bytes)
_HANDSHAKE_MAX = 1 << 16
_ADDRESS = re.compile(r"^(?:(tcp|tls|inproc|ucx|ws|wss)://)?[^\s:/]+(?::\d{1,5})?$")
_START = "start one with `dask scheduler` and give its tcp:// address"
_QUIET_LOGGERS = ("distributed", "tornado", "asyncio", "bokeh")
#: what :func:`cluster_info` knows about each client this module handed out
_INFO: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def check_workers_option(workers: Any) -> int | None:
    """``--workers N``: None or an integer in [1, MAX_WORKERS]."""
    if workers is None:
        return None
    try:
        n = int(workers)
    except (TypeError, ValueError):
        n = None
    if n is None or isinstance(workers, bool) or n != workers or not 1 <= n <= MAX_WORKERS:
        raise InputError(f"--workers must be an integer in [1, {MAX_WORKERS}], got {workers!r}")
    return n


def plan_workers(requested: int | None, *, tasks: int | None = None,
                 memory_per_task: float | None = None, cpus: int | None = None,
                 budget: tuple[int, str] | None = None) -> tuple[int, list[str]]:
    """How many process workers a LocalCluster gets, and why not more.

    ``requested`` (default: the CPU count) capped by the CPU count (the workers compute,
    more of them than cores only share the cores and add memory), by ``tasks`` (a worker
    without a task does nothing) and by the memory budget divided by what one worker
    holds (:data:`WORKER_BASE_BYTES` plus ``memory_per_task``).

    Returns
    -------
    (n, reasons)
        ``reasons`` says, for each limit that cut the count, which one and why (empty when
        the request stands).
    """
    cpus = int(cpus or os.cpu_count() or 1)
    asked = int(requested) if requested is not None else cpus
    n = asked
    reasons = []
    if n > cpus:
        n = cpus
        reasons.append(f"{cpus} CPU cores")
    if tasks is not None and n > max(int(tasks), 1):
        n = max(int(tasks), 1)
        reasons.append(f"{int(tasks)} task{'s' if int(tasks) != 1 else ''} to run")
    if memory_per_task is not None:
        limit, source = budget if budget is not None else memory_budget(None)
        per = WORKER_BASE_BYTES + max(float(memory_per_task), 0.0)
        fit = max(int(limit // per), 1)
        if n > fit:
            n = fit
            reasons.append(f"the memory budget of {format_bytes(limit)} ({source}) holds "
                           f"{fit} worker{'s' if fit != 1 else ''} of about {format_bytes(per)}")
    return max(n, 1), reasons


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def _has_bokeh() -> bool:
    try:
        import bokeh  # noqa: F401
    except ImportError:
        return False
    return True


def dashboard_text(client: Any) -> str:
    """The dashboard's address, or why there is none."""
    if not _has_bokeh():
        return "not available (install bokeh for the Dask dashboard: pip install 'render_inspect[dashboard]')"
    try:
        link = client.dashboard_link
    except Exception:  # a client whose scheduler reports no dashboard
        link = None
    return link or "not available"


def cluster_info(client: Any) -> dict:
    """What :func:`dask_client` knows of ``client``: ``kind`` ("local", "scheduler",
    "client"), ``workers`` (started or found), ``threads`` (numba threads per task, None
    when the cluster's own), ``dashboard``, ``address``, ``capped`` (why fewer workers
    than asked)."""
    if client is None:
        return {"kind": "threads", "workers": None, "threads": None, "dashboard": None,
                "address": None, "capped": []}
    return dict(_INFO.get(client, {"kind": "client", "workers": None, "threads": None,
                                   "dashboard": None, "address": None, "capped": []}))


def call_with_threads(threads: int | None, fn: Callable[..., Any], *args: Any,
                      **kwargs: Any) -> Any:
    """``fn(*args, **kwargs)`` with numba's thread count set to ``threads`` for this task
    (at most the threads numba started with; unchanged when None), and on a Dask worker its
    arrays kept on the heap while it runs (:func:`heap_kept`)."""
    if threads:
        import numba

        numba.set_num_threads(max(1, min(int(threads), int(numba.config.NUMBA_NUM_THREADS))))
    with heap_kept():
        return fn(*args, **kwargs)


# ------------------------------------------------------------------ existing clusters
def _read_exact(sock: socket.socket, n: int, deadline: float) -> bytes:
    buf = bytearray()
    while len(buf) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError
        sock.settimeout(left)
        chunk = sock.recv(n - len(buf))
        if not chunk:
            raise ConnectionError("closed")
        buf += chunk
    return bytes(buf)


def _probe_tcp(host: str, port: int, timeout: float) -> str | None:
    """What is wrong with the endpoint (None when a Dask scheduler answers there): connect
    and read its handshake (a scheduler sends one at once) with a deadline and a bounded
    size."""
    deadline = time.monotonic() + timeout
    silent = f"no Dask scheduler answered within {timeout:g} s"
    try:
        sock = socket.create_connection((host, port), timeout=timeout)
    except socket.timeout:
        return f"{silent} (the connection was not accepted)"
    except OSError as err:
        return f"no Dask scheduler answered (cannot connect: {err.strerror or err})"
    except (UnicodeError, ValueError, OverflowError) as err:  # a host name the resolver refuses
        return f"no Dask scheduler answered (cannot connect: {type(err).__name__}: {err})"
    foreign = "not a Dask scheduler: it answered with data that is not Dask's protocol"
    with sock:
        try:
            (total,) = struct.unpack("<Q", _read_exact(sock, 8, deadline))
            if not 16 <= total <= _HANDSHAKE_MAX:
                return f"{foreign} (a first message of {total} bytes)"
            body = _read_exact(sock, total, deadline)
        except TimeoutError:
            return f"{silent} (it accepted the connection but sent no handshake)"
        except (ConnectionError, OSError):
            return "not a Dask scheduler: it closed the connection without a handshake"
    (nframes,) = struct.unpack_from("<Q", body)
    if not 1 <= nframes <= 64 or 8 * (nframes + 1) > len(body):
        return foreign
    lengths = struct.unpack_from(f"<{nframes}Q", body, 8)
    if sum(lengths) + 8 * (nframes + 1) != len(body) or b"pickle-protocol" not in body:
        return foreign
    return None


def _scheduler_address(scheduler) -> str:
    address = str(scheduler).strip()
    m = _ADDRESS.match(address)
    host_port = address.partition("://")[2] if "://" in address else address
    host, _, port = host_port.rpartition(":") if ":" in host_port else (host_port, "", "")
    if not m or len(host or host_port) > 253 or (port and not 1 <= int(port) <= 65535):
        raise InputError(f"--scheduler must be a scheduler address like tcp://host:8786 (a host "
                         f"name of at most 253 characters, a port in 1 .. 65535), got "
                         f"{str(scheduler)[:80]!r}")
    return address if "://" in address else f"tcp://{address}"


def check_scheduler(scheduler: str) -> str:
    """The address of ``--scheduler`` (``tcp://`` added when no scheme is given), after
    checking, within :data:`CONNECT_TIMEOUT_S` and without reading more than a handshake,
    that a Dask scheduler answers there (TCP addresses; others are checked on connecting).
    Anything else is an :class:`InputError` saying what answered."""
    address = _scheduler_address(scheduler)
    scheme, _, rest = address.partition("://")
    if scheme == "tcp":
        host, _, port = rest.rpartition(":")
        if not host:
            host, port = rest, "8786"
        why = _probe_tcp(host.strip("[]"), int(port), CONNECT_TIMEOUT_S)
        if why is not None:
            raise InputError(f"--scheduler {address}: {why}; {_START}")
    return address


def _connect(address: str):
    import distributed

    check_scheduler(address)
    # Dask's own connection has a deadline for connecting, none for the handshake after
    # it (an endpoint that accepts and stays silent): the client is made in a thread that
    # is given up on after the deadline
    box: dict = {}

    def make():
        try:
            box["client"] = distributed.Client(address, timeout=f"{CONNECT_TIMEOUT_S}s",
                                               set_as_default=False)
        except BaseException as err:  # handed to the caller below
            box["error"] = err

    t = threading.Thread(target=make, name="render-inspect-connect", daemon=True)
    t.start()
    t.join(CONNECT_TIMEOUT_S + 5)
    err = box.get("error")
    if "client" in box:
        return box["client"]
    if err is None or isinstance(err, (OSError, TimeoutError, ValueError, MemoryError)):
        why = type(err).__name__ if err is not None else "no handshake"
        raise InputError(f"--scheduler {address}: no Dask scheduler answered within "
                         f"{CONNECT_TIMEOUT_S} s ({why}); {_START}") from None
    raise err


def wait_for_workers(client: Any, *, label: str, n: int | None = None,
                     timeout: float | None = None, hint: str | None = None) -> int:
    """Wait until the cluster has ``n`` workers (default: at least one); returns how many
    it has.  A cluster that has none after ``timeout`` (:data:`WORKER_WAIT_S`) is an
    :class:`InputError` saying how to start some (``hint``)."""
    timeout = WORKER_WAIT_S if timeout is None else timeout
    want = max(int(n or 1), 1)
    deadline = time.monotonic() + timeout
    while True:
        have = len(client.scheduler_info().get("workers") or {})
        if have >= want:
            return have
        if time.monotonic() > deadline:
            if have:
                return have
            addr = getattr(client.scheduler, "address", "the scheduler")
            raise InputError(f"{label}: the Dask cluster at {addr} has no worker after "
                             f"{timeout:g} s; " + (hint or f"start some with `dask worker {addr}`"))
        time.sleep(0.2)


def _check_versions(client, label: str) -> None:
    versions = client.run(importlib.metadata.version, "render_inspect", on_error="return")
    bad = {w: v for w, v in versions.items() if v != __version__}
    if bad:
        w, v = next(iter(bad.items()))
        why = f"has render_inspect {v}" if isinstance(v, str) else "cannot import render_inspect"
        raise InputError(f"{label}: worker {w} {why}; every worker needs render_inspect "
                         f"{__version__} (pip install render_inspect=={__version__} with the same "
                         f"extras), {len(bad)} of {len(versions)} workers differ")


def open_client() -> Any:
    """The ``distributed.Client`` open in this process (a notebook's), or None."""
    try:
        from distributed import default_client
    except ImportError:
        return None
    try:
        c = default_client()
    except ValueError:
        return None
    return c if getattr(c, "status", "") in ("running", "connecting", "newly-created") else None


# ------------------------------------------------------------------ Ctrl-C
def _ignore_sigint() -> None:
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


_PLUGIN = None


def _plugin():
    """A worker plugin: the LocalCluster's workers ignore SIGINT (Ctrl-C reaches every
    process of the terminal's group; the command that started them shuts them down)."""
    global _PLUGIN
    if _PLUGIN is None:
        from distributed import WorkerPlugin

        class IgnoreInterrupt(WorkerPlugin):
            name = "render-inspect-ignore-sigint"
            idempotent = True

            def setup(self, worker):
                _ignore_sigint()

        _PLUGIN = IgnoreInterrupt
    return _PLUGIN()


class _QuietFilter(logging.Filter):
    """Drops Dask's (and its libraries') log records once an interruption has arrived."""

    def __init__(self):
        super().__init__()
        self.on = False

    def filter(self, record) -> bool:
        return not (self.on and any(record.name == q or record.name.startswith(q + ".")
                                    for q in _QUIET_LOGGERS))


@contextlib.contextmanager
def _quiet_interrupts():
    """While the block runs, the first SIGINT or SIGTERM silences Dask's own log records
    (the connections an interruption cancels print no tracebacks) and then does what it
    did before (Ctrl-C: KeyboardInterrupt); a second one while the cluster shuts down is
    ignored, so that the shutdown is not itself interrupted half-way.  The handler takes
    no lock (it sets a flag that a logging filter reads)."""
    import signal
    import threading

    import distributed  # noqa: F401  (its loggers and their handlers exist from here on)

    quiet = _QuietFilter()
    targets = [logging.getLogger(n) for n in
               set(_QUIET_LOGGERS) | {n for n in list(logging.root.manager.loggerDict)
                                      if any(n.startswith(q + ".") for q in _QUIET_LOGGERS)}]
    # a record propagates to its parents' handlers past their loggers' filters: the
    # handlers get the filter too
    targets += [h for lg in list(targets) for h in lg.handlers] + list(logging.root.handlers)
    for t in targets:
        t.addFilter(quiet)
    old = {}

    def handler(signum, frame):
        if quiet.on:
            return  # the shutdown after the first interruption goes on
        quiet.on = True
        return old[signum](signum, frame)

    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            prev = signal.getsignal(sig)
            if callable(prev):
                old[sig] = prev
                signal.signal(sig, handler)
    try:
        yield
    except KeyboardInterrupt:
        quiet.on = True
        raise
    finally:
        for sig, prev in old.items():
            with contextlib.suppress(ValueError, TypeError):
                signal.signal(sig, prev)
        for t in targets:
            t.removeFilter(quiet)


@contextlib.contextmanager
def _local_cluster(n: int, threads: int, *, memory_limit: int, wait: bool, capped):
    import distributed

    dash = None
    if _has_bokeh():
        dash = "127.0.0.1:8787" if _port_free(8787) else "127.0.0.1:0"
    # the cluster's event-loop thread, which spawns the worker processes, starts with
    # SIGINT blocked: the workers inherit the blocked signal through fork and exec, so
    # Ctrl-C (sent to every process of the terminal's group) reaches only this process,
    # which shuts them down; this thread's mask is restored at once
    main = threading.current_thread() is threading.main_thread()
    if main:
        # multiprocessing's resource tracker, started with the first process, unblocks
        # SIGINT in the thread that starts it: started here first, it leaves the mask be
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if main else None
    try:
        # the workers' own log lines (heartbeats to a scheduler that is shutting down,
        # connections it closes) are not shown: what fails comes back with its task
        known = set(map(id, local_clusters()))
        try:
            cluster = distributed.LocalCluster(n_workers=0, threads_per_worker=1, processes=True,
                                               host="127.0.0.1", dashboard_address=dash,
                                               silence_logs=logging.CRITICAL,
                                               memory_limit=memory_limit)
        except KeyboardInterrupt:  # stopped while the cluster starts
            abandon(c for c in local_clusters() if id(c) not in known)
            raise
    finally:
        if mask is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    try:
        client = distributed.Client(cluster, set_as_default=False)
        try:
            client.register_plugin(_plugin())
            cluster.scale(n)
            client.expected_workers = n  # type: ignore[attr-defined]  # (read by wait_for_workers)
            _INFO[client] = {"kind": "local", "workers": n, "threads": threads,
                             "dashboard": dashboard_text(client),
                             "address": cluster.scheduler_address, "capped": list(capped),
                             "memory_limit_bytes": memory_limit}
            if wait:
                wait_for_workers(client, label="--workers", n=n, timeout=max(WORKER_WAIT_S, 60),
                                 hint="the workers of the LocalCluster did not start (see the "
                                      "messages above; try fewer --workers)")
            yield client
        finally:
            client.close()
    except KeyboardInterrupt:
        end_local_workers(cluster)
        raise
    finally:
        cluster.close()


@contextlib.contextmanager
def dask_client(*, client: Any = None, scheduler: str | None = None, workers: int | None = None,
                tasks: int | None = None, memory_per_task: float | None = None,
                wait: bool = True, use_open_client: bool = True,
                budget: tuple[int, str] | None = None,
                label: str | None = None) -> Iterator[Any]:
    """A ``distributed.Client`` for batch work (see the module notes for which one).

    Parameters
    ----------
    client : distributed.Client, optional
        Use this client (left open at the end).
    scheduler : str, optional
        Address of a running scheduler (``tcp://host:8786``).  Its workers must have the
        same version of render_inspect installed (checked).
    workers : int, optional
        Process workers of a new LocalCluster (default: the CPU count); capped by
        :func:`plan_workers` (the log says why).
    tasks : int, optional
        The number of tasks to run (caps the workers).
    memory_per_task : float, optional
        Bytes one task holds at its peak (caps the workers to what the memory budget holds).
    wait : bool
        Wait for a new LocalCluster's workers before returning (otherwise they start in
        the background: :func:`wait_for_workers` before the first task).
    use_open_client : bool
        Use the client open in this process (a notebook's) when none of ``client``,
        ``scheduler`` and ``workers`` is given.
    budget : (bytes, source), optional
        The memory budget (default: the automatic one).
    label : str, optional
        How messages name the cluster (default ``--scheduler ADDRESS`` / ``--workers``).

    Yields
    ------
    distributed.Client
        :func:`cluster_info` tells what it is (workers, numba threads per task, dashboard).
    """
    workers = check_workers_option(workers)
    given = [name for name, v in (("client", client), ("--scheduler", scheduler),
                                  ("--workers", workers)) if v is not None]
    if len(given) > 1:
        raise InputError(f"{' and '.join(given)} exclude each other: give one of them (a "
                         f"cluster that is running has its own workers)")
    if client is not None:
        try:
            from distributed import Client
        except ImportError:  # pragma: no cover - distributed is a dependency
            Client = ()  # type: ignore[misc, assignment]
        if not isinstance(client, Client):
            raise InputError(f"client must be a distributed.Client, got {type(client).__name__}")
    if client is None and scheduler is None and workers is None and use_open_client:
        client = open_client()
        if client is not None:
            log.info("using the Dask client open in this process (scheduler %s)",
                     getattr(client.scheduler, "address", "?"))
    with _quiet_interrupts():
        if client is not None:
            lab = label or "client"
            wait_for_workers(client, label=lab)
            _check_versions(client, lab)
            nw = len(client.scheduler_info().get("workers") or {})
            _INFO[client] = {"kind": "client", "workers": nw, "threads": None,
                             "dashboard": dashboard_text(client),
                             "address": getattr(client.scheduler, "address", None), "capped": []}
            yield client
            return
        if scheduler is not None:
            address = _scheduler_address(scheduler)
            lab = label or f"--scheduler {address}"
            c = _connect(address)
            try:
                nw = wait_for_workers(c, label=lab)
                _check_versions(c, lab)
                _INFO[c] = {"kind": "scheduler", "workers": nw, "threads": None,
                            "dashboard": dashboard_text(c), "address": address, "capped": []}
                yield c
            finally:
                c.close()
            return
        cpus = os.cpu_count() or 1
        limit = budget if budget is not None else memory_budget(None)
        n, capped = plan_workers(workers, tasks=tasks, memory_per_task=memory_per_task,
                                 cpus=cpus, budget=limit)
        if capped:
            asked = workers if workers is not None else cpus
            log.info("Dask: %d worker%s (%s %d; capped by %s)", n, "s" if n != 1 else "",
                     "asked for" if workers is not None else "by default", asked,
                     "; ".join(capped))
        threads = max(1, cpus // n)
        memory_limit = max(int(limit[0] // n), WORKER_BASE_BYTES)
        with _local_cluster(n, threads, memory_limit=memory_limit, wait=wait,
                            capped=capped) as c:
            yield c
