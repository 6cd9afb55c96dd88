"""Read measured height maps from instrument and exchange formats, in mm.

A registry keyed by file suffix (trimesh's habit): X3P via ``x3pio``; the project's own
``heightmap.exr``; ``.npy`` with a JSON side-car and ``.npz``; and the instrument formats
``surfalize`` reads (``.sur``, ``.plu``, ``.plux``, ``.sdf``, ``.al3d``, ``.vk4``, ``.opd``,
``.zon``, ...; surfalize gives micrometres, converted here).  Zygo ``.datx`` has no
well-kept Python reader in this environment: export such data to X3P.
"""

from __future__ import annotations

import math
import zipfile
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ._exr import exr_placement, read_exr
from ._limits import check_npy, check_npz, check_real_array, read_json_file
from ._registry import formats, reader, register_reader
from ._x3p import read_x3p

__all__ = ["read_measured", "measured_formats"]

_UNIT_TO_MM = {"mm": 1.0, "um": 1e-3, "µm": 1e-3, "nm": 1e-6, "m": 1e3}
_SURFALIZE = (".sur", ".plu", ".plux", ".sdf", ".al3d", ".vk4", ".vk6", ".vk7", ".opd",
              ".zon", ".gwy", ".tmd", ".os3d", ".nms", ".lext", ".oir", ".zmg", ".sflz", ".hdat")


def _to_mm(name: str, units) -> float:
    if not isinstance(units, str) or units not in _UNIT_TO_MM:
        raise InputError(f"{name}: units must be one of {sorted(_UNIT_TO_MM)}, got {units!r}")
    return _UNIT_TO_MM[units]


@register_reader("measured", ".x3p")
def _read_x3p(path, **_):
    return read_x3p(path, what="measured file")


@register_reader("measured", ".exr")
def _read_exr(path, *, channel=None, **_):
    ch, attrs = read_exr(path, what="measured file")
    if channel is None:
        for c in ("measured", "height", "machined", "Z", "z"):
            if c in ch:
                channel = c
                break
        else:
            if len(ch) != 1:
                raise InputError(f"{path}: EXR has channels {sorted(ch)}; say which with channel=")
            channel = next(iter(ch))
    if channel not in ch:
        raise InputError(f"{path}: EXR has no channel {channel!r} (channels: {sorted(ch)})")
    pixel, origin = exr_placement(attrs, what="measured file", path=path)
    scale = _to_mm(f"{path} header 'units'", attrs.get("units", "mm"))
    z = ch[channel].astype(np.float64) * scale
    return z, pixel, origin, {
        "format": "exr", "channel": channel, "scene": attrs.get("scene")}


def _sidecar_values(path, side: dict, pixel, origin, units):
    """pixel (mm), origin (x, y mm) and units from the arguments or the side-car, checked."""
    pixel = pixel if pixel is not None else side.get("pixel_mm")
    origin = origin if origin is not None else side.get("origin_mm", (0.0, 0.0))
    units = units or side.get("units", "mm")
    if pixel is not None and (isinstance(pixel, bool) or not isinstance(pixel, (int, float))
                              or not math.isfinite(pixel) or not pixel > 0):
        raise InputError(f"{path}: pixel_mm must be a finite number > 0 (mm), received {pixel!r}")
    if isinstance(origin, np.ndarray):
        origin = origin.tolist()
    if not (isinstance(origin, (list, tuple)) and len(origin) == 2 and all(
            isinstance(o, (int, float)) and not isinstance(o, bool) and math.isfinite(o)
            for o in origin)):
        raise InputError(f"{path}: origin_mm must be [x, y], two finite numbers (mm), received "
                         f"{origin!r}")
    if not isinstance(units, str):
        raise InputError(f"{path}: units must be one of {sorted(_UNIT_TO_MM)}, received {units!r}")
    return pixel, origin, units


@register_reader("measured", ".npy", ".npz")
def _read_numpy(path, *, pixel=None, origin=None, units=None, **_):
    path = Path(path)
    side = {}
    sidecar = path.with_suffix(".json")
    what = "measured file"
    try:
        if path.suffix.lower() == ".npz":
            members = check_npz(path, what=what)
            key = next((k for k in ("z", "height", "measured") if k in members), None)
            if key is None:
                raise InputError(f"{path}: .npz needs an array 'z' (heights), has {sorted(members)}")
            check_real_array(members[key][1], members[key][0], what=what, name=f"{path}:{key}")
            with np.load(path, allow_pickle=False) as npz:
                z = np.array(npz[key], dtype=np.float64)
                for k in ("pixel_mm", "origin_mm", "units"):
                    if k in npz.files:
                        side[k] = npz[k].tolist()
        else:
            check_npy(path, what=what)
            z = np.load(path, allow_pickle=False).astype(np.float64)
            if sidecar.is_file():
                side = read_json_file(sidecar, what=f"{what} side-car")
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as err:
        raise InputError(f"{what} {str(path)!r} cannot be read ({type(err).__name__}: {err})") from None
    pixel, origin, units = _sidecar_values(path, side, pixel, origin, units)
    if pixel is None:
        raise InputError(f"{path}: the pixel size is unknown; write {sidecar.name} with "
                         f'{{"pixel_mm": ..., "origin_mm": [x, y], "units": "mm"}} or pass pixel=')
    return z * _to_mm(f"{path} units", units), float(pixel), (float(origin[0]), float(origin[1])), {
        "format": path.suffix[1:], "units_in_file": units}


@register_reader("measured", *_SURFALIZE)
def _read_surfalize(path, **_):
    import warnings

    import surfalize

    try:
        with warnings.catch_warnings():  # non-square pixels: we raise a clearer error below
            warnings.filterwarnings("ignore", message=".*different pixel size.*")
            s = surfalize.Surface.load(str(path))
    except Exception as err:  # surfalize raises its own and builtin errors on corrupt files
        raise InputError(f"{path}: surfalize could not read it ({type(err).__name__}: {err})") from None
    z = np.asarray(s.data, dtype=np.float64) * 1e-3  # um -> mm
    if not np.isclose(s.step_x, s.step_y, rtol=1e-6):
        raise InputError(f"{path}: pixel sizes differ in x ({s.step_x * 1e-3:g} mm) and y "
                         f"({s.step_y * 1e-3:g} mm); resample to square pixels first")
    return z, float(s.step_x) * 1e-3, (0.0, 0.0), {"format": Path(path).suffix[1:],
                                                   "reader": f"surfalize {surfalize.__version__}"}


def measured_formats() -> list[str]:
    """File suffixes :func:`read_measured` reads."""
    return formats("measured")


def read_measured(path: str | Path, *, channel: str | None = None, pixel: float | None = None,
                  origin=None, units: str | None = None):
    """Read a measured (or exported) height map.

    Parameters
    ----------
    path : str or Path
        ``.x3p``, ``.exr`` (our ``heightmap.exr`` or any EXR with ``pixel_size_mm`` /
        ``origin_mm`` header attributes), ``.npy`` (+ ``<name>.json`` side-car with
        ``pixel_mm``, ``origin_mm``, ``units``), ``.npz`` (arrays ``z``, ``pixel_mm``,
        ``origin_mm``, ``units``) or an instrument format read by surfalize
        (see :func:`measured_formats`).
    channel : str, optional
        EXR channel (default: ``measured``, ``height``, ``machined``, or the only one).
    pixel, origin, units : optional
        For ``.npy``/``.npz`` without that information: pixel (mm), origin of pixel [0, 0]
        (mm), and the unit of the heights ("mm", "um", "nm", "m").

    Returns
    -------
    z : (ny, nx) float64 array
        Heights in mm, NaN where not measured; row 0 = smallest y.
    pixel : float
        mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    meta : dict
        ``format`` and what the file says about itself; ``path``; ``valid_fraction``.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".datx":
        raise InputError(f"{path}: Zygo .datx has no well-kept reader here; export the map to X3P "
                         f"(Mx: File > Save Data As > .x3p) and read that")
    read = reader("measured", path)
    if not path.is_file():
        raise InputError(f"measured file not found: {str(path)!r}")
    z, pixel_mm, origin_mm, meta = read(path, channel=channel, pixel=pixel, origin=origin,
                                        units=units)
    if z.ndim != 2 or min(z.shape) < 2:
        raise InputError(f"{path}: expected a 2-D height map of at least 2 x 2 points, got shape {z.shape}")
    if not pixel_mm > 0 or not np.isfinite(pixel_mm):
        raise InputError(f"{path}: pixel size must be > 0 mm, got {pixel_mm!r}")
    z = np.where(np.isinf(z), np.nan, z)
    valid = float(np.isfinite(z).mean())
    if valid == 0.0:
        raise InputError(f"{path}: the map has no valid (finite) heights")
    meta.update({"path": str(path), "valid_fraction": valid})
    return z, float(pixel_mm), (float(origin_mm[0]), float(origin_mm[1])), meta
