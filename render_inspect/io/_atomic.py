"""Write outputs so that a failed or interrupted run leaves nothing half-written.

Files go to a temporary name in the same folder and are renamed into place.  Output
folders (:func:`atomic_output_dir`) are built in a fresh hidden sibling folder and swapped
in whole, with one rename, when complete:

* ``--out`` is checked before any work: not empty text, not a file or a device, not
  under a file, writable, names not too long, not the current folder or one holding it;
* a lock (``.NAME.lock`` beside the folder, ``flock``) makes a second run into the same
  folder fail at once with a clear message instead of racing the first;
* a marker file :data:`MARKER` in every folder render_inspect writes lists the files of
  each command with their sizes and modification times; a non-empty folder without it,
  with a marker of another user or of an earlier version, or with files the marker does
  not list or that changed since, is refused unless ``overwrite`` (``--overwrite``) is
  given.  A sub-folder with a marker of its own (another command's output inside this
  one) is checked against its own marker; a Zarr store (``*.zarr``) counts as one entry;
  render_inspect's own temporaries (``.NAME.lock`` holding a process id,
  ``.NAME.partial-PID-XXXXXXXX/``, ``.NAME.backup-PID-XXXXXXXX/``, ``.NAME.XXXXXXXX.tmp``,
  exactly so named) are not counted, while a file that merely looks like one is the
  user's;
* ``overwrite`` never follows a symbolic link given as the folder, and a folder that
  holds the command's input (``inputs``) is refused even with it;
* ``merge`` (the ``render`` command): the new folder also keeps the files other commands
  wrote there (hard links), provided they were made from the same part (design, tool,
  process, simulation and artifacts), and the output folders of other commands nested in
  it; the command's own earlier files are replaced;
* the swap exchanges the two folders atomically (``renameat2(RENAME_EXCHANGE)``) where
  the file system allows it, else renames the old folder to a backup, the new one into
  place, and deletes the backup only after that succeeded;
* interruptions (SIGINT, SIGTERM, SIGHUP) are held back while the folder is swapped or
  the temporary folder removed, and delivered once that is done (the exception then
  says the folder is complete); folders left by a killed run (``.NAME.partial-*``,
  ``.NAME.backup-*``) are removed by the next run into the same folder once that run
  has put its own folder in place (a refused run removes nothing); a backup is put back
  first when the folder itself is missing.

The pieces are modules of their own: :mod:`._atomic_write` (files), :mod:`._outdir_names`
(the ``--out`` checks, temporary names), :mod:`._outdir_marker` (the marker),
:mod:`._outdir_lock` (the lock, signals held), :mod:`._outdir_swap` (the swap) and
:mod:`._outdir_clean` (leftovers of earlier runs); this module puts them together.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Callable, Iterable, Iterator
import contextlib
import errno
import json
import os
import secrets
import time
from pathlib import Path

from .. import __version__
from ..core.errors import InputError
from ._discard import discard_unused
from ._atomic_write import (
    _umask,
    atomic_write_bytes,
    atomic_write_stream,
    atomic_write_text,
    json_safe,
    write_json,
)
from ._outdir_clean import _clean_stale, _restore_backup, _stale_siblings, _undo
from ._outdir_lock import _deliver, _HELD_SIGNALS, _Lock, _signals_held, open_lock_file
from ._outdir_marker import (
    MARKER,
    MARKER_VERSION,
    NOT_PART,
    PART_SECTIONS,
    _distrust,
    _files,
    _foreign,
    _is_unit,
    _nested_outputs,
    _part_hashes,
    _scene_hash,
    _stat_record,
    _write_marker,
    part_hash,
    read_marker,
    write_marker,
)
from ._outdir_names import (
    _LOCK_MAX,
    _OS_JUNK,
    _SIBLING_EXTRA,
    _TEMP_DIR,
    _TEMP_FILE,
    _check_inputs,
    _check_link,
    _listing,
    _name_max,
    _own_temporary,
    _shown,
    check_output_path,
    refuse_inputs_inside,
    scene_files,
)
from ._outdir_swap import (
    _AT_FDCWD,
    _COMPLETED,
    _RENAME_EXCHANGE,
    _exchange,
    _link_file,
    _link_or_copy,
    _rmtree,
    _swap_in,
    completed_outputs,
)

__all__ = ["atomic_write_bytes", "atomic_write_text", "atomic_write_stream", "json_safe",
           "write_json", "atomic_output_dir", "check_output_path", "read_marker", "MARKER",
           "part_hash", "write_marker", "claim_output_dir", "check_output_dir",
           "completed_outputs", "MARKER_VERSION", "open_lock_file", "refuse_inputs_inside", "scene_files"]


def _inspect_existing(out: Path, *, overwrite: bool, merge: bool, part: tuple | None,
                      command: str, option: str, out_text: str,
                      inputs: Iterable[str | Path | None] = ()) -> tuple[str, dict | None]:
    """How to treat an existing ``out``: ("new" | "replace" | "merge", its marker)."""
    if not out.exists():
        return "new", None
    _check_inputs(out, inputs, option, out_text)
    present = _files(out)
    marker = read_marker(out)
    if not present:
        return ("merge" if merge and marker and not _distrust(out, marker) else "new"), marker
    if overwrite:
        return "replace", marker
    if marker is None:
        raise InputError(f"{option} {_shown(out_text)} is not empty ({len(present)} files: "
                         f"{_listing(present)}) and was not written by render-inspect (no "
                         f"{MARKER}); choose a new or empty folder, or pass --overwrite to "
                         f"replace it")
    why = _distrust(out, marker)
    if why:
        raise InputError(f"{option} {_shown(out_text)} is not empty ({len(present)} files: "
                         f"{_listing(present)}) and its {MARKER} {why}; choose a new or empty "
                         f"folder, or pass --overwrite to replace it")
    foreign = _foreign(out, marker)
    if foreign:
        raise InputError(f"{option} {_shown(out_text)} holds files render-inspect did not "
                         f"write or that changed since it wrote them ({_listing(foreign)}); "
                         f"move them away, choose another folder, or pass --overwrite to "
                         f"replace the folder")
    if merge and part is not None:
        parts = {c: v.get("part_sha256") for c, v in marker.get("commands", {}).items()
                 if isinstance(v, dict) and v.get("part_sha256") and c != command}
        other = sorted(c for c, h in parts.items() if h not in part)
        if other:
            raise InputError(f"{option} {_shown(out_text)} holds the {', '.join(other)} output "
                             f"of a different part (design, tool, process or simulation keys "
                             f"differ); choose another folder, or pass --overwrite to replace it")
    return ("merge" if merge else "replace"), marker


def check_output_dir(out: str | Path, *, overwrite: bool = False, merge: bool = False,
                     command: str = "output", scene: Any = None, option: str = "--out",
                     inputs: Iterable[str | Path | None] = ()) -> Path:
    """The checks :func:`atomic_output_dir` makes before its block runs (the path, and an
    existing folder's content against ``overwrite`` / ``merge`` / ``inputs``), without
    locking or writing anything: for a command that reads its input before it opens its
    output folder, so that a bad ``--out`` is refused before any work.  Returns the folder
    (absolute)."""
    out_text = os.fspath(out) if isinstance(out, (str, os.PathLike)) else str(out)
    target = check_output_path(out, option=option)
    _check_link(out_text, overwrite, option)
    inputs = (*inputs, *scene_files(scene))
    _inspect_existing(target, overwrite=overwrite, merge=merge, part=_part_hashes(scene),
                      command=command, option=option, out_text=out_text, inputs=inputs)
    return target


_OUTPUT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG, errno.EIO,
                  errno.EACCES, errno.EPERM, errno.EBUSY, errno.EXDEV, errno.ENOTEMPTY,
                  errno.EEXIST, errno.ENAMETOOLONG, errno.ELOOP}


@contextlib.contextmanager
def atomic_output_dir(out: str | Path, *, overwrite: bool = False, merge: bool = False,
                      command: str = "output", scene: Any = None, option: str = "--out",
                      inputs: Iterable[str | Path | None] = ()) -> Iterator[Path]:
    """Yield a fresh temporary folder; when the block ends without an exception it
    becomes ``out``, whole, in one swap (see the module docstring).

    Parameters
    ----------
    out : str or Path
        The output folder.  Checked, locked and inspected before the block runs, so open
        this context before the expensive work.
    overwrite : bool
        Replace a non-empty folder that render_inspect did not write (or that holds
        other files) instead of refusing it.
    merge : bool
        Keep the files other commands wrote in ``out`` (the ``render`` command adds its
        images to a ``simulate`` folder of the same part).
    command : str
        Name recorded in the marker for the files written.
    scene : Scene or dict, optional
        Recorded (as hashes) in the marker; a merge needs the same part.
    option : str
        The option named in error messages.
    inputs : sequence of paths
        The command's input files: an ``out`` that holds one is refused (it would be
        deleted with the folder), even with ``overwrite``; the files ``scene`` reads (its
        height map design, measured tool edge, machine program) are inputs too.

    ``overwrite`` does not follow a symbolic link: an ``out`` that is a link is refused
    with it (give the folder itself).  On an exception (an interruption included) before
    the swap the temporary folder is removed, ``out`` is left as it was and the exception
    propagates; an interruption that arrives during the swap is held back until the
    folder is in place and then raised with the attribute
    ``render_inspect_output_complete`` (the folder); :func:`completed_outputs` lists the
    folders swapped in.  Errors writing into the temporary folder (a full disk, a
    read-only file system) become :class:`InputError` naming ``option``.
    """
    out_text = os.fspath(out) if isinstance(out, (str, os.PathLike)) else str(out)
    target = check_output_path(out, option=option)
    _check_link(out_text, overwrite, option)
    # (the files the scene reads too: a program or a height map in the folder would go
    # with it)
    inputs = (*inputs, *scene_files(scene))
    created = []
    p = target.parent
    while not p.exists():
        created.append(p)
        p = p.parent
    lock = tmp = None
    try:
        for d in reversed(created):
            try:
                d.mkdir()
            except FileExistsError:
                pass
        lock = _Lock(target.parent / f".{target.name}.lock", out_text, option)
        _restore_backup(target)
        mode, marker = _inspect_existing(target, overwrite=overwrite, merge=merge,
                                         part=_part_hashes(scene), command=command, option=option,
                                         out_text=out_text, inputs=inputs)
        tmp = target.parent / f".{target.name}.partial-{os.getpid()}-{secrets.token_hex(4)}"
        os.mkdir(tmp, 0o777 & ~_umask() | 0o700)
    except OSError as err:
        with _signals_held():
            _undo(tmp, created, lock)
        raise InputError(f"{option} {_shown(out_text)}: cannot write there "
                         f"({err.strerror or err})") from None
    except BaseException:
        with _signals_held():
            _undo(tmp, created, lock)
        raise
    try:
        yield tmp
        with _signals_held():
            kept = {}
            if mode == "merge" and marker is not None:
                for rel, owner in marker["files"].items():
                    src = target / rel.rstrip("/")
                    if owner == command or (tmp / rel).exists() or not (src.exists() or src.is_symlink()):
                        continue
                    _link_or_copy(src, tmp / rel.rstrip("/"))
                    kept[rel] = owner
                # other commands' output folders nested in this one are kept too
                for rel in _nested_outputs(target, _files(target)):
                    if rel in marker["files"] or (tmp / rel.rstrip("/")).exists():
                        continue
                    _link_or_copy(target / rel.rstrip("/"), tmp / rel.rstrip("/"))
                    kept[rel] = marker["files"].get(rel) or "nested output"
            _write_marker(tmp, command=command, scene=scene,
                          previous=marker if mode == "merge" else None, kept=kept)
            _swap_in(tmp, target, target.parent / f".{target.name}.backup-{os.getpid()}-"
                                                  f"{secrets.token_hex(4)}")
            tmp = None
            created = []
            _COMPLETED.append((time.monotonic(), str(target)))
            _clean_stale(target)  # earlier runs' leftovers, now that this run is complete
        # an interruption held back during the swap is delivered here, inside this block,
        # so the handler below says that the folder is complete
    except BaseException as exc:
        if tmp is None:  # the folder was swapped in; an interruption held back arrived after
            exc.render_inspect_output_complete = str(target)  # type: ignore[attr-defined]
        tmp_text = str(tmp) if tmp is not None else None
        with _signals_held():
            _undo(tmp, created, lock)
            lock = None
        if isinstance(exc, OSError) and exc.errno in _OUTPUT_ERRNOS and (
                exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
                or _inside(exc, tmp_text, target)):
            raise InputError(f"{option} {_shown(out_text)}: {exc.strerror} while writing "
                             f"{Path(exc.filename).name if exc.filename else 'the output'}; "
                             f"nothing was written") from None
        raise
    finally:
        if lock is not None:
            lock.release()


def _inside(exc: OSError, tmp: str | None, target: Path) -> bool:
    """Whether the failed operation was on the output (the temporary folder, the target)."""
    if not exc.filename:
        return False
    f = os.fsdecode(exc.filename) if isinstance(exc.filename, bytes) else str(exc.filename)
    roots = [r for r in (tmp, str(target)) if r]
    return any(f == r or f.startswith(r + os.sep) for r in roots)


def claim_output_dir(out: str | Path, *, command: str, overwrite: bool = False,
                     option: str = "--out",
                     resumable: Callable[[Path], bool] | None = None) -> Path:
    """Check a folder that a command fills in place over many runs (``sweep``: its
    finished points are kept and the run goes on where it stopped), before any work.

    The path is checked as :func:`check_output_path` does (the folder is not replaced
    whole, so it may hold the current folder).  An existing non-empty folder must be
    ``command``'s own (its :data:`MARKER` names it, or ``resumable(path)`` says it is one
    written before markers were kept); another non-empty folder is refused unless
    ``overwrite`` (its files are then left in place beside the new ones).  The folder is
    created and marked as ``command``'s.

    Returns the folder (absolute).
    """
    out_text = os.fspath(out) if isinstance(out, (str, os.PathLike)) else str(out)
    target = check_output_path(out, option=option, replaced=False)
    if target.exists():
        present = _files(target)
        marker = read_marker(target)
        own = (marker is not None and command in marker.get("commands", {})) or \
            (resumable is not None and resumable(target))
        if present and not own and not overwrite:
            shown = ", ".join(present[:3]) + (", ..." if len(present) > 3 else "")
            what = ("was written by render-inspect " + "/".join(sorted(marker["commands"]))
                    if marker is not None else "was not written by render-inspect")
            raise InputError(f"{option} {_shown(out_text)} is not empty ({len(present)} "
                             f"entries: {shown}) and {what}, not by {command}; choose a new "
                             f"or empty folder, or pass --overwrite to write there anyway "
                             f"(the files there are left in place)")
    fresh = not target.exists()
    try:
        target.mkdir(parents=True, exist_ok=True)
        marker = read_marker(target)
        commands = dict(marker.get("commands", {})) if marker is not None else {}
        commands.setdefault(command, {"part_sha256": None, "scene_sha256": None})
        d = {"written_by": "render_inspect", "marker_version": MARKER_VERSION,
             "software_version": __version__, "files": {}, "stat": {},
             "commands": dict(sorted(commands.items()))}
        atomic_write_text(target / MARKER, json.dumps(d, indent=2, sort_keys=True) + "\n")
    except OSError as err:
        if fresh:  # a folder this call made is not left behind empty
            discard_unused(target, (MARKER,))
        raise InputError(f"{option} {_shown(out_text)}: cannot write there "
                         f"({err.strerror or err} while writing {MARKER})") from None
    return target
