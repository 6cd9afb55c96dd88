"""Stopping long work when the user asks (Ctrl-C, SIGTERM).

Python runs a signal's handler in the main thread, between two steps of Python code: a
compiled kernel (numba), a long C call or a worker thread does not see it until it
returns.  So long computations run in blocks of a fraction of a second and call
:func:`check` between them (or :func:`~render_inspect.core.progress.report`, which also
moves the progress bar): the command line's handlers :func:`request` the stop, and the
next :func:`check` in any thread raises the interruption, so that every command stops
within about one block of the signal (exit 130 / 143, the output folder as it was).

>>> clear()
>>> for a, b in blocks(10, 4):   # (0, 4), (4, 8), (8, 10), with a check between
...     pass
"""

from __future__ import annotations

from collections.abc import Iterator
import contextlib
import signal
import threading
from types import FrameType

__all__ = ["Terminated", "request", "requested", "clear", "check", "blocks", "deferred",
           "deferring"]


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP): handled like Ctrl-C, the run stops and cleans up."""


_STATE: dict = {"signum": None, "deferred": 0}


def request(signum: int = signal.SIGINT) -> None:
    """Ask every long computation to stop at its next :func:`check` (``signum``: the
    signal that asked, SIGINT by default)."""
    if _STATE["signum"] is None:
        _STATE["signum"] = int(signum)


def requested() -> int | None:
    """The signal that asked to stop, or None."""
    return _STATE["signum"]


def clear() -> None:
    """Forget a request (a new run starts)."""
    _STATE["signum"] = None


def check() -> None:
    """Raise the interruption asked for (:class:`KeyboardInterrupt` for SIGINT,
    :class:`Terminated` for SIGTERM / SIGHUP), if any; in any thread."""
    signum = _STATE["signum"]
    if signum is None:
        return
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    raise Terminated(signum)


def blocks(total: int, size: int) -> Iterator[tuple[int, int]]:
    """``(start, stop)`` ranges of at most ``size`` covering ``range(total)``, with a
    :func:`check` before each."""
    size = max(int(size), 1)
    for a in range(0, int(total), size):
        check()
        yield a, min(a + size, int(total))


@contextlib.contextmanager
def deferred() -> Iterator[None]:
    """Run the block without being interrupted part-way: a stop asked for meanwhile is only
    recorded, and raised when the block ends (the command line's handlers ask
    :func:`deferring` before raising).

    For native code that calls back into Python and cannot unwind an exception raised
    there by a signal's handler: importing Mitsuba / Dr.Jit (their C++ module set-up builds
    Python enums), switching its variant, loading a scene.  An exception raised inside
    aborts the whole process (SIGABRT) instead of stopping it cleanly.  Keep such blocks
    short (they delay the stop by their length); only the main thread's blocks count, as
    the handlers run there."""
    main = threading.current_thread() is threading.main_thread()
    if main:
        _STATE["deferred"] += 1
    try:
        yield
    finally:
        if main:
            _STATE["deferred"] -= 1
    if main and not _STATE["deferred"]:
        check()


#: where libraries take or give back a lock of their own in Python code (the end of the
#: file's path -> the functions): llvmlite's lock on the LLVM library, taken for every call
#: into it (numba loading a kernel from its cache, freeing compiled code), which runs
#: numba's callbacks after taking the lock and before giving it back; numba's compiler
#: lock.  An exception raised there by a signal's handler leaves the lock held for ever,
#: and the next thread that needs it (a row thread loading its kernel) waits for ever.
_LOCK_STEPS = {
    "llvmlite/binding/ffi.py": ("__enter__", "__exit__"),
    "numba/core/compiler_lock.py": ("acquire", "release", "__enter__", "__exit__"),
}
_LOCK_STEP_NAMES = frozenset(n for names in _LOCK_STEPS.values() for n in names)


def _in_lock_step(frame: FrameType | None) -> bool:
    """Whether ``frame`` or a frame that called it is one of :data:`_LOCK_STEPS`."""
    while frame is not None:
        code = frame.f_code
        if code.co_name in _LOCK_STEP_NAMES:
            path = code.co_filename.replace("\\", "/")
            if any(path.endswith(end) and code.co_name in names
                   for end, names in _LOCK_STEPS.items()):
                return True
        frame = frame.f_back
    return False


def deferring(frame: FrameType | None = None) -> bool:
    """Whether a signal's handler should only record the stop (see :func:`request`): the
    main thread is inside a :func:`deferred` block (the stop is raised when it ends), or
    ``frame``, the code the signal interrupted, is a library taking or giving back a lock
    of its own (:data:`_LOCK_STEPS`; the stop is raised by the next :func:`check`)."""
    return _STATE["deferred"] > 0 or _in_lock_step(frame)
