"""A folder a run made and then could not fill is removed: a run that fails (a full disk,
a quota, an I/O error, an interruption) before it wrote anything of worth leaves no empty
folder behind, only the folder as it was before."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
import contextlib
import os
import shutil
from pathlib import Path

__all__ = ["discard_unused", "discarding_new_folder"]


def discard_unused(folder: Path, scaffolding: Iterable[str] = ()) -> bool:
    """Remove ``folder`` when it holds nothing but ``scaffolding`` (names of the files a
    run writes before its work: its marker, a lock, a copy of its input) and empty
    files; returns whether it was removed.  A folder with any other entry is left."""
    folder = Path(folder)
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return False
    for e in entries:
        if e.name in scaffolding and not e.is_symlink():
            continue
        try:
            if e.is_file(follow_symlinks=False) and e.stat(follow_symlinks=False).st_size == 0:
                continue
        except OSError:
            pass
        return False
    with contextlib.suppress(OSError):
        shutil.rmtree(folder)
    return not folder.exists()


@contextlib.contextmanager
def discarding_new_folder(folder: Path, scaffolding: Iterable[str] = ()) -> Iterator[None]:
    """Within the block, ``folder`` is made and filled; if it did not exist before and
    the block fails, it is removed again unless it holds more than ``scaffolding`` and
    empty files (:func:`discard_unused`)."""
    folder = Path(folder)
    fresh = not os.path.lexists(folder)
    try:
        yield
    except BaseException:
        if fresh:
            discard_unused(folder, scaffolding)
        raise
