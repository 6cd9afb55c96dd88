"""Output folders, their names: ``--out`` checked before any work (not empty text, not a
file or a device, not under a file, writable, names not too long, not the current folder
or one holding it, no link replaced, no input inside), and render_inspect's own
temporary names beside it, told apart from the user's files."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any
import os
import re
import stat
import tempfile
from pathlib import Path

from ..core.errors import InputError

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


# ------------------------------------------------------------------------ --out checks
def _shown(text: str) -> str:
    return repr(text if len(text) <= 120 else text[:117] + "...")


def _name_max(folder: Path) -> int:
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def check_output_path(out: str | Path, *, option: str = "--out", replaced: bool = True) -> Path:
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


def scene_files(scene: Any) -> list[str]:
    """The files a scene reads: a height map design's ``path`` (a compound design's
    ``base`` and ``feature`` too), ``tool.edge_profile`` and ``process.program``, for the
    check that an output folder holds none of them."""
    if scene is None:
        return []
    d = scene.to_dict() if hasattr(scene, "to_dict") else scene
    found: list[str] = []

    def design(node: Any) -> None:
        if isinstance(node, dict):
            if isinstance(node.get("path"), str) and node["path"]:
                found.append(node["path"])
            for part in ("base", "feature"):
                design(node.get(part))

    if isinstance(d, dict):
        design(d.get("design"))
        for section, key in (("tool", "edge_profile"), ("process", "program")):
            value = (d.get(section) or {}).get(key) if isinstance(d.get(section), dict) else None
            if isinstance(value, str) and value:
                found.append(value)
    return found


def refuse_inputs_inside(out: str | Path, inputs: Iterable[Any], option: str = "--out") -> None:
    """Refuse ``out`` when it holds one of ``inputs`` (an existing folder that would be
    replaced with the input in it); nothing is checked or made otherwise."""
    out_text = os.fspath(out) if isinstance(out, (str, os.PathLike)) else str(out)
    target = check_output_path(out, option=option)
    if target.exists():
        _check_inputs(target, inputs, option, out_text)


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
