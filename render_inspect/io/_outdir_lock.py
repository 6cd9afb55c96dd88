"""Output folders, locking: an exclusive lock beside the folder (``.NAME.lock``,
``flock``) so that a second run into it fails at once, and the interruptions (SIGINT,
SIGTERM, SIGHUP) held back while the folder is swapped or cleaned up."""

from __future__ import annotations

import contextlib
import errno
import os
import signal
import stat
import threading
from pathlib import Path

from ..core.errors import InputError
from ._atomic_write import _umask
from ._outdir_names import _LOCK_MAX, _shown

__all__ = ["open_lock_file"]


_HELD_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP")
                      if hasattr(signal, n))


def _deliver(signum: int, handler) -> None:
    """Deliver a signal that was held back to the handler it would have reached."""
    if handler is signal.SIG_IGN:
        return
    if callable(handler):
        handler(signum, None)
        return
    if signum == signal.SIGINT:
        raise KeyboardInterrupt
    os.kill(os.getpid(), signum)  # the default action: end the process


@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT, SIGTERM and SIGHUP back while a block runs (the swap, the clean-up).

    Their handlers are replaced by one that only notes the signal; when the block ends
    the handlers are restored and the first noted signal goes to its handler then (an
    exception from the block wins).  Replacing the handlers, not masking the signals,
    is what holds them back in a process with several threads: a masked signal is
    delivered to another thread, and Python then runs its handler in the main thread at
    once.  Outside the main thread (where Python runs no handler) the block runs as it is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    noted: list[int] = []

    def note(signum, frame):
        noted.append(signum)

    old = {}
    try:
        for sig in _HELD_SIGNALS:
            try:
                old[sig] = signal.signal(sig, note)
            except (ValueError, OSError):
                pass
        yield
    finally:
        for sig, handler in old.items():
            with contextlib.suppress(ValueError, OSError, TypeError):
                signal.signal(sig, handler if handler is not None else signal.SIG_DFL)
    if noted:
        _deliver(noted[0], old.get(noted[0]))



def open_lock_file(path: str | Path, *, option: str = "--out", out_text: str | None = None) -> int:
    """Open (creating it) the lock file ``path`` for ``flock`` and return the descriptor,
    without following a symbolic link and without blocking on a pipe: a link, a hard
    link to another file, a device or pipe, or a file holding more than a process id
    under that name is refused with one line naming ``option`` (it is never truncated or
    written through)."""
    path = Path(path)
    out_text = str(path.parent) if out_text is None else out_text
    flags = os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | getattr(os, "O_NOFOLLOW", 0) \
        | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags, 0o666 & ~_umask() | 0o600)
    except OSError as err:
        if err.errno in (errno.ELOOP, errno.EMLINK) or os.path.islink(path):
            raise InputError(f"{option} {_shown(out_text)}: {str(path)!r} is a symbolic link, "
                             f"not render-inspect's lock file; remove it (the lock is never "
                             f"written through a link)") from None
        raise InputError(f"{option} {_shown(out_text)}: cannot write in {str(path.parent)!r} "
                         f"({err.strerror})") from None
    try:
        st = os.fstat(fd)
        why = None
        if not stat.S_ISREG(st.st_mode):
            why = "is not a regular file"
        elif st.st_nlink != 1:
            why = f"is a hard link ({st.st_nlink} names for one file)"
        elif st.st_size > _LOCK_MAX:
            why = f"holds {st.st_size} bytes, not a process id"
        else:
            text = os.pread(fd, _LOCK_MAX + 1, 0).strip()
            if text and not text.isdigit():
                why = "holds something other than a process id"
        if why:
            raise InputError(f"{option} {_shown(out_text)}: {str(path)!r} {why}, so it is not "
                             f"render-inspect's lock file; move it away (it is never "
                             f"truncated or written)")
    except BaseException:
        os.close(fd)
        raise
    return fd


class _Lock:
    """An exclusive ``flock`` on ``.NAME.lock`` beside the output folder (released by the
    kernel if the process dies).

    The lock file is opened without following a symbolic link (``O_NOFOLLOW``) and must
    be a regular file with one name that holds at most a process id: a link, a hard link
    to another file, a device or a file with other content planted under that name is
    refused, never truncated or written through."""

    def __init__(self, path: Path, out_text: str, option: str):
        import fcntl

        self.path = path
        while True:
            fd = open_lock_file(path, option=option, out_text=out_text)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as err:
                holder = ""
                with contextlib.suppress(OSError, ValueError):
                    txt = os.pread(fd, 64, 0).decode().strip()
                    if txt.isdigit():
                        holder = f" (process {txt})"
                os.close(fd)
                if err.errno in (errno.EWOULDBLOCK, errno.EACCES, errno.EAGAIN):
                    raise InputError(f"{option} {_shown(out_text)} is being written by another "
                                     f"render-inspect run{holder}; wait for it to finish or "
                                     f"choose another folder") from None
                raise InputError(f"{option} {_shown(out_text)}: cannot lock {str(path)!r} "
                                 f"({err.strerror})") from None
            # the file may have been removed and re-created by the previous holder
            try:
                same = os.path.samestat(os.fstat(fd), os.lstat(path))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        self.fd = fd
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)

    def release(self):
        if self.fd is None:
            return
        with contextlib.suppress(OSError):
            if os.path.samestat(os.fstat(self.fd), os.lstat(self.path)):
                os.unlink(self.path)
        with contextlib.suppress(OSError):
            os.close(self.fd)
        self.fd = None
