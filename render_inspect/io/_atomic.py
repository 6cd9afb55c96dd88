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
import threading
import time
from pathlib import Path

import numpy as np

from ..core.units import MIB_TO_BYTES
from .. import __version__
from ..core.errors import InputError
from ._discard import discard_unused

__all__ = ["atomic_write_bytes", "atomic_write_text", "atomic_write_stream", "json_safe",
           "write_json", "atomic_output_dir", "check_output_path", "read_marker", "MARKER",
           "part_hash", "write_marker", "claim_output_dir", "check_output_dir",
           "completed_outputs", "MARKER_VERSION", "open_lock_file"]

#: marker file in every output folder render_inspect writes (JSON)
MARKER = ".render_inspect.json"
#: the marker's layout: 2 records each file's size and modification time (``stat``)
MARKER_VERSION = 2
#: what the scene keys that shape the part are (a render may join a folder of the same part)
PART_SECTIONS = ("design", "tool", "process", "simulation", "artifacts", "rcse")
#: keys of those sections that do not shape the part: the memory budget of a run
NOT_PART = {"simulation": ("max_memory_gb",)}
#: files operating systems drop into folders by themselves (never counted as the user's)
_OS_JUNK = {".DS_Store", "Thumbs.db", "desktop.ini"}
#: characters the hidden sibling names add to the folder's name
_SIBLING_EXTRA = 48
#: render_inspect's own temporary names beside the files it writes, exactly as it makes
#: them (the part after ``.NAME.``): the lock, folders being built (``partial``) or
#: replaced (``backup``, ``old``), files being written (``tmp``).  A name that merely looks
#: like one (``.metrics.json.backup-1``) is the user's.
_TEMP_FILE = re.compile(r"^\..+\.(?:lock|[A-Za-z0-9_]{8}\.tmp|\d+\.tmp\.exr)$")
_TEMP_DIR = re.compile(r"^\..+\.(?:partial-\d+-[0-9a-f]{8}|partial-[A-Za-z0-9_]{8}|"
                       r"backup-\d+-[0-9a-f]{8}|old-\d+)$")
#: the largest lock file render_inspect writes (a process id and a newline)
_LOCK_MAX = 32


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
def part_hash(scene, *, legacy: bool = False) -> str | None:
    """SHA-256 of the scene keys that shape the part (:data:`PART_SECTIONS`, less
    :data:`NOT_PART`: the memory a run may use is no property of the part).  ``legacy``:
    the hash as folders written before that distinction recorded it."""
    if scene is None:
        return None
    d = scene.to_dict() if hasattr(scene, "to_dict") else dict(scene)
    part = {k: d.get(k) for k in PART_SECTIONS}
    if not legacy:
        for sec, keys in NOT_PART.items():
            if isinstance(part.get(sec), dict):
                part[sec] = {k: v for k, v in part[sec].items() if k not in keys}
    return hashlib.sha256(json.dumps(json_safe(part), sort_keys=True).encode()).hexdigest()


def _part_hashes(scene) -> tuple | None:
    """The hashes a folder of the same part may record (now and before :data:`NOT_PART`)."""
    return None if scene is None else (part_hash(scene), part_hash(scene, legacy=True))


def _scene_hash(scene) -> str | None:
    if scene is None:
        return None
    d = scene.to_dict() if hasattr(scene, "to_dict") else dict(scene)
    return hashlib.sha256(json.dumps(json_safe(d), sort_keys=True).encode()).hexdigest()


def read_marker(folder: str | Path) -> dict | None:
    """The marker of a folder render_inspect wrote (:data:`MARKER`), or None (no marker, a
    link, a damaged or foreign file)."""
    f = Path(folder) / MARKER
    try:
        st = os.lstat(f)
        if not stat.S_ISREG(st.st_mode) or st.st_size > 16 * MIB_TO_BYTES:
            return None
        d = json.loads(f.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(d, dict) or d.get("written_by") != "render_inspect" \
            or not isinstance(d.get("files"), dict) or not isinstance(d.get("commands", {}), dict):
        return None
    return d


def _distrust(folder: Path, marker: dict | None) -> str | None:
    """Why the marker of ``folder`` does not vouch for its files (None: it does).  It must
    belong to the user running render-inspect and record each file's size and date
    (:data:`MARKER_VERSION`)."""
    if marker is None:
        return "is missing"
    try:
        owner = os.lstat(folder / MARKER).st_uid
    except OSError:
        return "cannot be read"
    if hasattr(os, "geteuid") and owner != os.geteuid():
        return f"belongs to another user (uid {owner})"
    if not isinstance(marker.get("marker_version"), int) \
            or marker["marker_version"] < MARKER_VERSION or not isinstance(marker.get("stat"), dict):
        return ("comes from an earlier render-inspect version that did not record the files' "
                "sizes and dates")
    return None


def _is_unit(folder: Path) -> bool:
    """A folder listed as one entry: another command's output (its own marker) or a Zarr
    store."""
    return folder.name.endswith(".zarr") or read_marker(folder) is not None


def _own_temporary(full: Path, name: str, is_dir: bool) -> bool:
    """Whether ``name`` is one of render_inspect's temporaries (:data:`_TEMP_FILE`,
    :data:`_TEMP_DIR`): the exact name and the right kind (a lock file holding at most a
    process id; a file; a folder), never a link."""
    try:
        st = os.lstat(full)
    except OSError:
        return False
    if is_dir:
        return stat.S_ISDIR(st.st_mode) and bool(_TEMP_DIR.match(name))
    if not stat.S_ISREG(st.st_mode) or not _TEMP_FILE.match(name):
        return False
    if name.endswith(".lock"):
        if st.st_size > _LOCK_MAX or st.st_nlink != 1:
            return False
        try:
            text = full.read_bytes().strip()
        except OSError:
            return False
        return text == b"" or text.isdigit()
    return True


def _files(folder: Path) -> list[str]:
    """Relative paths (posix) of every file and link below ``folder``, the marker, OS
    junk and render_inspect's temporaries (:func:`_own_temporary`) left out; nested output
    folders and Zarr stores (:func:`_is_unit`) are one entry each, written with a trailing
    ``/``."""
    out = []
    for root, dirs, names in os.walk(folder):
        for n in names:
            full = Path(root, n)
            if n in _OS_JUNK or _own_temporary(full, n, False):
                continue
            rel = full.relative_to(folder).as_posix()
            if rel != MARKER:
                out.append(rel)
        for d in list(dirs):
            full = Path(root, d)
            if full.is_symlink():  # a link to a folder is listed as a file, not followed
                out.append(full.relative_to(folder).as_posix())
                dirs.remove(d)
            elif _own_temporary(full, d, True):
                dirs.remove(d)
            elif _is_unit(full):
                out.append(full.relative_to(folder).as_posix() + "/")
                dirs.remove(d)
    return sorted(out)


def _nested_outputs(folder: Path, entries) -> list[str]:
    """The entries of :func:`_files` (of ``folder``) that are output folders with a marker
    of their own."""
    return [e for e in entries if e.endswith("/") and read_marker(folder / e.rstrip("/"))]


def _stat_record(path: Path) -> list[int]:
    """What the marker records of an entry: [size, modification time (ns)] of a file or
    link; [bytes, latest modification time (ns), number of files] of a Zarr store."""
    st = os.lstat(path)
    if not stat.S_ISDIR(st.st_mode):
        return [int(st.st_size), int(st.st_mtime_ns)]
    size = latest = count = 0
    for root, dirs, names in os.walk(path):
        for n in names + [d for d in dirs if os.path.islink(os.path.join(root, d))]:
            s = os.lstat(os.path.join(root, n))
            size, latest, count = size + s.st_size, max(latest, s.st_mtime_ns), count + 1
    return [int(size), int(latest), int(count)]


def _foreign(folder: Path, marker: dict, depth: int = 0) -> list[str]:
    """The entries below ``folder`` its (trusted) marker does not vouch for: not listed, or
    changed since render-inspect wrote them (size or date); the output folders of other
    commands nested in it are checked against their own markers, to any depth."""
    out = []
    stats = marker.get("stat", {})
    for rel in _files(folder):
        full = folder / rel.rstrip("/")
        sub = read_marker(full) if rel.endswith("/") else None
        if sub is not None:  # another command's output: its own marker speaks for it
            if depth >= 32 or _distrust(full, sub):
                out.append(rel)
            else:
                out.extend(rel + f for f in _foreign(full, sub, depth + 1))
            continue
        try:
            same = rel in marker["files"] and stats.get(rel) == _stat_record(full)
        except OSError:
            same = False
        if not same:
            out.append(rel)
    return out


# ------------------------------------------------------------------------ signals, lock
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


#: output folders swapped in by this process: (time.monotonic(), folder)
_COMPLETED: list[tuple[float, str]] = []


def completed_outputs(since: float = 0.0) -> list[str]:
    """The output folders :func:`atomic_output_dir` swapped in (complete) in this process
    since ``since`` (a :func:`time.monotonic` time), oldest first: what a command stopped
    by an interruption after writing its folder reports as written."""
    return [f for t, f in _COMPLETED if t >= since]


def open_lock_file(path, *, option: str = "--out", out_text: str | None = None) -> int:
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


def _stale_siblings(out: Path) -> tuple[list[Path], list[Path]]:
    """(partial folders, backups newest first) that earlier runs into ``out`` left beside
    it: folders named exactly as :func:`atomic_output_dir` names them."""
    parent, name = out.parent, out.name
    pat = re.compile(rf"^\.{re.escape(name)}\.(partial|backup)-\d+-[0-9a-f]{{8}}$")
    partials, backups = [], []
    try:
        entries = list(os.scandir(parent))
    except OSError:
        return partials, backups
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


# ------------------------------------------------------------------------ the folder
def _listing(entries) -> str:
    return ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")


def _check_link(out_text: str, overwrite: bool, option: str) -> None:
    """``--overwrite`` does not replace the folder a symbolic link points to."""
    full = os.path.abspath(out_text)
    if overwrite and os.path.islink(full):
        raise InputError(f"{option} {_shown(out_text)} is a symbolic link to "
                         f"{os.path.realpath(full)!r}; --overwrite does not replace the folder a "
                         f"link points to: give that folder itself as {option}, or remove the link")


def _check_inputs(target: Path, inputs, option: str, out_text: str) -> None:
    """Refuse an output folder that holds one of the command's input files (it would be
    deleted with the folder), whatever ``--overwrite`` says."""
    for f in inputs or ():
        try:
            full = Path(os.path.abspath(os.fspath(f))).resolve()
        except (OSError, RuntimeError, TypeError, ValueError):
            continue
        if full == target or target in full.parents:
            raise InputError(f"{option} {_shown(out_text)} holds the input {str(f)!r}; the "
                             f"output folder is replaced as a whole, which would delete it: "
                             f"choose another {option} or move the input out of it")


def _inspect_existing(out: Path, *, overwrite: bool, merge: bool, part: tuple | None,
                      command: str, option: str, out_text: str,
                      inputs=()) -> tuple[str, dict | None]:
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


def check_output_dir(out, *, overwrite: bool = False, merge: bool = False,
                     command: str = "output", scene=None, option: str = "--out",
                     inputs=()) -> Path:
    """The checks :func:`atomic_output_dir` makes before its block runs (the path, and an
    existing folder's content against ``overwrite`` / ``merge`` / ``inputs``), without
    locking or writing anything: for a command that reads its input before it opens its
    output folder, so that a bad ``--out`` is refused before any work.  Returns the folder
    (absolute)."""
    out_text = os.fspath(out) if isinstance(out, (str, os.PathLike)) else str(out)
    target = check_output_path(out, option=option)
    _check_link(out_text, overwrite, option)
    _inspect_existing(target, overwrite=overwrite, merge=merge, part=_part_hashes(scene),
                      command=command, option=option, out_text=out_text, inputs=inputs)
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
    # each entry's size and date (a nested output folder speaks for itself with its marker)
    stats = {rel: _stat_record(folder / rel.rstrip("/")) for rel in files
             if not (rel.endswith("/") and read_marker(folder / rel.rstrip("/")) is not None)}
    d = {"written_by": "render_inspect", "marker_version": MARKER_VERSION,
         "software_version": __version__, "files": dict(sorted(files.items())),
         "stat": dict(sorted(stats.items())), "commands": dict(sorted(commands.items()))}
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
                      command: str = "output", scene=None, option: str = "--out", inputs=()):
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
        deleted with the folder), even with ``overwrite``.

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
