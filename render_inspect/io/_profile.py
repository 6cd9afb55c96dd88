"""Read measured profiles (one trace of heights along a line), in mm.

Profiles are what stylus profilers write and what interferometer software exports as a
2-D slice through an areal measurement.  Three kinds of file are read:

- text exports (``.csv``, ``.txt``, ``.tsv``, ``.asc``, ``.prf``, ``.xy``): two or three
  columns (position, height, optionally a label such as ``Slice 2``), with or without a
  header, separated by ``,`` ``;`` a tab or spaces (with ``;`` a decimal comma is
  accepted); a blank or non-numeric height is a point that was not measured.  A header
  may state the units (``X (um)``, ``Height [nm]``, ``x/mm``); where it does not, the
  caller says so (``units="um"``, or ``"mm,nm"`` for position and height) -- the numbers
  are never guessed, and the refusal describes what they would mean in each unit;
- the Bruker Dektak ``.opdx`` profile (read with SurfaceTopography's OPDx reader; the
  file states its units);
- X3P files whose feature type is a profile (``PRF``, read with x3pio; metres).

Every reader returns :class:`MeasuredProfile`: positions and heights in mm on a uniform
spacing (the spacing is checked: a trace with uneven steps is refused, naming the worst
step), NaN where a height was not measured.
"""

from __future__ import annotations

import math
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.units import M_TO_MM, MIB_TO_BYTES, MM_TO_NM, MM_TO_UM
from ._instrument import (NOT_STATED, date_text, finish, format_name, instrument_text,
                          library_header, x3p_header)
from ._limits import check_file_values, check_x3p
from ._registry import reader, register_reader

__all__ = ["MeasuredProfile", "read_profile", "is_profile_file", "parse_units",
           "PROFILE_TEXT_SUFFIXES", "PROFILE_UNITS"]

#: length units a user may give with ``units=`` (and ``--units``), in mm
PROFILE_UNITS = {"m": 1e3, "mm": 1.0, "um": 1e-3, "µm": 1e-3, "μm": 1e-3, "nm": 1e-6}

#: suffixes read as text profile exports
PROFILE_TEXT_SUFFIXES = (".csv", ".txt", ".tsv", ".asc", ".prf", ".xy")

#: relative scatter of the position steps a trace may have and still count as uniform
SPACING_TOLERANCE = 1e-3  # not a unit conversion

_WHAT = "measured profile"


@dataclass(frozen=True)
class MeasuredProfile:
    """A profile read from a file.

    Attributes
    ----------
    x : (n,) float64 array
        Positions along the trace, mm, increasing with a uniform step.
    z : (n,) float64 array
        Heights, mm; NaN where not measured.
    meta : dict
        ``format``, ``format_name``, ``reader``, ``path``, ``units_in_file``
        (``{"position", "height"}``: what the file declares, or what the caller gave, with
        ``units_from``: "file", "--units" or "file and --units", and
        ``units_in_file_from`` saying it in words), ``instrument`` (one line: what the
        file names, or "not stated in the file"), ``instrument_fields``, ``date`` (or
        None), ``n_points``, ``n_measured``, ``n_invalid``, ``valid_fraction``,
        ``spacing_mm``, ``length_mm`` and, for text files, ``label`` (the third column's
        value where there is one).
    """

    x: np.ndarray
    z: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def spacing(self) -> float:
        """Distance between points, mm."""
        return float(self.meta["spacing_mm"])

    @property
    def n_measured(self) -> int:
        return int(np.count_nonzero(np.isfinite(self.z)))

    @property
    def length(self) -> float:
        """Length of the trace from the first to the last point, mm."""
        return float(self.x[-1] - self.x[0])


def parse_units(units: str | None, *, option: str = "--units") -> tuple[str, str] | None:
    """``units`` as (position unit, height unit): None, one unit for both (``"um"``), or
    two (``"mm,nm"`` / ``("mm", "nm")``)."""
    if units is None:
        return None
    parts = [u.strip() for u in units.split(",")] if isinstance(units, str) else list(units)
    if len(parts) == 1:
        parts = parts * 2
    if len(parts) != 2 or not all(isinstance(u, str) and u in PROFILE_UNITS for u in parts):
        raise InputError(f"{option} must be one of um, mm, nm (or POSITION,HEIGHT such as "
                         f"mm,nm), received {units!r}")
    return parts[0], parts[1]


# -- text exports -----------------------------------------------------------------------------

_NUM = re.compile(r"^[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?$")
_UNIT_IN_HEADER = re.compile(r"[\(\[\{]\s*(mm|um|µm|μm|nm|m)\s*[\)\]\}]|/\s*(mm|um|µm|μm|nm|m)\b",
                             re.IGNORECASE)


def _split(line: str, sep: str | None) -> list[str]:
    if sep is None:
        return line.split()
    return [f.strip() for f in line.split(sep)]


def _number(text: str, decimal_comma: bool) -> float | None:
    t = text.strip()
    if decimal_comma:
        t = t.replace(",", ".")
    if not _NUM.match(t):
        return None
    v = float(t)
    return v if math.isfinite(v) else None


def _separator(lines: list[str]) -> tuple[str | None, bool]:
    """The field separator of the data lines and whether numbers use a decimal comma."""
    sample = [ln for ln in lines if ln.strip()][:50]
    joined = "\n".join(sample)
    if ";" in joined:
        return ";", "," in joined
    if "\t" in joined:
        return "\t", False
    if "," in joined:
        return ",", False
    return None, False


def _header_units(header: list[str]) -> tuple[str | None, str | None]:
    """Units a header states for its first two columns (None where it says none)."""
    if not header:
        return None, None
    found = []
    for field_ in header[:2]:
        m = _UNIT_IN_HEADER.search(field_)
        u = (m.group(1) or m.group(2)) if m else None
        found.append({"µm": "um", "μm": "um"}.get(u, u.lower()) if u else None)
    while len(found) < 2:
        found.append(None)
    return found[0], found[1]


def _read_text(path: Path, units) -> tuple[np.ndarray, np.ndarray, dict]:
    check_file_values(path, what=_WHAT, bytes_per_value=4)
    try:
        text = path.read_text(encoding="utf-8-sig", errors="strict")
    except UnicodeDecodeError:
        try:
            text = path.read_text(encoding="latin-1")
        except OSError as err:
            raise InputError(f"{_WHAT} {str(path)!r} cannot be read ({err})") from None
    except OSError as err:
        raise InputError(f"{_WHAT} {str(path)!r} cannot be read ({err})") from None
    lines = text.splitlines()
    sep, dec_comma = _separator(lines)
    header: list[str] = []
    xs: list[float] = []
    zs: list[float] = []
    labels: set[str] = set()
    first_data = None
    for i, line in enumerate(lines):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        f = _split(line, sep)
        xv = _number(f[0], dec_comma) if f else None
        if xv is None:
            if first_data is None and not xs:
                header = f  # a header line (the last one before the data counts)
                continue
            raise InputError(f"{path}: line {i + 1}: the position (first column) must be a "
                             f"number, received {f[0]!r}")
        if first_data is None:
            first_data = i
        if len(f) < 2 or len(f) > 3:
            raise InputError(f"{path}: line {i + 1}: a profile has 2 or 3 columns (position, "
                             f"height, optional label), received {len(f)}: {line.strip()[:80]!r}")
        zv = _number(f[1], dec_comma)
        xs.append(xv)
        zs.append(np.nan if zv is None else zv)
        if len(f) == 3 and f[2]:
            labels.add(f[2])
    if len(xs) < 2:
        raise InputError(f"{path}: a profile needs at least 2 rows of (position, height), "
                         f"found {len(xs)}")
    x = np.asarray(xs, dtype=np.float64)
    z = np.asarray(zs, dtype=np.float64)
    pos_u, h_u = _header_units(header)
    given = parse_units(units)
    if pos_u and h_u:
        declared, source = (pos_u, h_u), "file"
        if given is not None and tuple(given) != declared:
            raise InputError(f"{path}: the header states units {declared[0]} (position) and "
                             f"{declared[1]} (height); --units {','.join(given)} contradicts it")
    elif given is not None:
        declared = (pos_u or given[0], h_u or given[1])
        source = "file and --units" if (pos_u or h_u) else "--units"
    else:
        raise InputError(_units_refusal(path, x, z, pos_u, h_u))
    meta = {"format": path.suffix[1:].lower() or "text", "reader": "render_inspect",
            "format_name": f"text profile export ({path.suffix.lower() or 'no suffix'})",
            "units_in_file": {"position": declared[0], "height": declared[1]},
            "units_from": source, "units_in_file_from": _TEXT_UNITS_FROM[source],
            "header": header,
            "separator": {None: "spaces", "\t": "tab"}.get(sep, sep)}
    if labels:
        meta["label"] = ", ".join(sorted(labels))
    return x * PROFILE_UNITS[declared[0]], z * PROFILE_UNITS[declared[1]], meta


#: where a text profile's units come from, by ``units_from``
_TEXT_UNITS_FROM = {"file": "the header line",
                    "--units": "--units (the file does not state them)",
                    "file and --units": "the header line (what it states) and --units (the rest)"}


def _units_refusal(path, x, z, pos_u, h_u) -> str:
    ok = np.isfinite(z)
    step = float(np.median(np.diff(x))) if x.size > 1 else float("nan")
    length = float(x[-1] - x[0])
    pv = float(np.ptp(z[ok])) if ok.any() else float("nan")
    said = []
    if pos_u:
        said.append(f"position in {pos_u}")
    if h_u:
        said.append(f"height in {h_u}")
    read = []
    for u in ("um", "mm", "nm"):
        pu = pos_u or u
        hu = h_u or u
        read.append(f"as {u}: a {length * PROFILE_UNITS[pu]:.4g} mm trace, step "
                    f"{step * PROFILE_UNITS[pu] * MM_TO_UM:.4g} um, heights spanning "
                    f"{pv * PROFILE_UNITS[hu] * MM_TO_NM:.4g} nm")
    stated = f"states only the {' and '.join(said)}" if said else "does not state its units"
    return (f"{path}: the file {stated}; say which with --units um|mm|nm (or "
            f"--units POSITION,HEIGHT such as um,nm). Its numbers: positions "
            f"{x[0]:.6g} .. {x[-1]:.6g} (step {step:.6g}), heights {np.nanmin(z):.4g} .. "
            f"{np.nanmax(z):.4g}, {int(ok.sum())} of {z.size} measured; read "
            + "; ".join(read))


# -- Dektak .opdx and X3P profiles ---------------------------------------------------------

def _opdx_extent(rd: Any, t: Any) -> float | None:
    """The Extent (first to last point, in the topography's unit) of the profile channel
    that ``rd.topography()`` read (the first), from the file's manifest; None where the
    file states none in that unit."""
    try:
        name = rd.manifest["/MetaData/1D_Channels/Height"][0]
        extent = rd.manifest[f"/1D_Data/{name}/Extent"]
        return float(extent.value) if extent.symbol == t.unit else None
    except (KeyError, IndexError, AttributeError, TypeError, ValueError):
        return None


def _read_opdx(path: Path, units) -> tuple[np.ndarray, np.ndarray, dict]:
    import SurfaceTopography.IO as stio

    if units is not None:
        raise InputError(f"{path}: a Dektak .opdx file states its own units; --units is only "
                         f"for text files that do not, received {units!r}")
    check_file_values(path, what=_WHAT, bytes_per_value=2)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            rd = stio.OPDxReader(str(path))
            if not rd.channels:
                raise InputError(f"{path}: the file holds no height data")
            t = rd.topography()
    except InputError:
        raise
    except Exception as err:  # the reader raises its own and builtin errors on bad files
        raise InputError(f"{path}: SurfaceTopography's OPDxReader could not read it "
                         f"({type(err).__name__}: {err})") from None
    if t.dim != 1:
        raise InputError(f"{path}: holds a {t.dim}-D topography, not a profile; read it as an "
                         f"areal map")
    unit = {"µm": "um", "μm": "um"}.get(t.unit, t.unit)
    if unit not in PROFILE_UNITS:
        raise InputError(f"{path}: the file's unit must be one of {sorted(PROFILE_UNITS)}, "
                         f"received {t.unit!r}")
    scale = PROFILE_UNITS[unit]
    h = t.heights()
    h = h.filled(np.nan) if np.ma.isMaskedArray(h) else np.asarray(h, dtype=np.float64)
    n = h.size
    # the file's Extent runs from the first to the last point (its ScanResolution and
    # the instrument's own text export give Extent / (n - 1)); read from the file's own
    # entry, since SurfaceTopography's physical size is the Extent in 1.18.2 and
    # Extent n / (n - 1) in 1.27.1 (in the topography's unit either way)
    extent = _opdx_extent(rd, t)
    if extent is None or not extent > 0 or n < 2:
        raise InputError(f"{path}: the profile states no Extent in its unit {t.unit!r} over "
                         f"at least 2 points: its point spacing is not known")
    x = np.arange(n, dtype=np.float64) * (extent / (n - 1)) * scale
    info = t.info or {}
    return x, np.asarray(h, dtype=np.float64) * scale, {
        "format": "opdx", "reader": _version("SurfaceTopography"),
        "units_in_file": {"position": unit, "height": unit}, "units_from": "file",
        "units_in_file_from": "the file: the height channel's unit and its Extent",
        "instrument_fields": {**library_header(info)["fields"],
                              "acquired": date_text(info.get("acquisition_time"))}}


def _x3p_feature(path: Path) -> str | None:
    """The feature type (``SUR``, ``PRF``, ``PCL``) an X3P's main.xml declares."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as zf:
            name = next((n for n in zf.namelist() if n.lower().endswith("main.xml")), None)
            if name is None or zf.getinfo(name).file_size > 64 * MIB_TO_BYTES:
                return None
            text = zf.read(name).decode("utf-8", errors="replace")
    except (zipfile.BadZipFile, OSError, ValueError, KeyError):
        return None
    m = re.search(r"<FeatureType>\s*(\w+)\s*</FeatureType>", text)
    return m.group(1).upper() if m else None


def _read_x3p_profile(path: Path, units) -> tuple[np.ndarray, np.ndarray, dict]:
    import x3pio

    if units is not None:
        raise InputError(f"{path}: an X3P file states its own units (metres); --units is only "
                         f"for text files that do not, received {units!r}")
    check_x3p(path, what=_WHAT)
    try:
        f = x3pio.read(str(path))
    except (x3pio.X3pError, ValueError, OSError, EOFError) as err:
        raise InputError(f"{path}: not a readable X3P file ({err})") from None
    if not isinstance(f, x3pio.Profile):
        raise InputError(f"{path}: the X3P feature type is {type(f).__name__}, not a profile "
                         f"(PRF); read it as an areal map")
    layer = f.layers[0]
    z = np.asarray(layer.z, dtype=np.float64).ravel() * M_TO_MM
    sp = getattr(layer, "spacing", None)
    dx = float(sp[0] if np.ndim(sp) else sp) if sp is not None else None
    if dx is None or not dx > 0:
        raise InputError(f"{path}: the X3P profile has no regular x increment (CX)")
    off = np.asarray(f.placement.offset, dtype=np.float64) * M_TO_MM
    x = off[0] + np.arange(z.size) * dx * M_TO_MM
    if off[2]:
        z = z + off[2]
    return x, z, {"format": "x3p", "reader": _version("x3pio"),
                  "units_in_file": {"position": "m", "height": "m"}, "units_from": "file",
                  "units_in_file_from": "ISO 25178-72: X3P stores metres",
                  "instrument_fields": x3p_header(f.metadata)["instrument_fields"]}


def _version(dist: str) -> str:
    from importlib import metadata

    try:
        return f"{dist} {metadata.version(dist)}"
    except metadata.PackageNotFoundError:
        return dist


# -- registry -----------------------------------------------------------------------------

@register_reader("profile", *PROFILE_TEXT_SUFFIXES)
def _text_reader(path, *, units=None, **_):
    return _read_text(Path(path), units)


@register_reader("profile", ".opdx")
def _opdx_reader(path, *, units=None, **_):
    return _read_opdx(Path(path), units)


@register_reader("profile", ".x3p")
def _x3p_reader(path, *, units=None, **_):
    return _read_x3p_profile(Path(path), units)


def is_profile_file(path: str | Path) -> bool:
    """True when ``path`` holds a profile rather than an areal map: a text export, a
    Dektak ``.opdx`` whose data are 1-D, or an X3P whose feature type is ``PRF``."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix in PROFILE_TEXT_SUFFIXES:
        # a text grid (more than three numbers a line: an areal map another reader takes)
        # is not a profile
        return _text_columns(path) <= 3
    if not path.is_file():
        return False
    if suffix == ".x3p":
        return _x3p_feature(path) == "PRF"
    if suffix == ".opdx":
        try:
            with open(path, "rb") as fh:
                head = fh.read(4096)
        except OSError:
            return False
        return b"1D_Data" in head
    return False


def _text_columns(path: Path, *, lines: int = 64) -> int:
    """The number of numbers on the first line of ``path`` that holds only numbers (0 when
    none of its first ``lines`` lines does, or it cannot be read)."""
    try:
        with open(path, "r", errors="replace") as fh:
            for _, line in zip(range(lines), fh):
                sep = r"[;\s]+" if ";" in line else r"[,\s]+"  # ";" allows decimal commas
                words = [w.replace(",", ".") for w in re.split(sep, line.strip()) if w]
                if not words:
                    continue
                try:
                    [float(w) for w in words]
                except ValueError:
                    continue
                return len(words)
    except OSError:
        return 0
    return 0


def read_profile(path: str | Path, *, units: str | None = None) -> MeasuredProfile:
    """Read a measured profile.

    Parameters
    ----------
    path : str or Path
        A text export (see :data:`PROFILE_TEXT_SUFFIXES`), a Dektak ``.opdx`` profile or an
        X3P profile (feature type ``PRF``).
    units : str or (str, str), optional
        For text files that do not state their units: ``"um"``, ``"mm"`` or ``"nm"`` for
        both columns, or ``"mm,nm"`` (position, height).  Refused for files that state
        their own.

    Returns
    -------
    MeasuredProfile
        Positions and heights in mm, uniform spacing, NaN = not measured.

    Raises
    ------
    InputError
        Unknown suffix, missing or unreadable file, units not stated and not given,
        uneven or non-increasing positions, no measured height.
    """
    path = Path(path)
    fn = reader("profile", path)
    if not path.is_file():
        raise InputError(f"{_WHAT} not found: {str(path)!r}")
    x, z, meta = fn(path, units=units)
    x = np.asarray(x, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    z[np.isinf(z)] = np.nan
    if x.size >= 2 and x[-1] < x[0]:  # a trace written from its end
        x, z = x[::-1].copy(), z[::-1].copy()
    steps = np.diff(x)
    if not (steps > 0).all():
        i = int(np.argmin(steps))
        raise InputError(f"{path}: positions must increase from row to row; row {i + 2} "
                         f"({x[i + 1]:.6g} mm) follows {x[i]:.6g} mm")
    dx = float((x[-1] - x[0]) / (x.size - 1))
    worst = float(np.max(np.abs(steps - dx)) / dx)
    if worst > SPACING_TOLERANCE:
        i = int(np.argmax(np.abs(steps - dx)))
        raise InputError(f"{path}: the positions must be evenly spaced (within "
                         f"{SPACING_TOLERANCE:.0e} of the mean step {dx:.6g} mm); the step "
                         f"after row {i + 1} is {steps[i]:.6g} mm")
    ok = np.isfinite(z)
    if not ok.any():
        raise InputError(f"{path}: the profile has no measured (finite) height")
    big = float(np.max(np.abs(z[ok])))
    if big > 100.0 or dx > 100.0 or not dx > 1e-9:
        raise InputError(f"{path}: the numbers do not fit a profile in the stated units "
                         f"{meta.get('units_in_file')}: step {dx:.3g} mm (allowed 1e-09 .. 100 "
                         f"mm), heights up to {big:.3g} mm (allowed 100 mm)")
    # what the file says of the instrument that wrote it (its fields on one line, or "not
    # stated"), as read_surface says it of a map
    fields = finish(meta.get("instrument_fields") or {})
    meta["instrument_fields"] = fields
    meta["instrument"] = instrument_text(fields) if fields else NOT_STATED
    meta["date"] = fields.get("acquired")
    meta.setdefault("format_name", format_name(path.suffix))
    meta.update({"path": str(path), "n_points": int(z.size), "n_measured": int(ok.sum()),
                 "n_invalid": int(z.size - ok.sum()), "valid_fraction": float(ok.mean()),
                 "spacing_mm": dx, "length_mm": float(x[-1] - x[0]),
                 "units": {"position": "mm", "height": "mm"}})
    return MeasuredProfile(x, z, meta)
