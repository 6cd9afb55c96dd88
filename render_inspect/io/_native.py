"""What a library's C code prints on its own while it reads a file, held back.

OpenEXR's C core reports a damaged file on the process's standard error itself (``file.exr:
(EXR_ERR_BAD_CHUNK_LEADER) Corrupt tile ...``) before the Python binding raises its own
error, so a damaged file would give a user two lines, one of them the library's.
:func:`library_messages` sends what is written to the standard error's file descriptor
meanwhile (and to the standard output's, where the binding prints its warnings) to
temporary files: the reader puts the library's text into its own one-line
error, and when the read succeeds the text is written out as it came (a line another thread
printed meanwhile, such as a progress bar's, is delayed; on an error it is dropped with the
library's text, which the error line quotes).
"""

from __future__ import annotations

import contextlib
import io
import os
import sys
import tempfile
import threading
from collections.abc import Iterator

from ._outdir_lock import _signals_held

__all__ = ["library_messages"]

#: at most this much of the library's text is put into an error line
_SHOWN = 300


class Held:
    """The text held back (:attr:`text`, set when the block ends)."""

    text = ""

    def summary(self) -> str:
        """The held text as the end of one line, each distinct line once: "; the library:
        ..." (empty when none)."""
        lines = list(dict.fromkeys(" ".join(ln.split()) for ln in self.text.splitlines()))
        t = " / ".join(ln for ln in lines if ln)
        if not t:
            return ""
        return f"; the library: {t if len(t) <= _SHOWN else t[:_SHOWN - 3] + '...'}"


def _flush_c_streams() -> None:
    """Flush the C library's own buffers (a library's C++ stream writes through them, and
    on a pipe they hold its text until a later flush, after the descriptors are back)."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # no C library to ask (not POSIX)
        pass


#: one read holds the streams at a time: a second thread's read meanwhile runs with the
#: streams as they are (two nested redirections could not be undone in any order)
_HOLDING = threading.Lock()


@contextlib.contextmanager
def library_messages() -> Iterator[Held]:
    """Hold back what is written to file descriptors 1 and 2 in the block, and to Python's
    ``sys.stdout`` / ``sys.stderr`` (OpenEXR's binding prints its warnings through
    Python's standard output; see the module docstring); the yielded object's ``text``
    holds it all once the block ends.  When the block ends normally the text is written out,
    each part to its own stream; on an exception it is not (the caller's error quotes it),
    so a line another thread printed meanwhile (a progress bar's) is dropped with it.  One
    block at a time holds the streams: in a second thread meanwhile the block runs with the
    streams as they are.  The streams are put back with the interruption signals held, so
    that a Ctrl-C arriving then cannot leave them redirected."""
    held = Held()
    if not _HOLDING.acquire(blocking=False):
        yield held
        return
    try:
        with _redirected(held):
            yield held
    finally:
        _HOLDING.release()


@contextlib.contextmanager
def _redirected(held: Held) -> Iterator[None]:
    streams = ((1, sys.stdout), (2, sys.stderr))
    saved: list[int] = []
    with _signals_held():
        try:
            for fd, stream in streams:
                stream.flush()
                saved.append(os.dup(fd))
        except (OSError, ValueError, AttributeError):  # no such stream to redirect
            for s in saved:
                os.close(s)
            saved = []
    if not saved:
        yield
        return
    ok = False
    py = (io.StringIO(), io.StringIO())
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        tmps = (out, err)
        try:
            with _signals_held():
                for (fd, _), tmp in zip(streams, tmps):
                    os.dup2(tmp.fileno(), fd)
                sys.stdout, sys.stderr = py
            yield
            ok = True
        finally:
            with _signals_held():
                sys.stdout, sys.stderr = streams[0][1], streams[1][1]
                _flush_c_streams()
                for (fd, _), s in zip(streams, saved):
                    os.dup2(s, fd)
                    os.close(s)
            texts = []
            for (_, stream), tmp, mine in zip(streams, tmps, py):
                tmp.seek(0)
                text = mine.getvalue() + tmp.read().decode("utf-8", "replace")
                texts.append(text)
                if ok and text:
                    stream.write(text)
                    stream.flush()
            held.text = "".join(texts)
