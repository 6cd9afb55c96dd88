"""Write outputs so that a failed or interrupted run leaves nothing half-written.

Files go to a temporary name in the same folder and are renamed into place.  Output
folders (:func:`atomic_output_dir`) are built in a fresh hidden sibling folder and swapped
in whole, with one rename, when complete:

* ``--out`` is checked before any work: not empty text, not a file or a device, not
  under a file, writable, names not too long, not the current folder or one holding it;
* a lock (``.NAME.lock`` beside the folder, ``flock``) makes a second run into the same
  folder fail at once with a clear message instead of racing the first;
* a marker file :data:`MARKER` in every folder render_inspect writes lists the files of
  each command; a non-empty folder without it, or with files the marker does not list,
  is refused unless ``overwrite`` (``--overwrite``) is given.  A sub-folder with a marker
  of its own (another command's output inside this one) and a Zarr store (``*.zarr``)
  count as one entry each; render_inspect's own temporary names (``.NAME.lock``,
  ``.NAME.partial-*``, ``.NAME.backup-*``, ``.NAME.*.tmp``) are not counted;
* ``merge`` (the ``render`` command): the new folder also keeps the files other commands
  wrote there (hard links), provided they were made from the same part (design, tool,
  process, simulation and artifacts), and the output folders of other commands nested in
  it; the command's own earlier files are replaced;
* the swap exchanges the two folders atomically (``renameat2(RENAME_EXCHANGE)``) where
  the file system allows it, else renames the old folder to a backup, the new one into
  place, and deletes the backup only after that succeeded;
* interruptions (SIGINT, SIGTERM) are held back while the folder is swapped or the
  temporary folder removed; folders left by a killed run (``.NAME.partial-*``,
  ``.NAME.backup-*``) are removed, or the backup restored, by the next run into the same
  folder.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import hashlib
import json
import math
import os
import re
import secrets
import shutil
import signal
import stat
import tempfile
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError

__all__ = ["atomic_write_bytes", "atomic_write_text", "atomic_write_stream", "json_safe",
           "write_json", "atomic_output_dir", "check_output_path", "read_marker", "MARKER",
           "part_hash", "write_marker", "claim_output_dir", "check_output_dir"]

#: marker file in every output folder render_inspect writes (JSON)
MARKER = ".render_inspect.json"
#: what the scene keys that shape the part are (a render may join a folder of the same part)
PART_SECTIONS = ("design", "tool", "process", "simulation", "artifacts", "rcse")
#: files operating systems drop into folders by themselves (never counted as the user's)
_OS_JUNK = {".DS_Store", "Thumbs.db", "desktop.ini"}
#: characters the hidden sibling names add to the folder's name
_SIBLING_EXTRA = 48
#: render_inspect's own temporary names beside the files it writes (locks, folders being
#: built or replaced, files being written): never counted as the user's
_OWN_TEMPORARY = re.compile(r"^\..+\.(lock|partial-.+|backup-.+|old-\d+|tmp(\.exr)?)$")


def _umask() -> int:
    m = os.umask(0)
    os.umask(m)
    return m


def atomic_write_stream(path: str | Path, write) -> Path:
    """Write a file by calling ``write(fh)`` on a binary temporary file in the same folder,
    then rename it into place (the caller streams large content in pieces)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            write(fh)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual file mode
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    return atomic_write_stream(path, lambda fh: fh.write(data))


def atomic_write_text(path: str | Path, text: str) -> Path:
    return atomic_write_bytes(path, text.encode("utf-8"))


def json_safe(obj):
    """``obj`` with numpy scalars/arrays turned into Python values, paths into text and
    non-finite floats into None, so it is strict JSON (no NaN or Infinity)."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_json(path: str | Path, obj) -> Path:
    """Write ``obj`` as strict JSON (:func:`json_safe`), indented, keys sorted, atomically."""
    text = json.dumps(json_safe(obj), indent=2, sort_keys=True, allow_nan=False)
    return atomic_write_text(path, text + "\n")


# ------------------------------------------------------------------------ --out checks
def _shown(text: str) -> str:
    return repr(text if len(text) <= 120 else text[:117] + "...")


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def check_output_path(out, *, option: str = "--out", replaced: bool = True) -> Path:
    """Check an output folder before any work and return it as an absolute path
    (symbolic links resolved).

    Raises :class:`InputError` naming ``option`` when ``out`` is empty, is or lies under
    a file or a device, is too long, cannot be written (permissions, a read-only file
    system, ``/proc``), or (``replaced``: the folder is swapped as a whole) holds the
    current folder.
    """
    if out is None:
        raise InputError(f"{option} must name an output folder, received None")
    try:
        text = os.fspath(out)
    except TypeError:
        raise InputError(f"{option} must be a folder path, received {type(out).__name__}") from None
    if isinstance(text, bytes):
        text = os.fsdecode(text)
    if not text.strip():
        raise InputError(f"{option} must name an output folder, received {text!r}")
    if "\x00" in text:
        raise InputError(f"{option} must not contain a NUL character, received {_shown(text)}")
    if len(os.fsencode(text)) > 3800:
        raise InputError(f"{option} is too long ({len(text)} characters; at most 3800), "
                         f"received {_shown(text)}")
    try:
        path = Path(os.path.abspath(text)).resolve()
    except (OSError, RuntimeError) as err:  # a loop of symbolic links, a name too long
        raise InputError(f"{option} {_shown(text)} cannot be resolved "
                         f"({getattr(err, 'strerror', None) or err})") from None
    for part in path.parts:
        if len(os.fsencode(part)) > 255:
            raise InputError(f"{option}: the name {_shown(part)} is too long (at most 255 bytes "
                             f"per folder name)")
    if path == Path(path.anchor):
        raise InputError(f"{option} must not be the root folder, received {_shown(text)}")
    # the nearest folder that exists: a file there means no folder can be made below it
    probe = path
    while True:
        try:
            st = os.stat(probe)
            break
        except FileNotFoundError:
            probe = probe.parent
        except NotADirectoryError:
            probe = probe.parent
            continue
        except OSError as err:
            raise InputError(f"{option} {_shown(text)}: cannot check {str(probe)!r} "
                             f"({err.strerror})") from None
    if probe == path and not stat.S_ISDIR(st.st_mode):
        kind = "a file" if stat.S_ISREG(st.st_mode) else "not a folder (a device, pipe or socket)"
        raise InputError(f"{option} {_shown(text)} exists and is {kind}; give a folder")
    if probe != path and not stat.S_ISDIR(st.st_mode):
        raise InputError(f"{option} {_shown(text)} lies under {str(probe)!r}, which is a file, "
                         f"not a folder")
    name_max = _name_max(probe)
    for part in path.relative_to(probe).parts + (path.name,):
        if len(os.fsencode(part)) + (_SIBLING_EXTRA if part == path.name else 0) > name_max:
            raise InputError(f"{option}: the name {_shown(part)} is too long for the file "
                             f"system (at most {name_max - _SIBLING_EXTRA} bytes for the "
                             f"output folder's own name)")
    if not os.access(probe, os.W_OK | os.X_OK):
        raise InputError(f"{option} {_shown(text)}: no permission to write in {str(probe)!r} "
                         f"(or the file system is read-only)")
    try:  # permissions are not the whole story (/proc, read-only mounts): try it
        os.rmdir(tempfile.mkdtemp(prefix=".render_inspect-probe-", dir=probe))
    except OSError as err:
        raise InputError(f"{option} {_shown(text)}: cannot write in {str(probe)!r} "
                         f"({err.strerror or err})") from None
    try:
        cwd = Path.cwd().resolve()
    except OSError:
        cwd = None
    if replaced and cwd is not None and (cwd == path or path in cwd.parents):
        raise InputError(f"{option} {_shown(text)} is the current folder or holds it; the "
                         f"output folder is replaced as a whole, so choose a folder inside it")
    return path


# ------------------------------------------------------------------------ marker
def part_hash(scene) -> str | None:
    """SHA-256 of the scene keys that shape the part (:data:`PART_SECTIONS`)."""
    if scene is None:
        return None
    d = scene.to_dict() if hasattr(scene, "to_dict") else dict(scene)
    part = {k: d.get(k) for k in PART_SECTIONS}
    return hashlib.sha256(json.dumps(json_safe(part), sort_keys=True).encode()).hexdigest()


def _scene_hash(scene) -> str | None:
    if scene is None:
        return None
    d = scene.to_dict() if hasattr(scene, "to_dict") else dict(scene)
    return hashlib.sha256(json.dumps(json_safe(d), sort_keys=True).encode()).hexdigest()


def read_marker(folder: str | Path) -> dict | None:
    """The marker of a folder render_inspect wrote (:data:`MARKER`), or None."""
    f = Path(folder) / MARKER
    try:
        if not f.is_file() or f.stat().st_size > 16 * 2 ** 20:
            return None
        d = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(d, dict) or d.get("written_by") != "render_inspect" \
            or not isinstance(d.get("files"), dict) or not isinstance(d.get("commands", {}), dict):
        return None
    return d


def _is_unit(folder: Path) -> bool:
    """A folder listed as one entry: another command's output (its own marker) or a Zarr
    store."""
    return folder.name.endswith(".zarr") or read_marker(folder) is not None


def _files(folder: Path) -> list[str]:
    """Relative paths (posix) of every file and link below ``folder``, the marker, OS
    junk and render_inspect's temporary names left out; nested output folders and Zarr
    stores (:func:`_is_unit`) are one entry each, written with a trailing ``/``."""
    out = []
    for root, dirs, names in os.walk(folder):
        for n in names:
            if n in _OS_JUNK or _OWN_TEMPORARY.match(n):
                continue
            rel = Path(root, n).relative_to(folder).as_posix()
            if rel != MARKER:
                out.append(rel)
        for d in list(dirs):
            full = Path(root, d)
            if full.is_symlink():  # a link to a folder is listed as a file, not followed
                out.append(full.relative_to(folder).as_posix())
                dirs.remove(d)
            elif _OWN_TEMPORARY.match(d):
                dirs.remove(d)
            elif _is_unit(full):
                out.append(full.relative_to(folder).as_posix() + "/")
                dirs.remove(d)
    return sorted(out)


def _nested_outputs(folder: Path, entries) -> list[str]:
    """The entries of :func:`_files` (of ``folder``) that are output folders with a marker
    of their own."""
    return [e for e in entries if e.endswith("/") and read_marker(folder / e.rstrip("/"))]


# ------------------------------------------------------------------------ signals, lock
@contextlib.contextmanager
def _signals_held():
    """Hold SIGINT/SIGTERM/SIGHUP back while a block runs (the swap, the clean-up)."""
    sigs = {signal.SIGINT, signal.SIGTERM, signal.SIGHUP}
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    except (ValueError, OSError, AttributeError):
        old = None
    try:
        yield
    finally:
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


class _Lock:
    """An exclusive ``flock`` on ``.NAME.lock`` beside the output folder (released by the
    kernel if the process dies)."""

    def __init__(self, path: Path, out_text: str, option: str):
        import fcntl

        self.path = path
        while True:
            try:
                fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666 & ~_umask() | 0o600)
            except OSError as err:
                raise InputError(f"{option} {_shown(out_text)}: cannot write in "
                                 f"{str(path.parent)!r} ({err.strerror})") from None
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
                same = os.path.samestat(os.fstat(fd), os.stat(path))
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
            os.unlink(self.path)
        with contextlib.suppress(OSError):
            os.close(self.fd)
        self.fd = None


# ------------------------------------------------------------------------ the swap
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


def _clean_stale(out: Path) -> list[str]:
    """Remove the temporary folders of earlier runs into ``out`` that did not finish (we
    hold the lock: nobody else is using them); restore a backup if ``out`` is missing."""
    parent, name = out.parent, out.name
    done = []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return done
    partials = [e for e in entries if e.name.startswith(f".{name}.partial-")]
    backups = sorted((e for e in entries if e.name.startswith(f".{name}.backup-")),
                     key=lambda e: e.stat(follow_symlinks=False).st_mtime, reverse=True)
    if backups and not out.exists():
        with contextlib.suppress(OSError):
            os.rename(backups[0].path, out)
            done.append(f"restored {backups[0].name}")
            backups = backups[1:]
    for e in partials + backups:
        _rmtree(Path(e.path))
        done.append(f"removed {e.name}")
    return done


# ------------------------------------------------------------------------ the folder
def _inspect_existing(out: Path, *, overwrite: bool, merge: bool, part: str | None,
                      command: str, option: str, out_text: str) -> tuple[str, dict | None]:
    """How to treat an existing ``out``: ("new" | "replace" | "merge", its marker)."""
    if not out.exists():
        return "new", None
    present = _files(out)
    marker = read_marker(out)
    if not present:
        return ("merge" if merge and marker else "new"), marker
    if overwrite:
        return "replace", marker
    if marker is None:
        shown = ", ".join(present[:3]) + (", ..." if len(present) > 3 else "")
        raise InputError(f"{option} {_shown(out_text)} is not empty ({len(present)} files: "
                         f"{shown}) and was not written by render-inspect (no {MARKER}); "
                         f"choose a new or empty folder, or pass --overwrite to replace it")
    nested = set(_nested_outputs(out, present))
    foreign = [f for f in present if f not in marker["files"] and f not in nested]
    if foreign:
        shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
        raise InputError(f"{option} {_shown(out_text)} holds files render-inspect did not "
                         f"write ({shown}); move them away, choose another folder, or pass "
                         f"--overwrite to replace the folder")
    if merge and part is not None:
        parts = {c: v.get("part_sha256") for c, v in marker.get("commands", {}).items()
                 if isinstance(v, dict) and v.get("part_sha256") and c != command}
        other = sorted(c for c, h in parts.items() if h != part)
        if other:
            raise InputError(f"{option} {_shown(out_text)} holds the {', '.join(other)} output "
                             f"of a different part (design, tool, process or simulation keys "
                             f"differ); choose another folder, or pass --overwrite to replace it")
    return ("merge" if merge else "replace"), marker


def check_output_dir(out, *, overwrite: bool = False, merge: bool = False,
                     command: str = "output", scene=None, option: str = "--out") -> Path:
    """The checks :func:`atomic_output_dir` makes before its block runs (the path, and an
    existing folder's content against ``overwrite`` / ``merge``), without locking or
    writing anything: for a command that reads its input before it opens its output
    folder, so that a bad ``--out`` is refused before any work.  Returns the folder
    (absolute)."""
    out_text = os.fspath(out) if isinstance(out, (str, os.PathLike)) else str(out)
    target = check_output_path(out, option=option)
    _inspect_existing(target, overwrite=overwrite, merge=merge, part=part_hash(scene),
                      command=command, option=option, out_text=out_text)
    return target


def write_marker(folder: str | Path, *, command: str, scene=None) -> None:
    """Mark ``folder`` (being built) as ``command``'s output: its files and the scene's
    hashes go into :data:`MARKER`.  For a sub-folder that later commands address on their
    own (the add-on's variant folders); :func:`atomic_output_dir` marks the folders it
    writes by itself."""
    _write_marker(Path(folder), command=command, scene=scene, previous=None, kept={})


def _write_marker(folder: Path, *, command: str, scene, previous: dict | None,
                  kept: dict) -> None:
    files = {rel: command for rel in _files(folder) if rel not in kept}
    files.update(kept)
    commands = {}
    if previous is not None:
        commands = {c: v for c, v in previous.get("commands", {}).items()
                    if c in set(kept.values()) and isinstance(v, dict)}
    commands[command] = {"part_sha256": part_hash(scene), "scene_sha256": _scene_hash(scene)}
    d = {"written_by": "render_inspect", "marker_version": 1, "software_version": __version__,
         "files": dict(sorted(files.items())), "commands": dict(sorted(commands.items()))}
    (folder / MARKER).write_text(json.dumps(d, indent=2, sort_keys=True) + "\n", encoding="utf-8")


def _link_file(src, dst) -> None:
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


_OUTPUT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EFBIG, errno.EIO,
                  errno.EACCES, errno.EPERM, errno.EBUSY, errno.EXDEV, errno.ENOTEMPTY,
                  errno.EEXIST, errno.ENAMETOOLONG, errno.ELOOP}


@contextlib.contextmanager
def atomic_output_dir(out: str | Path, *, overwrite: bool = False, merge: bool = False,
                      command: str = "output", scene=None, option: str = "--out"):
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

    On an exception (an interruption included) the temporary folder is removed, ``out``
    is left as it was and the exception propagates; errors writing into the temporary
    folder (a full disk, a read-only file system) become :class:`InputError` naming
    ``option``.
    """
    out_text = os.fspath(out) if isinstance(out, (str, os.PathLike)) else str(out)
    target = check_output_path(out, option=option)
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
        _clean_stale(target)
        mode, marker = _inspect_existing(target, overwrite=overwrite, merge=merge,
                                         part=part_hash(scene), command=command, option=option,
                                         out_text=out_text)
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
    except BaseException as exc:
        if tmp is None:  # the folder was swapped in; an interruption held back arrived after
            exc.render_inspect_output_complete = str(target)
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


def _undo(tmp, created, lock) -> None:
    """Remove the temporary folder, release the lock, and remove the parents this run
    made (innermost first) if they are still empty."""
    if tmp is not None:
        _rmtree(Path(tmp))
    if lock is not None:
        lock.release()
    for d in created:
        with contextlib.suppress(OSError):
            d.rmdir()


def claim_output_dir(out, *, command: str, overwrite: bool = False, option: str = "--out",
                     resumable=None) -> Path:
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
    try:
        target.mkdir(parents=True, exist_ok=True)
        marker = read_marker(target)
        commands = dict(marker.get("commands", {})) if marker is not None else {}
        commands.setdefault(command, {"part_sha256": None, "scene_sha256": None})
        d = {"written_by": "render_inspect", "marker_version": 1,
             "software_version": __version__, "files": {},
             "commands": dict(sorted(commands.items()))}
        atomic_write_text(target / MARKER, json.dumps(d, indent=2, sort_keys=True) + "\n")
    except OSError as err:
        raise InputError(f"{option} {_shown(out_text)}: cannot write there "
                         f"({err.strerror or err})") from None
    return target
