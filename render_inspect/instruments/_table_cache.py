"""The imaging model's tables kept on disk between processes.

The transfer function's table, the pupil's unit table and the facets' acceptance table
(:mod:`._transfer`) depend only on their arguments (the apertures, the source's spectrum,
the axial bin spacing and the table sizes), yet take one to three seconds to build.  A
process that builds one writes it to the user's cache folder, and the next process that
asks for the same arguments reads it back instead, as numba keeps its compiled kernels:

* the folder is ``$XDG_CACHE_HOME/render_inspect/tables`` (``~/.cache/render_inspect/tables``
  when ``XDG_CACHE_HOME`` is not set); ``RENDER_INSPECT_TABLE_CACHE=off`` turns the cache
  off (every process builds its tables), and an unwritable folder leaves it off quietly;
* an entry is named by a SHA-256 of the table's name, its arguments written exactly
  (floats as their hexadecimal form), the package's version and the source text of the
  modules whose code builds it (the tables' and, for the transfer function, the
  source's sampling), so a change to any of them builds afresh;
* an entry is written to a temporary file in the folder and renamed into place (two
  processes building the same table leave one whole file), and holds a SHA-256 of its
  arrays: an entry that cannot be read, or whose arrays do not match it (a damaged or
  altered file), is built again and written anew.

A table read back is the table built, bit for bit (the arrays are stored as they are).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .. import __version__

__all__ = ["TABLE_CACHE_ENV", "cached_arrays", "table_cache_dir", "table_key", "STATS"]

#: Environment variable that turns the cache off (``off``, ``0``, ``no`` or ``false``).
TABLE_CACHE_ENV = "RENDER_INSPECT_TABLE_CACHE"
_FORMAT = 1
#: What this process did (``built``, ``loaded``, ``rebuilt``: an entry that failed its check).
STATS = {"built": 0, "loaded": 0, "rebuilt": 0}
_SOURCE_SHA: dict[str, str] = {}


def table_cache_dir() -> Path | None:
    """The folder of the cached tables, or None when the cache is off."""
    if os.environ.get(TABLE_CACHE_ENV, "").strip().lower() in ("off", "0", "no", "false"):
        return None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "render_inspect" / "tables"


def _exact(v):
    """``v`` as JSON whose text names its value exactly (floats by their hex form)."""
    if isinstance(v, (bool, np.bool_)) or v is None or isinstance(v, str):
        return v
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        f = float(v)
        return {"float": f.hex()} if math.isfinite(f) else {"float": repr(f)}
    if isinstance(v, dict):
        return {str(k): _exact(x) for k, x in sorted(v.items())}
    if isinstance(v, (list, tuple)):
        return [_exact(x) for x in v]
    raise TypeError(f"table cache: cannot key an argument of type {type(v).__name__}")


def _source_sha(module_file: str) -> str:
    sha = _SOURCE_SHA.get(module_file)
    if sha is None:
        try:
            sha = hashlib.sha256(Path(module_file).read_bytes()).hexdigest()
        except OSError:
            sha = "unreadable"
        _SOURCE_SHA[module_file] = sha
    return sha


def table_key(name: str, args: dict, module_file: str | tuple[str, ...]) -> str:
    """The entry's name: a SHA-256 of ``name``, ``args``, the package's version and the
    text of ``module_file`` (the module, or modules, whose code builds the table)."""
    files = (module_file,) if isinstance(module_file, str) else tuple(module_file)
    text = json.dumps({"table": name, "args": _exact(args), "version": __version__,
                       "module": [_source_sha(f) for f in files], "format": _FORMAT},
                      sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _digest(key: str, arrays: dict) -> str:
    h = hashlib.sha256(key.encode())
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _load(path: Path, key: str) -> dict | None:
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except FileNotFoundError:
        return None
    except Exception:  # a damaged file: np.load raises ValueError, OSError, zipfile errors
        return {}
    check = arrays.pop("_sha256", None)
    if check is None or str(check) != _digest(key, arrays):
        return {}
    return arrays


def _store(folder: Path, path: Path, key: str, arrays: dict) -> None:
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp", dir=folder)
    except OSError:
        return  # an unwritable cache folder: the table is used, not kept
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez(f, _sha256=np.array(_digest(key, arrays)), **arrays)
        os.replace(tmp, path)
    except OSError:
        pass
    finally:
        if os.path.exists(tmp):
            try:
                os.unlink(tmp)
            except OSError:
                pass


def cached_arrays(name: str, args: dict, module_file: str | tuple[str, ...],
                  build: Callable[[], dict]) -> dict:
    """The arrays ``build()`` returns (a dict of numpy arrays) for the table ``name`` with
    arguments ``args``, read from the cache when an entry for them is there and whole,
    else built and written to it."""
    folder = table_cache_dir()
    if folder is None:
        STATS["built"] += 1
        return build()
    key = table_key(name, args, module_file)
    path = folder / f"{name}-{key[:40]}.npz"
    got = _load(path, key)
    if got:
        STATS["loaded"] += 1
        return got
    STATS["rebuilt" if got is not None else "built"] += 1
    arrays = build()
    _store(folder, path, key, {k: np.asarray(v) for k, v in arrays.items()})
    return arrays
