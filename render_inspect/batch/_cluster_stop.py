"""Stopping a LocalCluster when the run is stopped (Ctrl-C, SIGTERM): its workers end at
once, and a cluster whose start was interrupted is forgotten quietly."""

from __future__ import annotations

from typing import Any
from collections.abc import Iterable
import contextlib
import logging
import os
import signal

__all__ = ["local_clusters", "abandon", "end_local_workers"]


def local_clusters() -> list:
    from distributed.deploy.spec import SpecCluster

    return list(getattr(SpecCluster, "_instances", ()))


def abandon(clusters: Iterable[Any]) -> None:
    """Clusters whose start was interrupted: end their workers and forget them, so
    that nothing tries to close a half-started cluster at exit (which prints tracebacks);
    the messages of their unfinished start are not shown."""
    from distributed.deploy.spec import SpecCluster

    for name in ("asyncio", "distributed", "tornado"):
        logging.getLogger(name).setLevel(logging.CRITICAL)
    for cluster in list(clusters):
        end_local_workers(cluster)
        with contextlib.suppress(Exception):
            SpecCluster._instances.discard(cluster)


def end_local_workers(cluster: Any) -> None:
    """The run was stopped (Ctrl-C, SIGTERM): end the LocalCluster's worker
    processes at once instead of waiting seconds for the points they are running (a
    point's folder is written whole or not at all; the next run into the sweep's folder
    removes what a stopped point left)."""
    for nanny in list(getattr(cluster, "workers", {}).values()):
        proc = getattr(getattr(nanny, "process", None), "process", None)
        pid = getattr(proc, "pid", None)
        if pid:
            with contextlib.suppress(OSError):
                os.kill(pid, signal.SIGTERM)
