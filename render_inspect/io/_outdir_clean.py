"""Output folders, clean-up: what earlier runs into a folder left beside it (partial
folders, backups) put back or removed, and what a failed run made undone."""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import contextlib
import os
import re
from pathlib import Path

from ._outdir_swap import _rmtree


def _stale_siblings(out: Path) -> tuple[list[Path], list[Path]]:
    """(partial folders, backups newest first) that earlier runs into ``out`` left beside
    it: folders named exactly as :func:`atomic_output_dir` names them."""
    parent, name = out.parent, out.name
    pat = re.compile(rf"^\.{re.escape(name)}\.(partial|backup)-\d+-[0-9a-f]{{8}}$")
    partials: list[tuple[float, Path]] = []
    backups: list[tuple[float, Path]] = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return [], []
    for e in entries:
        m = pat.match(e.name)
        if m is None:
            continue
        try:
            if not e.is_dir(follow_symlinks=False):
                continue
            (partials if m.group(1) == "partial" else backups).append(
                (e.stat(follow_symlinks=False).st_mtime, Path(e.path)))
        except OSError:
            continue
    return [p for _, p in partials], [p for _, p in sorted(backups, reverse=True)]


def _restore_backup(out: Path) -> str | None:
    """A run killed in the middle of a swap can leave ``out`` missing and its old content
    in a backup beside it: put the newest backup back (we hold the lock)."""
    if out.exists() or out.is_symlink():
        return None
    _, backups = _stale_siblings(out)
    for b in backups:
        with contextlib.suppress(OSError):
            os.rename(b, out)
            return f"restored {b.name}"
    return None


def _clean_stale(out: Path) -> list[str]:
    """Remove the temporary folders of earlier runs into ``out`` that did not finish (we
    hold the lock: nobody else is using them).  Called only once this run's folder is in
    place, so a refused or failed run removes nothing."""
    partials, backups = _stale_siblings(out)
    done = []
    for p in partials + backups:
        _rmtree(p)
        done.append(f"removed {p.name}")
    return done


def _undo(tmp: str | Path | None, created: Sequence[Path], lock: Any) -> None:
    """Remove the temporary folder, release the lock, and remove the parents this run
    made (innermost first) if they are still empty."""
    if tmp is not None:
        _rmtree(Path(tmp))
    if lock is not None:
        lock.release()
    for d in created:
        with contextlib.suppress(OSError):
            d.rmdir()
