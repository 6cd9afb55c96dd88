"""The heap of a Dask worker while one of the package's tasks runs on it.

A Dask nanny starts its workers (a LocalCluster's, ``--workers``) with
``MALLOC_TRIM_THRESHOLD_`` in their environment, and a threshold set that way also fixes
glibc's mmap threshold at 128 KiB: every array over it is mapped afresh and faults its
pages in again.  A fit's evaluation of a map took 1.6 times the CPU there that it takes
in one process (the extra time spent in the system).  While a task runs, arrays come from
the heap (as glibc's own rule has them in a process started without the variable);
after it, the worker's thresholds are set back to what its environment says and the
freed memory is given back (``malloc_trim``).  The same numbers either way; a process
without the variable, or another C library, is left as it is.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
from collections.abc import Iterator

__all__ = ["heap_kept"]

#: glibc's mallopt parameters (malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: the thresholds a task on a worker runs with: arrays up to 32 MiB from the heap, freed
#: memory kept up to 64 MiB (where glibc's own dynamic rule ends)
_TASK_HEAP = ((_M_MMAP_THRESHOLD, 32 << 20), (_M_TRIM_THRESHOLD, 64 << 20))
#: glibc's mmap threshold where the environment sets none (128 KiB)
_GLIBC_MMAP_THRESHOLD = 128 << 10


@contextlib.contextmanager
def heap_kept() -> Iterator[None]:
    """Within the block, arrays from the heap where the process was started with
    ``MALLOC_TRIM_THRESHOLD_`` (a Dask worker); after it, the environment's thresholds
    again and the freed memory given back.  Nothing where the variable is not set."""
    env = os.environ.get("MALLOC_TRIM_THRESHOLD_")
    libc = None
    after: tuple[tuple[int, int], ...] = ()
    if env is not None:
        with contextlib.suppress(OSError, AttributeError, ValueError):
            after = ((_M_TRIM_THRESHOLD, int(env)),
                     (_M_MMAP_THRESHOLD, int(os.environ.get("MALLOC_MMAP_THRESHOLD_",
                                                            _GLIBC_MMAP_THRESHOLD))))
            libc = ctypes.CDLL("libc.so.6")
            for p, v in _TASK_HEAP:
                libc.mallopt(p, v)
    try:
        yield
    finally:
        if libc is not None:
            for p, v in after:
                libc.mallopt(p, v)
            libc.malloc_trim(0)
