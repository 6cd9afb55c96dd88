"""One OpenBLAS thread for a block of products and solves of a few columns.

OpenBLAS (numpy's and SciPy's, each its own library) runs a product or a factorisation of
a tall matrix of a few columns (a registration's Jacobian: points x 6) on one thread per
core.  Such a product is short, and its threads wait for one another at every step: on a
machine whose cores are busy with other work each wait lasts until the scheduler runs the
other thread again, and the work takes longer than on one thread (docs/performance.md).
:func:`one_blas_thread` sets every OpenBLAS loaded in the process to one thread while a
block runs, and back to its count after it.  The products are the same, and so are their
numbers (each element is still summed in one thread's order).

The libraries are found among the process's mapped files (``/proc/self/maps``, Linux);
where there is no such list, or no OpenBLAS, or one without the thread switch, the block
runs as it is.  Only the standard library is imported here.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Callable, Iterator
from typing import Any

__all__ = ["one_blas_thread", "blas_threads"]

#: the name prefixes and suffixes OpenBLAS builds give their functions (SciPy's wheels
#: ``scipy_``, numpy's 64-bit-integer build ``64_``)
_PREFIXES = ("", "scipy_")
_SUFFIXES = ("", "64_", "_64")

_LOCK = threading.Lock()
# path -> (get, set) of each OpenBLAS met so far (None: a library without the switch)
_FOUND: dict[str, tuple[Callable[[], int], Callable[[int], Any]] | None] = {}
# the number of imported modules when the mapped files were last read
_SCANNED = {"modules": -1}
# blocks running now, and the counts to set back when the last one ends
_DEPTH = 0
_SAVED: list[tuple[Callable[[int], Any], int]] = []


def _mapped_openblas() -> list[str]:
    """The files of the OpenBLAS libraries mapped in this process (none where the process
    has no ``/proc/self/maps``)."""
    paths = []
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
            for line in fh:
                path = line.rsplit(None, 1)[-1] if "/" in line else ""
                if "openblas" in os.path.basename(path).lower() and path not in paths:
                    paths.append(path)
    except OSError:
        return []
    return paths


def _switch(path: str) -> tuple[Callable[[], int], Callable[[int], Any]] | None:
    """The thread count's getter and setter of the OpenBLAS at ``path`` (already loaded:
    it is not loaded again), or None."""
    import ctypes

    try:
        lib = ctypes.CDLL(path, mode=getattr(os, "RTLD_NOLOAD", 0) | ctypes.RTLD_LOCAL)
    except OSError:
        return None
    for pre in _PREFIXES:
        for suf in _SUFFIXES:
            get = getattr(lib, f"{pre}openblas_get_num_threads{suf}", None)
            put = getattr(lib, f"{pre}openblas_set_num_threads{suf}", None)
            if get is not None and put is not None:
                get.restype, get.argtypes = ctypes.c_int, ()
                put.restype, put.argtypes = None, (ctypes.c_int,)
                return get, put
    return None


def _switches() -> list[tuple[Callable[[], int], Callable[[int], Any]]]:
    """The switches of the OpenBLAS libraries loaded so far.  The mapped files are read
    again only after a module was imported (an OpenBLAS is loaded by the extension module
    that links it), not at every block: a registration's blocks come one after another."""
    modules = len(sys.modules)
    if modules != _SCANNED["modules"]:
        for path in _mapped_openblas():
            if path not in _FOUND:
                _FOUND[path] = _switch(path)
        _SCANNED["modules"] = modules
    return [s for s in _FOUND.values() if s is not None]


def blas_threads() -> list[int]:
    """The thread count of each OpenBLAS loaded in the process (empty where none is
    found)."""
    with _LOCK:
        return [get() for get, _ in _switches()]


@contextlib.contextmanager
def one_blas_thread() -> Iterator[None]:
    """Run the block (or, as a decorator, the function) with every loaded OpenBLAS on one
    thread; their counts are set back when the last such block of the process ends."""
    global _DEPTH
    with _LOCK:
        if _DEPTH == 0:
            _SAVED[:] = [(put, get()) for get, put in _switches()]
            for put, n in _SAVED:
                if n > 1:
                    put(1)
        _DEPTH += 1
    try:
        yield
    finally:
        with _LOCK:
            _DEPTH -= 1
            if _DEPTH == 0:
                for put, n in _SAVED:
                    if n > 1:
                        put(n)
                _SAVED.clear()
