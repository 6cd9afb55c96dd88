"""Evaluations on disk, keyed by the hash of what determines them: the resolved scene (every
key, the fitted values included), the virtual instrument, the field and the software
version.  A fit that is run again (after an interruption, or with other options) takes the
evaluations it has already made from here instead of simulating them again."""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..io import atomic_write_bytes

__all__ = ["EvaluationCache", "task_hash", "scene_hash"]


def scene_hash(scene: dict) -> str:
    """SHA-256 (hex) of a scene dictionary's canonical JSON (sorted keys, no spaces)."""
    text = json.dumps(scene, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def task_hash(task: dict) -> str:
    """SHA-256 (hex) of the canonical JSON of an evaluation task and the software version."""
    text = json.dumps({"task": task, "software_version": __version__}, sort_keys=True,
                      separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


class EvaluationCache:
    """Predicted maps stored as ``<hash>.npz`` in ``folder`` (None: in memory only)."""

    def __init__(self, folder=None):
        self.folder = None if folder is None else Path(folder)
        self._memory: dict = {}
        self.hits = 0
        self.written = 0          # entries this object stored on disk
        self._mine: list = []     # their keys (those not on disk before)
        self._made = None         # the folders this object created (the deepest last)
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
        p = self.folder
        while not p.exists():
            made.append(p)
            p = p.parent
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
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
        return self.folder / f"{key}.npz"

    def get(self, key: str):
        """(height, meta) or None."""
        if key in self._memory:
            self.hits += 1
            return self._memory[key]
        if self.folder is None:
            return None
        p = self._path(key)
        if not p.is_file():
            return None
        try:
            with np.load(p, allow_pickle=False) as npz:
                h = np.array(npz["height"], dtype=np.float64)
                meta = json.loads(str(npz["meta"]))
        except (OSError, ValueError, KeyError, EOFError):
            return None  # a damaged entry is made again
        self._memory[key] = (h, meta)
        self.hits += 1
        return h, meta

    def put(self, key: str, height, meta: dict) -> np.ndarray:
        """Store a map (as float32: what a later run reads back) and return it as read
        back, so that a fit run afresh and a fit resumed see the same numbers."""
        h = np.asarray(height, dtype=np.float32)
        self._memory[key] = (h.astype(np.float64), meta)
        if self.folder is None:
            return self._memory[key][0]
        import io

        buf = io.BytesIO()
        np.savez_compressed(buf, height=h, meta=np.array(json.dumps(meta, default=str)))
        self._create()
        existed = self._path(key).exists()
        atomic_write_bytes(self._path(key), buf.getvalue())
        if not existed:
            self._mine.append(key)
        self.written += 1
        return self._memory[key][0]

    def __len__(self) -> int:
        return len(self._memory)
