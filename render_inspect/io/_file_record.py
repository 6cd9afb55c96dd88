"""A record of an input file a run read: its path, size and SHA-256 (what a report's
provenance and a written program's header name)."""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

from ..core.units import MIB_TO_BYTES

__all__ = ["file_record"]

#: bytes read at a time while hashing a file
_CHUNK = MIB_TO_BYTES


def file_record(path: str | Path, role: str) -> dict:
    """``{"role", "path" (absolute), "bytes", "sha256"}`` of an input file; a folder (a
    ``.zarr`` store) or a file that cannot be read gets ``sha256`` None and ``note`` saying
    why."""
    p = Path(path)
    rec: dict[str, Any] = {"role": role, "path": str(p.resolve()), "bytes": None, "sha256": None}
    try:
        if p.is_dir():
            rec["note"] = "a folder (a store): not hashed"
            return rec
        h = hashlib.sha256()
        with open(p, "rb") as fh:
            for chunk in iter(lambda: fh.read(_CHUNK), b""):
                h.update(chunk)
        rec["sha256"] = h.hexdigest()
        rec["bytes"] = p.stat().st_size
    except OSError as err:
        rec["note"] = f"not read ({err.strerror or err})"
    return rec
