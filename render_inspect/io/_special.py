"""What a path given as an input file is, when it is not a file: a named pipe (FIFO) or a
device (``/dev/zero``) would block the reader or feed it without end, and a folder is
not a file; each is refused with one line saying which, not "not found"."""

from __future__ import annotations

from pathlib import Path
import os
import stat

__all__ = ["not_a_file"]


def not_a_file(path: str | Path) -> str | None:
    """None when ``path`` is a regular file (through links); else what it is, as the end
    of a sentence: ``"not found"``, ``"is a named pipe (FIFO), not a regular file"``,
    ``"is a device, not a regular file"``, ``"is a socket, not a regular file"``, ``"is a
    folder, not a file"`` or ``"cannot be read (...)"``."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return "not found"
    except OSError as err:
        return f"cannot be read ({err.strerror or err})"
    mode = st.st_mode
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "is a folder, not a file"
    if stat.S_ISFIFO(mode):
        return "is a named pipe (FIFO), not a regular file"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "is a device, not a regular file"
    if stat.S_ISSOCK(mode):
        return "is a socket, not a regular file"
    return "is not a regular file"
