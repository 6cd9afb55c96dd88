"""Output folders, the swap: the complete folder put in place in one rename (exchanged
atomically where the file system allows it, else through a backup deleted only after the
new folder is in place), the folders swapped in by this process, and the hard links that
keep other commands' files in a merged folder."""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import shutil
from pathlib import Path

__all__ = ["completed_outputs"]

#: output folders swapped in by this process: (time.monotonic(), folder)
_COMPLETED: list[tuple[float, str]] = []


def completed_outputs(since: float = 0.0) -> list[str]:
    """The output folders :func:`atomic_output_dir` swapped in (complete) in this process
    since ``since`` (a :func:`time.monotonic` time), oldest first: what a command stopped
    by an interruption after writing its folder reports as written."""
    return [f for t, f in _COMPLETED if t >= since]


_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically (Linux ``renameat2``); False when not supported here."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        fn = libc.renameat2
    except (OSError, AttributeError):
        return False
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    e = ctypes.get_errno()
    if e in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EPERM):
        return False
    raise OSError(e, os.strerror(e), str(b))


def _rmtree(path: Path) -> None:
    shutil.rmtree(path, ignore_errors=True)
    if path.exists() or path.is_symlink():
        with contextlib.suppress(OSError):
            path.unlink()


def _swap_in(new: Path, out: Path, backup: Path) -> None:
    """Put the complete folder ``new`` at ``out``; the old ``out`` (if any) is deleted
    only after the new one is in place."""
    if not out.exists():
        try:
            os.rename(new, out)
            return
        except OSError as err:
            if err.errno not in (errno.ENOTEMPTY, errno.EEXIST):
                raise
        # a folder appeared meanwhile: fall through to the swap
    if _exchange(new, out):
        _rmtree(new)  # holds the old content now
        return
    os.rename(out, backup)
    try:
        os.rename(new, out)
    except BaseException:
        os.rename(backup, out)
        raise
    _rmtree(backup)


def _link_file(src: str | Path, dst: str | Path) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _link_or_copy(src: Path, dst: Path) -> None:
    """Hard-link ``src`` at ``dst`` (a copy where links are not possible); a folder is
    linked file by file."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    if src.is_symlink():
        os.symlink(os.readlink(src), dst)
        return
    if src.is_dir():
        shutil.copytree(src, dst, symlinks=True, copy_function=_link_file)
        return
    _link_file(src, dst)
