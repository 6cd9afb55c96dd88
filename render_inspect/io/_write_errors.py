"""Write errors of the libraries that report them as text.

OpenEXR (and other C++ writers behind Python bindings) raise a ``RuntimeError`` whose
message ends in the C library's text of the error (``Failed to write pixel data to image
file "x.exr". No space left on device.``).  :func:`write_errors` turns such an error into
the :class:`OSError` it stands for, with its errno and the file's name, so that the
output folder's clean-up and the command line report it as they report every other
write error: one line naming the file and the cause.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
import contextlib
import errno
import os

__all__ = ["write_errors", "as_os_error", "WRITE_ERRNOS"]

#: the errors a writer may meet, most specific first
WRITE_ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG, errno.EROFS, errno.EACCES,
                errno.EPERM, errno.ENOENT, errno.ENOTDIR, errno.EISDIR, errno.ENAMETOOLONG,
                errno.ELOOP, errno.EMFILE, errno.ENFILE, errno.ENOMEM)


def as_os_error(err: BaseException, path: str | Path) -> OSError | None:
    """The :class:`OSError` behind ``err`` (an OSError as it is, with ``path`` as its file
    when it names none; a library's error whose text ends in a system error's), or None."""
    if isinstance(err, OSError):
        if err.errno is not None and not err.filename:
            return OSError(err.errno, err.strerror or os.strerror(err.errno), os.fspath(path))
        return err
    text = str(err)
    for code in WRITE_ERRNOS:
        if os.strerror(code) in text:
            return OSError(code, os.strerror(code), os.fspath(path))
    return None


@contextlib.contextmanager
def write_errors(path: str | Path) -> Iterator[None]:
    """Within the block, a library's write error that stands for a system error is raised
    as that :class:`OSError` naming ``path`` (the file being written)."""
    try:
        yield
    except (RuntimeError, ValueError, OSError) as err:
        mapped = as_os_error(err, path)
        if mapped is None or mapped is err:
            raise
        raise mapped from err
