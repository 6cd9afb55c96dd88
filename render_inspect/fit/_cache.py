"""Evaluations on disk, keyed by the hash of what determines them: the resolved scene (every
key, the fitted values included), the virtual instrument, the field and the software
version.  A fit that is run again (after an interruption, or with other options) takes the
evaluations it has already made from here instead of simulating them again.

An entry is trusted only when it proves itself: it carries the SHA-256 of its content (the
map's bytes, its shape, its metadata) together with its key, the fit's context (the scene's
and the measured window's hashes) and the software version; its size is checked before it
is decompressed (a small file that would inflate to gigabytes is refused unread) and its
map's shape against the fit's.  An entry that fails any check (altered, truncated, from
another fit, of the wrong shape) is reported once, recomputed and overwritten, never used."""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import shutil
import zipfile
from pathlib import Path
from typing import cast

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.units import MIB_TO_BYTES
from ..io import atomic_write_bytes

__all__ = ["EvaluationCache", "task_hash", "scene_hash", "content_hash", "MAX_ENTRY_BYTES"]

log = logging.getLogger("render_inspect")

#: largest entry (decompressed) read when the expected map shape is not known, bytes
MAX_ENTRY_BYTES = 256 * MIB_TO_BYTES
#: the entry's format (its content hash's rule)
ENTRY_FORMAT = 2


def scene_hash(scene: dict) -> str:
    """SHA-256 (hex) of a scene dictionary's canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(scene, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def task_hash(task: dict) -> str:
    """SHA-256 (hex) of the canonical JSON of an evaluation task and the software version."""
    text = json.dumps({"task": task, "software_version": __version__}, sort_keys=True,
                      separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def content_hash(key: str, height: np.ndarray, meta_text: str, context: dict) -> str:
    """SHA-256 (hex) of an entry: its key, the fit's ``context``, the software version,
    the map's shape and float32 bytes, its metadata's JSON text."""
    h = np.ascontiguousarray(np.asarray(height, dtype=np.float32))
    d = hashlib.sha256()
    head = json.dumps({"key": key, "context": context, "software_version": __version__,
                       "format": ENTRY_FORMAT, "shape": list(h.shape), "dtype": "float32"},
                      sort_keys=True, separators=(",", ":"), default=str)
    d.update(head.encode())
    d.update(h.tobytes())
    d.update(meta_text.encode())
    return d.hexdigest()


class EvaluationCache:
    """Predicted maps stored as ``<hash>.npz`` in ``folder`` (None: in memory only).

    ``context``: what else the entries must agree with (the scene's and the measured
    window's hashes); ``shape``: the predicted maps' shape, when known (an entry of
    another shape is refused, and the decompressed size is limited to it)."""

    def __init__(self, folder=None, *, context: dict | None = None, shape=None):
        self.folder = None if folder is None else Path(folder)
        self.context = dict(context or {})
        self.shape = None if shape is None else tuple(int(v) for v in shape)
        self.rejected: list = []  # (key, why) of entries refused and recomputed
        self._memory: dict = {}
        self.hits = 0
        self.written = 0          # entries this object stored on disk
        self._mine: list = []     # their keys (those not on disk before)
        self._made: list[Path] | None = None  # the folders this object created (the deepest last)
        if self.folder is not None:
            if self.folder.exists() and not self.folder.is_dir():
                raise InputError(f"--cache {str(self.folder)!r}: not a folder")
            probe = self.folder
            while not probe.exists() and probe != probe.parent:
                probe = probe.parent
            if not os.access(probe, os.W_OK):
                raise InputError(f"--cache {str(self.folder)!r}: "
                                 f"{'the folder' if probe == self.folder else str(probe)!r} "
                                 f"is not writable")

    def _create(self) -> None:
        """Create the folder on the first entry (a fit refused before it evaluates
        anything leaves none)."""
        if self._made is not None:
            return
        made = []
        p = folder = cast(Path, self.folder)  # (entries are written only with a folder)
        while not p.exists():
            made.append(p)
            p = p.parent
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise InputError(f"--cache {str(self.folder)!r}: cannot create the folder "
                             f"({err.strerror or err})") from None
        self._made = made

    def discard(self) -> None:
        """Remove what this object wrote: the folders it created with their entries, or
        its entries in a folder that was there before."""
        if self.folder is None or self._made is None:
            return
        if self._made:
            shutil.rmtree(self._made[-1], ignore_errors=True)
        else:
            for key in self._mine:
                with contextlib.suppress(OSError):
                    self._path(key).unlink()
        self._made, self._mine, self.written = None, [], 0

    def _path(self, key: str) -> Path:
        return cast(Path, self.folder) / f"{key}.npz"

    def get(self, key: str) -> tuple[np.ndarray, dict] | None:
        """(height, meta) or None."""
        if key in self._memory:
            self.hits += 1
            return self._memory[key]
        if self.folder is None:
            return None
        p = self._path(key)
        if not p.is_file():
            return None
        why = None
        try:
            h, meta, why = self._read(p, key)
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as err:
            why = f"unreadable ({type(err).__name__})"
        if why is not None:
            self.rejected.append((key, why))
            log.warning("cache entry %s: %s; it is recomputed, not used", p.name, why)
            return None
        self._memory[key] = (h, meta)
        self.hits += 1
        return h, meta

    def _limit(self) -> int:
        if self.shape is None:
            return MAX_ENTRY_BYTES
        return 4 * math.prod(self.shape) + MIB_TO_BYTES  # float32 map and its metadata

    def _read(self, p: Path, key: str):
        """(height, meta, None) or (None, None, why it is refused)."""
        limit = self._limit()
        if p.stat().st_size > limit:
            return None, None, f"{p.stat().st_size} bytes on disk, more than the {limit} allowed"
        with zipfile.ZipFile(p) as zf:
            infos = zf.infolist()
            total = sum(i.file_size for i in infos)
            names = sorted(i.filename for i in infos)
        if total > limit:
            return None, None, (f"would decompress to {total} bytes, more than the {limit} "
                                f"allowed")
        if names != ["digest.npy", "height.npy", "meta.npy"]:
            return None, None, "not an entry of this version (members " + ", ".join(names) + ")"
        with np.load(p, allow_pickle=False) as npz:
            raw = np.array(npz["height"])
            meta_text = str(npz["meta"])
            digest = str(npz["digest"])
        if raw.dtype != np.float32 or raw.ndim != 2:
            return None, None, f"holds a {raw.dtype} array of {raw.ndim} dimensions"
        if self.shape is not None and raw.shape != self.shape:
            return None, None, (f"holds a {raw.shape[0]} x {raw.shape[1]} map, the fit's "
                                f"are {self.shape[0]} x {self.shape[1]}")
        if digest != content_hash(key, raw, meta_text, self.context):
            return None, None, ("its content hash does not match (altered, or made for "
                                "another scene, measurement or software version)")
        return raw.astype(np.float64), json.loads(meta_text), None

    def put(self, key: str, height: np.ndarray, meta: dict) -> np.ndarray:
        """Store a map (as float32: what a later run reads back) and return it as read
        back, so that a fit run afresh and a fit resumed see the same numbers."""
        h = np.asarray(height, dtype=np.float32)
        self._memory[key] = (h.astype(np.float64), meta)
        if self.folder is None:
            return self._memory[key][0]
        import io

        buf = io.BytesIO()
        meta_text = json.dumps(meta, default=str)
        np.savez_compressed(buf, height=h, meta=np.array(meta_text),
                            digest=np.array(content_hash(key, h, meta_text, self.context)))
        self._create()
        existed = self._path(key).exists()
        atomic_write_bytes(self._path(key), buf.getvalue())
        if not existed:
            self._mine.append(key)
        self.written += 1
        return self._memory[key][0]

    def __len__(self) -> int:
        return len(self._memory)
