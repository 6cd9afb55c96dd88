"""Output folders, their marker (:data:`MARKER`): what render_inspect wrote there (each
file's size and modification time, the scene's hashes per command), and which of the
files a marker does not vouch for."""

from __future__ import annotations

import hashlib
import json
import os
import stat
from pathlib import Path
from typing import Any

from .. import __version__
from ..core.units import MIB_TO_BYTES
from ._atomic_write import json_safe
from ._outdir_names import _OS_JUNK, _own_temporary

__all__ = ["MARKER", "MARKER_VERSION", "part_hash", "read_marker", "write_marker"]

#: marker file in every output folder render_inspect writes (JSON)
MARKER = ".render_inspect.json"
#: the marker's layout: 2 records each file's size and modification time (``stat``)
MARKER_VERSION = 2
#: what the scene keys that shape the part are (a render may join a folder of the same part)
PART_SECTIONS = ("design", "tool", "process", "simulation", "artifacts", "rcse")
#: keys of those sections that do not shape the part: the memory budget of a run
NOT_PART = {"simulation": ("max_memory_gb",)}


# ------------------------------------------------------------------------ marker
def part_hash(scene: Any, *, legacy: bool = False) -> str | None:
    """SHA-256 of the scene keys that shape the part (:data:`PART_SECTIONS`, less
    :data:`NOT_PART`: the memory a run may use is no property of the part).  ``legacy``:
    the hash as folders written before that distinction recorded it."""
    if scene is None:
        return None
    d = scene.to_dict() if hasattr(scene, "to_dict") else dict(scene)
    part: dict[str, Any] = {k: d.get(k) for k in PART_SECTIONS}
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


def write_marker(folder: str | Path, *, command: str, scene: Any = None) -> None:
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
