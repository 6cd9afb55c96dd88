"""OpenEXR read/write (float32 channels, JSON-text and typed header attributes).

OpenEXR 3.5's ``File(header, channels)`` mutates both dicts: we pass copies.  Python
floats are stored as float32 attributes, so exact doubles go in as JSON text
(``<name>_json``) beside the float attribute.

Large maps are written *tiled* (square tiles, so a reader can decode only the tiles of
a window) with an optional *overview*: a second part named ``overview`` holding an
area-averaged copy of the channels (factor ``overview_factor``; see
``render_inspect.io._pyramid``).  The Python binding of OpenEXR 3.5 cannot write
MIPMAP_LEVELS files (it writes level 0 only and leaves the file unreadable), hence the
two-part layout; readers that know only single-part files read part 0, the full map.
Compression is a choice of speed against size, measured on a 16 M-sample height map
(float32, 3 channels, one core): none 0.15 s / 192 MB, zstd 1.2 s / 51 MB, zip 2.1 s /
117 MB, piz 5 s / 147 MB.  A file is compressed by OpenEXR's own threads, one per usable
CPU, while it is written (:func:`compression_threads`): each block of lines or tile is
compressed alone and written in its place, so the file's bytes are those one thread
writes.
"""

from __future__ import annotations

from collections.abc import Iterator
import contextlib
import json
import math
import os
import threading
from pathlib import Path
from typing import Any, cast

import numpy as np
from ..core.lazy import njit  # numba, imported on first use
from ..core.threads import over_rows

from ..core.errors import InputError
from ..core.limits import usable_cpus
from ._atomic import _umask
from ._limits import check_exr
from ._native import library_messages
from ._pyramid import heightmap_block_sums, level_count, means
from ._write_errors import write_errors

_RESERVED = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder",
             "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type", "name",
             "version", "chunkCount", "tiles"}

#: compression names accepted by :func:`write_exr`
COMPRESSIONS = {"none": "NO_COMPRESSION", "rle": "RLE_COMPRESSION", "zips": "ZIPS_COMPRESSION",
                "zip": "ZIP_COMPRESSION", "piz": "PIZ_COMPRESSION", "zstd": "ZSTD_COMPRESSION"}

_POOL_LOCK = threading.Lock()
_POOL_USERS = 0


@contextlib.contextmanager
def compression_threads() -> Iterator[None]:
    """OpenEXR's process-wide thread pool holds one thread per usable CPU
    (:func:`~render_inspect.core.limits.usable_cpus`) while files are written in this
    block, and none after the last writer leaves it (no idle threads are left behind for
    a later ``fork`` to lose)."""
    import OpenEXR

    global _POOL_USERS
    n = usable_cpus()
    if n <= 1:
        yield
        return
    with _POOL_LOCK:
        if _POOL_USERS == 0:
            OpenEXR.set_global_thread_count(n)
        _POOL_USERS += 1
    try:
        yield
    finally:
        with _POOL_LOCK:
            _POOL_USERS -= 1
            if _POOL_USERS == 0:
                OpenEXR.set_global_thread_count(0)


def _channels(channels: dict, what: str) -> tuple[dict, tuple]:
    shape = None
    chans = {}
    for name, arr in channels.items():
        a = np.ascontiguousarray(arr, dtype=np.float32)
        if a.ndim != 2:
            raise InputError(f"write_exr: {what}channel {name!r} must be 2-D, got shape {a.shape}")
        if shape is None:
            shape = a.shape
        elif a.shape != shape:
            raise InputError(f"write_exr: {what}channel {name!r} has shape {a.shape}, expected {shape}")
        chans[name] = a
    return chans, cast(tuple, shape)  # (callers give at least one channel: a shape)


def write_exr(path: str | Path, channels: dict[str, np.ndarray], attrs: dict | None = None, *,
              compression: str = "zip", tile: int | None = None,
              overview: dict[str, np.ndarray] | None = None, overview_factor: int | None = None) -> Path:
    """Write float32 channels (all the same 2-D shape) and header attributes.

    Attribute values: str -> string; float/int -> float attribute plus exact JSON text;
    anything else (tuples, dicts) -> JSON text.  Read back with :func:`read_exr`.

    Parameters
    ----------
    path : str or Path
        Written atomically (a temporary file in the same folder, renamed into place).
    channels : dict of (ny, nx) arrays
        Stored as float32.
    attrs : dict, optional
        Header attributes.
    compression : str
        One of ``COMPRESSIONS`` (see the module notes for speed and size).
    tile : int, optional
        Tile side in pixels (tiled file); scanlines if None.
    overview : dict of arrays, optional
        Reduced copies of (some of) the channels, written as a second part ``overview``.
    overview_factor : int, optional
        Their reduction factor, stored as the overview's ``overview_factor`` attribute.
    """
    import OpenEXR

    if not channels:
        raise InputError("write_exr: channels must not be empty")
    if compression not in COMPRESSIONS:
        raise InputError(f"write_exr: compression must be one of {sorted(COMPRESSIONS)}, got {compression!r}")
    chans, shape = _channels(channels, "")
    comp = getattr(OpenEXR, COMPRESSIONS[compression])
    header = {"compression": comp, "type": OpenEXR.scanlineimage}
    if tile is not None:
        if not 1 <= int(tile) <= 65536:
            raise InputError(f"write_exr: tile must be in [1, 65536] pixels, got {tile!r}")
        td = OpenEXR.TileDescription()
        td.xSize = td.ySize = int(tile)
        td.mode = OpenEXR.ONE_LEVEL
        header.update(type=OpenEXR.tiledimage, tiles=td)
    meta = {}
    for k, v in (attrs or {}).items():
        if k in _RESERVED:
            raise InputError(f"write_exr: attribute name {k!r} is reserved by OpenEXR")
        if isinstance(v, str):
            header[k] = v
        elif isinstance(v, (bool, np.bool_)):
            header[k] = "true" if v else "false"
        elif isinstance(v, (int, float, np.integer, np.floating)):
            header[k] = float(v)
            meta[k] = float(v) if isinstance(v, (float, np.floating)) else int(v)
        else:
            header[k] = json.dumps(v, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
    header["render_inspect_attrs_json"] = json.dumps(meta)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.exr")
    try:
        if overview:
            ov, oshape = _channels(overview, "overview ")
            window = (np.array([0, 0], dtype=np.int32), np.array([shape[1] - 1, shape[0] - 1], dtype=np.int32))
            oheader = {"compression": comp, "type": OpenEXR.scanlineimage, "displayWindow": window,
                       "dataWindow": (np.array([0, 0], dtype=np.int32),
                                      np.array([oshape[1] - 1, oshape[0] - 1], dtype=np.int32)),
                       "overview_factor": float(overview_factor or 0),
                       "render_inspect_attrs_json": json.dumps({"overview_factor": int(overview_factor or 0)})}
            parts = [OpenEXR.Part(dict(header), dict(chans), "heightmap"), OpenEXR.Part(oheader, dict(ov), "overview")]
            with write_errors(path), compression_threads(), OpenEXR.File(parts) as f:
                f.write(str(tmp))
        else:
            with write_errors(path), compression_threads(), \
                    OpenEXR.File(dict(header), dict(chans)) as f:
                f.write(str(tmp))
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def read_exr_overview(path: str | Path) -> tuple[dict[str, np.ndarray], int] | None:
    """The ``overview`` part of a file written by :func:`write_exr` with an overview:
    (channels, factor), or None if the file has none."""
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise InputError(f"EXR file not found: {str(path)!r}")
    h, w, n = check_exr(path, what="EXR file")
    try:
        with OpenEXR.File(str(path), header_only=True) as f:
            if len(f.parts) < 2:
                return None
            (x0, y0), (x1, y1) = (tuple(int(v) for v in p) for p in f.parts[1].header["dataWindow"])
        # the overview is a reduced copy: never larger than the full map
        if (x1 - x0 + 1) * (y1 - y0 + 1) > h * w:
            raise InputError(f"EXR file {str(path)!r}: its overview part is larger than the map")
        with library_messages(), OpenEXR.File(str(path), separate_channels=True) as f:
            p = f.parts[1]
            chans = {name: np.array(ch.pixels, dtype=np.float32, copy=True)
                     for name, ch in p.channels.items()}
            meta = json.loads(dict(p.header).get("render_inspect_attrs_json", "{}"))
        factor = int(meta.get("overview_factor", 0)) if isinstance(meta, dict) else 0
    except InputError:
        raise
    except Exception as err:  # OpenEXR raises RuntimeError/ValueError/OSError on damaged data
        raise InputError(f"EXR file {str(path)!r}: the overview part cannot be read "
                         f"({type(err).__name__}: {err})") from None
    return chans, factor


def _safe_repr(v) -> str:
    """repr of a header value (OpenEXR's opaque attributes may fail to print)."""
    try:
        text = repr(v)
    except Exception:  # an undecodable opaque attribute
        text = f"<{type(v).__name__}>"
    return text if len(text) <= 80 else text[:77] + "..."


def _positive_number(v) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) and v > 0


def exr_placement(attrs: dict, *, what: str, path: str | Path,
                  pair: bool = False) -> tuple[Any, tuple[float, float]]:
    """(pixel, (x, y)) from the ``pixel_size_mm`` and ``origin_mm`` header attributes,
    checked: a finite pixel > 0 and two finite numbers (mm); else :class:`InputError`.
    With ``pair`` the pixel may also be ``[x, y]`` and comes back as (pixel_x, pixel_y)."""
    for key in ("pixel_size_mm", "origin_mm"):
        if key not in attrs:
            raise InputError(f"{what} {str(path)!r}: the EXR header lacks {key!r}; it is needed "
                             f"to place the map in mm")
    p, o = attrs["pixel_size_mm"], attrs["origin_mm"]
    if pair and isinstance(p, (list, tuple)) and len(p) == 2 and all(_positive_number(v) for v in p):
        p = (float(p[0]), float(p[1]))
    elif _positive_number(p):
        p = (float(p), float(p)) if pair else float(p)
    else:
        allowed = "a finite number > 0 (or [x, y] of them)" if pair else "a finite number > 0"
        raise InputError(f"{what} {str(path)!r}: header pixel_size_mm must be {allowed}, "
                         f"received {_safe_repr(p)}")
    if not (isinstance(o, (list, tuple)) and len(o) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in o)):
        raise InputError(f"{what} {str(path)!r}: header origin_mm must be [x, y], two finite "
                         f"numbers (mm), received {_safe_repr(o)}")
    return p, (float(o[0]), float(o[1]))


def read_exr(path: str | Path, *, what: str = "EXR file",
             budget: int | tuple[int, str] | None = None
             ) -> tuple[dict[str, np.ndarray], dict]:
    """Return (channels, attrs).  Numbers come back exact (from the JSON text);
    JSON-text attributes are decoded.

    The header is checked first (:func:`~render_inspect.io._limits.check_exr`: a real EXR
    whose data window fits ``budget``); a damaged file raises :class:`InputError` naming
    ``what``."""
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{what}: EXR file not found: {str(path)!r}")
    check_exr(path, what=what, budget=budget)
    held = None
    try:
        with library_messages() as held, OpenEXR.File(str(path), separate_channels=True) as f:
            header = dict(f.header())
            channels = {name: np.array(ch.pixels, dtype=np.float32, copy=True)
                        for name, ch in f.channels().items()}
    except Exception as err:  # OpenEXR raises RuntimeError/ValueError/OSError on damaged data
        raise InputError(f"{what} {str(path)!r} cannot be read: damaged or truncated EXR "
                         f"({type(err).__name__}: {err}{held.summary() if held else ''})") from None
    exact = {}
    if "render_inspect_attrs_json" in header:
        try:
            exact = json.loads(header.pop("render_inspect_attrs_json"))
        except (TypeError, ValueError):
            raise InputError(f"{what} {str(path)!r}: damaged render_inspect_attrs_json "
                             f"attribute") from None
        if not isinstance(exact, dict):
            exact = {}
    attrs = {}
    for k, v in header.items():
        if k in _RESERVED:
            continue
        if k in exact:
            attrs[k] = exact[k]
        elif isinstance(v, str):
            try:
                attrs[k] = json.loads(v) if v[:1] in "[{\"" else v
            except json.JSONDecodeError:
                attrs[k] = v
        elif isinstance(v, bytes):
            attrs[k] = v.decode("utf-8", "replace")
        else:
            attrs[k] = v
    return channels, attrs


#: heightmap.exr: tile side (pixels) and compression (see the module notes: the write
#: costs less than the simulation; zstd would make the file 3.7 x smaller for 8 x the time)
HEIGHTMAP_TILE = 256
HEIGHTMAP_COMPRESSION = "none"
#: the overview part's larger side is at most this many pixels
OVERVIEW_SIDE = 1024


@njit(cache=True, nogil=True)
def _to_float32(design, machined, d32, m32, r32, i0, i1):
    for i in range(i0, i1):
        for j in range(design.shape[1]):
            d = design[i, j]
            m = machined[i, j]
            d32[i, j] = d
            m32[i, j] = m
            r32[i, j] = m - d


def heightmap_channels(design: np.ndarray, machined: np.ndarray) -> dict[str, np.ndarray]:
    """float32 ``design``, ``machined`` and ``residual`` (machined - design formed in
    float64, then rounded) in one pass: no float64 temporary of the map."""
    out = {k: np.empty(design.shape, dtype=np.float32) for k in ("design", "machined", "residual")}
    over_rows(_to_float32, design.shape[0], np.ascontiguousarray(design, dtype=np.float64),
              np.ascontiguousarray(machined, dtype=np.float64), out["design"], out["machined"], out["residual"])
    return out


def write_height_channels(path: str | Path, design: np.ndarray, machined: np.ndarray, attrs: dict, *,
                          compression: str = HEIGHTMAP_COMPRESSION, tile: int = HEIGHTMAP_TILE,
                          overview_side: int = OVERVIEW_SIDE, overview: dict | None = None) -> Path:
    """heightmap.exr: channels design, machined, residual (float32, mm), tiled, with an
    area-averaged overview part when the map is larger than ``overview_side``
    (``overview``: :func:`heightmap_overview`, when the caller already has it)."""
    if overview is None:
        overview = heightmap_overview(design, machined, overview_side)
    ch = heightmap_channels(design, machined)
    return write_exr(path, ch, attrs, compression=compression, tile=tile, overview=overview["means"] or None,
                     overview_factor=overview["factor"] if overview["means"] else None)


def heightmap_overview(design: np.ndarray, machined: np.ndarray, side: int = OVERVIEW_SIDE) -> dict:
    """The overview of a map: ``factor`` (the smallest power of two that brings its larger
    side to at most ``side`` pixels), ``means`` (float32 block means of design, machined
    and residual; empty when the factor is 1) and ``residual`` (the residual's block sums
    and counts, for coarser previews)."""
    k = level_count(design.shape, smallest=side)
    if k == 0:
        return {"factor": 1, "means": {}, "residual": None}
    sums = heightmap_block_sums(design, machined, 2 ** k)
    return {"factor": 2 ** k, "means": {name: means(*sc) for name, sc in sums.items()},
            "residual": sums["residual"]}
