"""OpenEXR read/write (float32 channels, JSON-text and typed header attributes).

OpenEXR 3.5's ``File(header, channels)`` mutates both dicts: we pass copies.  Python
floats are stored as float32 attributes, so exact doubles go in as JSON text
(``<name>_json``) beside the float attribute.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ._atomic import atomic_write_bytes
from ._limits import check_exr

_RESERVED = {"channels", "compression", "dataWindow", "displayWindow", "lineOrder",
             "pixelAspectRatio", "screenWindowCenter", "screenWindowWidth", "type", "name",
             "version", "chunkCount", "tiles"}


def write_exr(path: str | Path, channels: dict[str, np.ndarray], attrs: dict | None = None) -> Path:
    """Write float32 channels (all the same 2-D shape) and header attributes.

    Attribute values: str -> string; float/int -> float attribute plus exact JSON text;
    anything else (tuples, dicts) -> JSON text.  Read back with :func:`read_exr`.
    """
    import OpenEXR

    if not channels:
        raise InputError("write_exr: channels must not be empty")
    shape = None
    chans = {}
    for name, arr in channels.items():
        a = np.ascontiguousarray(arr, dtype=np.float32)
        if a.ndim != 2:
            raise InputError(f"write_exr: channel {name!r} must be 2-D, got shape {a.shape}")
        if shape is None:
            shape = a.shape
        elif a.shape != shape:
            raise InputError(f"write_exr: channel {name!r} has shape {a.shape}, expected {shape}")
        chans[name] = a
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
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
    tmp = path.with_name(f".{path.name}.tmp.exr")
    try:
        with OpenEXR.File(dict(header), dict(chans)) as f:
            f.write(str(tmp))
        data = tmp.read_bytes()
    finally:
        tmp.unlink(missing_ok=True)
    return atomic_write_bytes(path, data)


def _safe_repr(v) -> str:
    """repr of a header value (OpenEXR's opaque attributes may fail to print)."""
    try:
        text = repr(v)
    except Exception:  # an undecodable opaque attribute
        text = f"<{type(v).__name__}>"
    return text if len(text) <= 80 else text[:77] + "..."


def exr_placement(attrs: dict, *, what: str, path) -> tuple[float, tuple[float, float]]:
    """(pixel, (x, y)) from the ``pixel_size_mm`` and ``origin_mm`` header attributes,
    checked: a finite pixel > 0 and two finite numbers (mm); else :class:`InputError`."""
    for key in ("pixel_size_mm", "origin_mm"):
        if key not in attrs:
            raise InputError(f"{what} {str(path)!r}: the EXR header lacks {key!r}; it is needed "
                             f"to place the map in mm")
    p, o = attrs["pixel_size_mm"], attrs["origin_mm"]
    if isinstance(p, bool) or not isinstance(p, (int, float)) or not (math.isfinite(p) and p > 0):
        raise InputError(f"{what} {str(path)!r}: header pixel_size_mm must be a finite number > 0, "
                         f"received {_safe_repr(p)}")
    if not (isinstance(o, (list, tuple)) and len(o) == 2 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in o)):
        raise InputError(f"{what} {str(path)!r}: header origin_mm must be [x, y], two finite "
                         f"numbers (mm), received {_safe_repr(o)}")
    return float(p), (float(o[0]), float(o[1]))


def read_exr(path: str | Path, *, what: str = "EXR file", budget=None
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
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            header = dict(f.header())
            channels = {name: np.array(ch.pixels, dtype=np.float32, copy=True)
                        for name, ch in f.channels().items()}
    except Exception as err:  # OpenEXR raises RuntimeError/ValueError/OSError on damaged data
        raise InputError(f"{what} {str(path)!r} cannot be read: damaged or truncated EXR "
                         f"({type(err).__name__}: {err})") from None
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
