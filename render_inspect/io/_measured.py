"""Read measured height maps from instrument and exchange formats, in mm.

One reader per file suffix, chosen for reading that format correctly (checked against
the values published with real instrument files, see docs/metrology.md):

- SurfaceTopography (the reference library of contact.engineering): Zygo MetroPro
  ``.dat`` and ``.datx``, Sensofar ``.plu`` / ``.plux``, Wyko ``.opd`` / ``.opdx``, Alicona
  ``.al3d``, Keyence ``.vk3`` .. ``.vk7``, Olympus ``.lext`` / ``.oir``, Gwyddion ``.gwy``,
  FRT ``.frt``, ``.zon``;
- x3pio: ISO 25178-72 ``.x3p`` (with our own parser for files whose ``main.xml`` lacks
  the ISO 5436-2 namespace);
- surfalize: Digital Surf ``.sur`` (SurfaceTopography 1.18.2 reads its non-measured points
  as heights) and the formats only it knows (``.sdf``, ``.os3d``, ``.zmg``, ``.sflz``,
  ``.hdat``);
- our own parsers: TrueMap / GelSight ``.tmd`` (mm), NanoFocus ``.nms``;
- the project's ``heightmap.exr``, ``.npy`` + JSON side-car, ``.npz``.

Every reader returns heights in mm, the pixel as ``(pixel_x, pixel_y)`` in mm (never
squared), and the units the file itself declares (``meta["units_in_file"]``).
"""

from __future__ import annotations

from collections.abc import Sequence
import math
import warnings
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.units import MIB_TO_BYTES, UM_TO_MM
from ..core.errors import InputError
from ..core.limits import (MAX_ABS_MM, MAX_FIELD_MM, MOSTLY_EMPTY_FRACTION, PIXEL_RANGE_MM,
                           mostly_empty_warning)
from . import _wyko
from ._exr import exr_placement, read_exr
from ._frt import reader_keeps_stored_order
from ._instrument import (al3d_header, finish, format_name, frt_header,
                          instrument_text, library_header, metropro_header, opd_header,
                          plu_header)
from ._limits import (
    check_file_values,
    check_npy,
    check_npz,
    check_real_array,
    check_values,
    check_zip,
    read_json_file,
    reading_for,
)
from ._registry import formats, reader, register_reader
from ._special import not_a_file
from ._sur import sur_offset_fix
from ._vendor import read_nms, read_tmd
from ._x3p import read_x3p_xy
from ._zarr import ZarrHeightMap, zarr_read_overhead

__all__ = ["MeasuredMap", "read_surface", "read_measured", "measured_formats",
           "reader_for", "UNIT_TO_MM", "PIXEL_RANGE_MM", "MAX_FIELD_MM", "MAX_ABS_MM",
           "MOSTLY_EMPTY_FRACTION", "mostly_empty_warning"]

#: Length units a file may declare, in mm.
UNIT_TO_MM = {"m": 1e3, "mm": 1.0, "um": 1e-3, "µm": 1e-3, "μm": 1e-3, "nm": 1e-6,
              "pm": 1e-9, "Å": 1e-7, "A": 1e-7}

_LIBRARY: dict = {}  # suffix -> name of the library that reads it


def _register(*suffixes, name: str):
    """Register ``fn`` as the ``measured`` reader of ``suffixes`` (io's registry) and
    remember which library it uses."""
    def deco(fn):
        for s in suffixes:
            _LIBRARY[s] = name
        return register_reader("measured", *suffixes)(fn)
    return deco


def _to_mm(name: str, units) -> float:
    if not isinstance(units, str) or units not in UNIT_TO_MM:
        raise InputError(f"{name}: units must be one of {sorted(UNIT_TO_MM)}, got {units!r}")
    return UNIT_TO_MM[units]


@dataclass(frozen=True)
class MeasuredMap:
    """A height map read from a file.

    Attributes
    ----------
    z : (ny, nx) float64 array
        Heights, mm; NaN where not measured.  Row 0 is the first row the reader gives
        (for X3P: the smallest y).
    pixel : (pixel_x, pixel_y)
        Sampling distances along x (columns) and y (rows), mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    meta : dict
        ``format``, ``format_name``, ``reader``, ``units_in_file`` (what the file
        declares; ``units_in_file_from``: where that is said), ``path``,
        ``valid_fraction``, ``n_invalid``, ``instrument`` (one line: what the header names,
        or "not stated in the file"), ``instrument_fields``, ``date`` and what else the
        file says about itself.
    """

    z: np.ndarray
    pixel: tuple
    origin: tuple
    meta: dict = field(default_factory=dict)

    @property
    def shape(self) -> tuple:
        return tuple(self.z.shape)

    @property
    def square(self) -> bool:
        """True when the two sampling distances agree to 1e-6."""
        return bool(np.isclose(self.pixel[0], self.pixel[1], rtol=1e-6, atol=0))

    @property
    def extent(self) -> tuple:
        """(x0, x1, y0, y1) of the pixel edges, mm (for ``imshow(origin="lower")``)."""
        (px, py), (ox, oy) = self.pixel, self.origin
        ny, nx = self.z.shape
        return (ox - px / 2, ox + px * (nx - 0.5), oy - py / 2, oy + py * (ny - 0.5))


# -- readers ------------------------------------------------------------------------------

#: what the readers' messages call the file
_WHAT = "measured file"
#: the instrument of a map render_inspect simulated
_SIMULATED = "none: a height map simulated by render_inspect"


@_register(".x3p", name="x3pio")
def _read_x3p(path, **_):
    return read_x3p_xy(path, what=_WHAT)


@_register(".exr", name="render_inspect")
def _read_exr(path, *, channel=None, **_):
    ch, attrs = read_exr(path, what=_WHAT)
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
    pxy, origin = exr_placement(attrs, what=_WHAT, path=path, pair=True)
    units = attrs.get("units", "mm")
    z = ch[channel].astype(np.float64) * _to_mm(f"{path} header 'units'", units)
    return z, pxy, origin, {
        "format": "exr", "channel": channel, "scene": attrs.get("scene"),
        "units_in_file": {"lateral": "mm", "vertical": units},
        "units_in_file_from": "header: pixel_size_mm (mm) and units",
        **({"instrument": _SIMULATED} if attrs.get("scene") else {})}


@_register(".zarr", name="zarr")
def _read_zarr(path, *, channel=None, region=None, **_):
    z = ZarrHeightMap(path, what=_WHAT)
    channel = channel or "machined"
    rows, cols = z.index_window(region) if region is not None else (slice(0, z.shape[0]), slice(0, z.shape[1]))
    # the window's values, and the chunks zarr decodes at once to fill it
    check_values(path, what=_WHAT, desc=f"a {rows.stop - rows.start} x {cols.stop - cols.start} window",
                 count=(rows.stop - rows.start) * (cols.stop - cols.start),
                 extra_bytes=zarr_read_overhead(z, rows, cols))
    data = z.read(channel, rows, cols).astype(np.float64)
    origin = (z.origin[0] + cols.start * z.pixel, z.origin[1] + rows.start * z.pixel)
    return data, (z.pixel, z.pixel), origin, {"format": "zarr", "channel": channel,
                                              "store_shape": list(z.shape),
                                              "instrument": _SIMULATED,
                                              "units_in_file": {"lateral": "mm", "vertical": "mm"},
                                              "units_in_file_from": "the store: mm"}


def _finite_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _sidecar_values(path, side: dict, pixel, origin, units):
    """pixel ((x, y) mm, or None), origin (x, y mm) and units from the arguments or the
    side-car, checked."""
    pixel = pixel if pixel is not None else side.get("pixel_mm")
    origin = origin if origin is not None else side.get("origin_mm", (0.0, 0.0))
    units = units or side.get("units", "mm")
    if isinstance(pixel, np.ndarray):
        pixel = pixel.tolist()
    if isinstance(pixel, np.generic):
        pixel = pixel.item()
    if pixel is not None:
        pxy = [pixel, pixel] if not isinstance(pixel, (list, tuple)) else list(pixel)
        if len(pxy) != 2 or not all(_finite_number(v) and v > 0 for v in pxy):
            raise InputError(f"{path}: pixel_mm must be a finite number > 0 (or [x, y] of them) "
                             f"(mm), received {pixel!r}")
        pixel = (float(pxy[0]), float(pxy[1]))
    if isinstance(origin, np.ndarray):
        origin = origin.tolist()
    if not (isinstance(origin, (list, tuple)) and len(origin) == 2
            and all(_finite_number(o) for o in origin)):
        raise InputError(f"{path}: origin_mm must be [x, y], two finite numbers (mm), received "
                         f"{origin!r}")
    if not isinstance(units, str):
        raise InputError(f"{path}: units must be one of {sorted(UNIT_TO_MM)}, received {units!r}")
    return pixel, (float(origin[0]), float(origin[1])), units


@_register(".npy", ".npz", name="numpy")
def _read_numpy(path, *, pixel=None, origin=None, units=None, **_):
    path = Path(path)
    side = {}
    sidecar = path.with_suffix(".json")
    try:
        if path.suffix.lower() == ".npz":
            members = check_npz(path, what=_WHAT)
            key = next((k for k in ("z", "height", "measured") if k in members), None)
            if key is None:
                raise InputError(f"{path}: .npz needs an array 'z' (heights), has {sorted(members)}")
            check_real_array(members[key][1], members[key][0], what=_WHAT, name=f"{path}:{key}")
            with np.load(path, allow_pickle=False) as npz:
                z = np.array(npz[key], dtype=np.float64)
                for k in ("pixel_mm", "origin_mm", "units"):
                    if k in npz.files:
                        side[k] = npz[k].tolist()
        else:
            check_npy(path, what=_WHAT)
            z = np.load(path, allow_pickle=False).astype(np.float64)
            if sidecar.is_file():
                side = read_json_file(sidecar, what=f"{_WHAT} side-car")
    except InputError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile, TypeError) as err:
        raise InputError(f"{_WHAT} {str(path)!r} cannot be read ({type(err).__name__}: {err})") from None
    units_arg = units
    pxy, origin, units = _sidecar_values(path, side, pixel, origin, units)
    if pxy is None:
        raise InputError(f"{path}: the pixel size is unknown; write {sidecar.name} with "
                         f'{{"pixel_mm": ..., "origin_mm": [x, y], "units": "mm"}} or pass pixel=')
    said = ("the units argument" if units_arg else
            f"{'the .npz' if path.suffix.lower() == '.npz' else sidecar.name}: units"
            if "units" in side else "not stated: mm assumed")
    return z * _to_mm(f"{path} units", units), pxy, origin, {
        "format": path.suffix[1:], "units_in_file": {"lateral": "mm", "vertical": units},
        "units_in_file_from": said}


_ST_READERS = {".dat": "MetroProReader", ".datx": "DATXReader", ".plu": "PLUReader",
               ".plux": "PLUXReader", ".opd": "OPDReader", ".opdx": "OPDxReader",
               ".al3d": "AL3DReader", ".vk3": "VKReader", ".vk4": "VKReader",
               ".vk6": "VKReader", ".vk7": "VKReader", ".lext": "LEXTReader",
               ".oir": "OIRReader", ".gwy": "GWYReader", ".frt": "FRTReader",
               ".zon": "ZONReader"}


@_register(*_ST_READERS, name="SurfaceTopography")
def _read_surface_topography(path, **_):
    import SurfaceTopography.IO as stio

    suffix = Path(path).suffix.lower()
    cls = getattr(stio, _ST_READERS[suffix])
    if suffix == ".plux":
        _check_plux(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rd = cls(str(path))
            if not rd.channels:
                raise InputError(f"{path}: the file holds no height data (no height layer)")
            # the grid the file declares, checked before the heights are read
            for ch in rd.channels[:1]:
                n = ch.nb_grid_pts
                check_values(path, what=_WHAT, desc=f"a {' x '.join(str(int(v)) for v in n)} grid",
                             count=math.prod(int(v) for v in n))
            t = rd.topography()
    except InputError:
        raise
    except Exception as err:  # the readers raise their own and builtin errors on bad files
        raise InputError(f"{path}: SurfaceTopography's {cls.__name__} could not read it "
                         f"({type(err).__name__}: {err})") from None
    if t.dim != 2 or not t.is_uniform:
        raise InputError(f"{path}: holds a {t.dim}-D{' non-uniform' if not t.is_uniform else ''} "
                         f"topography; only areal maps on a regular grid are supported")
    unit = t.unit
    scale = _to_mm(f"{path}: unit declared in the file", unit)
    h = t.heights()
    h = h.filled(np.nan) if np.ma.isMaskedArray(h) else np.asarray(h)
    z = np.asarray(h, dtype=np.float64).T * scale  # SurfaceTopography: [x, y]; here [row=y, col=x]
    if Path(path).suffix.lower() == ".opd":  # 16-bit invalid-point markers (io/_wyko.py)
        z = _wyko.mask_invalid(path, z)
    px, py = (float(v) * scale for v in t.pixel_size)
    info = t.info or {}
    meta = {"format": Path(path).suffix[1:].lower(), "units_in_file": {"lateral": unit,
                                                                       "vertical": unit},
            "units_in_file_from": f"SurfaceTopography's {cls.__name__} (its unit)",
            "library_units": {"lateral": unit, "vertical": unit},
            "date": str(info.get("acquisition_time", ""))}
    meta.update(_st_header(path, suffix, info))
    if suffix == ".frt":
        # Gwyddion's row order (the file's last stored row first), whichever order the
        # installed SurfaceTopography gives (see render_inspect.io._frt)
        if reader_keeps_stored_order():
            z = z[::-1]
        meta["row_order"] = "Gwyddion's: the last stored row first"
    return z, (px, py), (0.0, 0.0), meta


#: the header parsers of the formats SurfaceTopography reads (render_inspect.io._instrument)
_ST_HEADERS = {".dat": lambda path, info: metropro_header(info),
               ".opd": lambda path, info: opd_header(path),
               ".plu": lambda path, info: plu_header(path),
               ".al3d": lambda path, info: al3d_header(info),
               ".frt": lambda path, info: frt_header(info)}


def _st_header(path, suffix: str, info: dict) -> dict:
    """What the file's header says of the instrument and of its units (the file's own
    units replace the one SurfaceTopography converted to, which stays in
    ``library_units``)."""
    head = _ST_HEADERS.get(suffix, lambda path, info: library_header(info))(path, info)
    fields = head["fields"]
    out: dict = {"instrument_fields": finish(fields)}
    if "units" in head:
        out["units_in_file"] = head["units"]
        out["units_in_file_from"] = head["units_from"]
    return out


def _check_plux(path) -> None:
    """A Sensofar ``.plux`` is a zip archive with ``index.xml``, ``recipe.txt`` and one
    raster per layer: checked (sizes, members) before SurfaceTopography reads it, so
    that a container without a height layer says so."""
    infos = check_zip(path, what=_WHAT, kind=".plux file (a zip archive)")
    names = {i.filename for i in infos}
    if "index.xml" not in names:
        raise InputError(f"{path}: not a Sensofar .plux file (no index.xml in the archive)")
    index = next(i for i in infos if i.filename == "index.xml")
    if index.file_size > 16 * MIB_TO_BYTES:
        raise InputError(f"{path}: index.xml is {index.file_size} bytes; refused (a .plux "
                         f"index is a few kB)")
    try:
        with zipfile.ZipFile(path) as zf:
            text = zf.read(index)
    except (zipfile.BadZipFile, OSError, ValueError, RuntimeError, EOFError) as err:
        raise InputError(f"{path}: index.xml cannot be read ({err})") from None
    if b"LAYER_0" not in text or "recipe.txt" not in names:
        raise InputError(f"{path}: the file holds no height data (no height layer"
                         f"{'' if 'recipe.txt' in names else ' and no recipe.txt'})")


_SURFALIZE_ONLY = (".sur", ".sdf", ".os3d", ".zmg", ".sflz", ".hdat")


@_register(*_SURFALIZE_ONLY, name="surfalize")
def _read_surfalize(path, **_):
    import surfalize

    # surfalize reads the whole file at once: the file's size bounds what it can declare
    # (2-byte heights at the least)
    check_file_values(path, what=_WHAT, bytes_per_value=2)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = surfalize.Surface.load(str(path))
    except Exception as err:  # surfalize raises its own and builtin errors on corrupt files
        raise InputError(f"{path}: surfalize could not read it ({type(err).__name__}: {err})") from None
    z = np.asarray(s.data, dtype=np.float64) * UM_TO_MM  # surfalize gives micrometres
    md = getattr(s, "metadata", {}) or {}
    declared = {"lateral": md.get("unit_step_x", "um"), "vertical": md.get("unit_step_z", "um")}
    meta = {"format": Path(path).suffix[1:].lower(), "units_in_file": declared,
            "units_in_file_from": ("header: unit_step_x and unit_step_z" if "unit_step_z" in md
                                   else "surfalize (micrometres; the file names no unit)"),
            "instrument_fields": _surfalize_fields(md)}
    if Path(path).suffix.lower() == ".sur":  # the z offset's unit (render_inspect.io._sur)
        z, more = sur_offset_fix(z, md, _to_mm(f"{path}: unit of the z step",
                                               md.get("unit_step_z", "um")))
        meta.update(more)
    return z, (float(s.step_x) * UM_TO_MM, float(s.step_y) * UM_TO_MM), (0.0, 0.0), meta


def _surfalize_fields(md: dict) -> dict:
    """A Digital Surf header's acquisition type (0: unknown, no instrument said) and
    date; nothing for the formats whose header surfalize does not give."""
    kind = md.get("acquisition_type")
    name = getattr(kind, "name", None)
    fields = {"technique": (name.replace("_", " ").lower()
                            if name and getattr(kind, "value", 0) else None)}
    y, mo, d = (md.get(k) for k in ("year", "month", "day"))
    if isinstance(y, int) and isinstance(mo, int) and isinstance(d, int) and y > 0 \
            and 1 <= mo <= 12 and 1 <= d <= 31:
        h, mi, sec = (int(md.get(k) or 0) for k in ("hours", "minutes", "seconds"))
        fields["acquired"] = f"{y:04d}-{mo:02d}-{d:02d} {h:02d}:{mi:02d}:{sec:02d}"
    return finish(fields)


@_register(".tmd", name="render_inspect")
def _read_tmd(path, **_):
    check_file_values(path, what=_WHAT, bytes_per_value=4)  # float32 heights
    return read_tmd(path)


@_register(".nms", name="render_inspect")
def _read_nms(path, **_):
    check_file_values(path, what=_WHAT, bytes_per_value=2)  # uint16 codes
    return read_nms(path)


# -- public -------------------------------------------------------------------------------

def measured_formats() -> list[str]:
    """File suffixes :func:`read_surface` reads."""
    return formats("measured")


def reader_for(suffix: str) -> str:
    """Name of the library that reads ``suffix`` (e.g. ``".plu"`` -> ``"SurfaceTopography"``)."""
    s = suffix.lower() if suffix.startswith(".") else "." + suffix.lower()
    fn = reader("measured", "file" + s)  # InputError naming the supported ones
    return _LIBRARY.get(s, getattr(fn, "__module__", "render_inspect"))


def _library_version(name: str) -> str:
    from importlib import metadata

    dist = {"SurfaceTopography": "SurfaceTopography", "surfalize": "surfalize",
            "x3pio": "x3pio"}.get(name)
    if dist is None:
        return name
    try:
        return f"{name} {metadata.version(dist)}"
    except metadata.PackageNotFoundError:
        return name


def read_surface(path: str | Path, *, channel: str | None = None,
                 pixel: float | Sequence[float] | None = None,
                 origin: Sequence[float] | None = None,
                 units: str | None = None, region: Sequence[float] | None = None,
                 bytes_per_value: float | None = None,
                 purpose: str = "analyse") -> MeasuredMap:
    """Read a measured (or exported) height map.

    Parameters
    ----------
    path : str or Path
        An instrument file (see :func:`measured_formats`), ``.x3p``, ``.exr`` (our
        ``heightmap.exr`` or any EXR with ``pixel_size_mm`` / ``origin_mm`` header
        attributes), ``.npy`` (+ ``<name>.json`` side-car with ``pixel_mm`` (one number or
        [x, y]), ``origin_mm``, ``units``) or ``.npz`` (arrays ``z``, ``pixel_mm``,
        ``origin_mm``, ``units``).
    channel : str, optional
        EXR channel (default: ``measured``, ``height``, ``machined``, or the only one).
    pixel, origin, units : optional
        For ``.npy``/``.npz`` without that information: pixel (mm, one number or (x, y)),
        origin of pixel [0, 0] (mm), and the unit of the heights (see :data:`UNIT_TO_MM`).
    region : (x0, y0, x1, y1), optional
        For a ``heightmap.zarr`` store: read only the pixels whose centres lie in this
        window (mm), not the whole map.
    bytes_per_value : float, optional
        What the caller will hold per map point once the map is read (e.g.
        ``analyze_memory_per_point()``): the declared size of the file is checked against
        the memory budget with it, so a map too large for ``purpose`` is refused before
        it is read (:func:`~render_inspect.io._limits.reading_for`).

    Returns
    -------
    MeasuredMap
        Heights in mm, ``pixel = (pixel_x, pixel_y)`` in mm.

    Raises
    ------
    InputError
        Unknown suffix, missing or unreadable file, unknown units, a map that is not 2-D,
        a pixel that is not > 0, no valid height.
    """
    path = Path(path)
    problem = None if path.suffix.lower() == ".zarr" and path.is_dir() else not_a_file(path)
    if problem is not None and problem != "not found":  # a pipe, a device, a folder
        raise InputError(f"measured file {str(path)!r} {problem}")
    fn = reader("measured", path)
    if problem is not None:
        raise InputError(f"measured file not found: {str(path)!r}")
    # a reader registered from another module of io/ names itself (its module)
    lib = _LIBRARY.get(path.suffix.lower(), getattr(fn, "__module__", "render_inspect"))
    kw = {"region": region} if region is not None else {}
    if bytes_per_value is not None:
        with reading_for(bytes_per_value, purpose):
            z, pxy, origin_mm, meta = fn(path, channel=channel, pixel=pixel, origin=origin,
                                         units=units, **kw)
    else:
        z, pxy, origin_mm, meta = fn(path, channel=channel, pixel=pixel, origin=origin,
                                     units=units, **kw)
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 2:
        raise InputError(f"{path}: expected a 2-D height map of at least 2 x 2 points, got shape {z.shape}")
    px, py = (float(v) for v in pxy)
    ox, oy = (float(v) for v in origin_mm)
    _check_plausible(path, z, (px, py), (ox, oy), meta)
    z[np.isinf(z)] = np.nan
    ok = np.isfinite(z)
    n_ok = int(np.count_nonzero(ok))
    if not n_ok:
        raise InputError(f"{path}: the map has no valid (finite) heights")
    meta.setdefault("reader", _library_version(lib))
    # what the file says of the instrument: its fields on one line, or "not stated"
    fields = finish(meta.get("instrument_fields") or {})
    meta["instrument_fields"] = fields
    if fields.get("acquired"):
        meta["date"] = fields["acquired"]
    if any(k in fields for k in ("manufacturer", "model", "system", "serial")) \
            or not meta.get("instrument"):
        meta["instrument"] = instrument_text(fields)
    meta["format_name"] = format_name(path.suffix if path.suffix else ".zarr")
    meta.setdefault("units_in_file_from", "not stated")
    meta.update({"path": str(path), "valid_fraction": n_ok / ok.size,
                 "n_invalid": int(ok.size - n_ok), "units": {"lateral": "mm", "vertical": "mm"},
                 "pixel_x_mm": px, "pixel_y_mm": py})
    if n_ok / ok.size < 1.0 - MOSTLY_EMPTY_FRACTION:
        meta.setdefault("warnings", []).append(mostly_empty_warning(1.0 - n_ok / ok.size))
    return MeasuredMap(z, (px, py), (ox, oy), meta)


#: the key that gives the pixel, by format (named when it is out of bounds)
_PIXEL_KEYS = {"exr": "pixel_size_mm", "zarr": "pixel_size_mm", "npy": "pixel_mm",
               "npz": "pixel_mm", "x3p": "the CX / CY increment"}


def _check_plausible(path, z, pixel, origin, meta) -> None:
    """Bounds a measured map must keep (:data:`PIXEL_RANGE_MM`, :data:`MAX_FIELD_MM`,
    :data:`MAX_ABS_MM`): beyond them the file's units or its invalid-point marker were
    not understood, and a double could no longer resolve nanometres."""
    lateral = (meta.get("units_in_file") or {}).get("lateral")
    vertical = (meta.get("units_in_file") or {}).get("vertical")
    lat = f" (the file's lateral unit: {lateral!r})" if lateral else ""
    lo, hi = PIXEL_RANGE_MM
    ny, nx = z.shape
    key = _PIXEL_KEYS.get(str(meta.get("format", "")).lower())
    for name, v, n in (("pixel_x", pixel[0], nx), ("pixel_y", pixel[1], ny)):
        if not (math.isfinite(v) and lo <= v <= hi):
            said = f" ({key} in the file)" if key else ""
            raise InputError(f"{path}: {name}{said} must lie within {lo:g} .. {hi:g} mm, "
                             f"received {v:.3g} mm{lat}")
        if v * n > MAX_FIELD_MM:
            raise InputError(f"{path}: the field ({n} x {name} = {v * n:.3g} mm) must be at most "
                             f"{MAX_FIELD_MM:g} mm{lat}")
    for name, v in (("origin x", origin[0]), ("origin y", origin[1])):
        if not (math.isfinite(v) and abs(v) <= MAX_ABS_MM):
            raise InputError(f"{path}: the {name} must lie within +-{MAX_ABS_MM:g} mm, received "
                             f"{v:.3g} mm{lat}")
    with np.errstate(invalid="ignore"):
        finite = np.isfinite(z)
        if finite.any():
            zmin, zmax = float(np.min(z, where=finite, initial=np.inf)), \
                float(np.max(z, where=finite, initial=-np.inf))
            big = max(abs(zmin), abs(zmax))
            if big > MAX_ABS_MM:
                unit = f" from the file's unit {vertical!r}" if vertical else ""
                raise InputError(f"{path}: heights must lie within +-{MAX_ABS_MM:g} mm (converted"
                                 f"{unit}), received values up to {big:.3g} mm; the file's unit "
                                 f"or its marker of points not measured was not understood")


def read_measured(path: str | Path, *, channel: str | None = None,
                  pixel: float | Sequence[float] | None = None,
                  origin: Sequence[float] | None = None,
                  units: str | None = None,
                  region: Sequence[float] | None = None) -> tuple[np.ndarray, float, tuple[float, float], dict]:
    """Read a height map with square pixels as ``(z_mm, pixel_mm, origin_mm, meta)``.

    The tuple form of :func:`read_surface` for callers that need one pixel size: a map
    whose x and y sampling differ (by more than 1e-6) raises :class:`InputError` naming
    both; use :func:`read_surface`, which keeps ``(pixel_x, pixel_y)``.
    """
    m = read_surface(path, channel=channel, pixel=pixel, origin=origin, units=units, region=region)
    if not m.square:
        raise InputError(f"{path}: pixel sizes differ in x ({m.pixel[0]:.6g} mm) and y "
                         f"({m.pixel[1]:.6g} mm); read it with read_surface, which keeps both")
    return m.z, m.pixel[0], m.origin, m.meta
