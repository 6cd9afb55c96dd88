"""What a measured file's header says about the instrument that wrote it, and the units
the file itself declares.

Read from the file's own header (its bytes, or the header the reading library decoded),
never guessed: a field the header does not carry is left out, and a file whose header
names no instrument is said to be so (:data:`NOT_STATED`).  The fields
(:func:`instrument_text` puts them on one line):

- ``manufacturer``, ``model``, ``serial``, ``version`` (of the instrument's software),
  ``system`` (a coded instrument type the header gives as a number);
- ``objective`` (objective, magnification, zoom), ``technique`` (measuring mode);
- ``probing`` (X3P: the probing system's identification and type);
- ``acquired``: the acquisition date and time as the header states it (UTC where the
  header gives a Unix time).

Per format (the header fields in brackets):

- Zygo MetroPro ``.dat``: system type [``sys_type``], serial [``sys_serial2``, the full
  number; the 16-bit ``sys_serial`` otherwise], objective and zoom [``obj_name``,
  ``zoom_descr``], MetroPro version [``swinfo``], phase resolution [``phase_res``: 4096,
  32768 or 131072 counts per fringe], acquired [``time_stamp``, Unix time];
- Wyko / Bruker Vision ``.opd``: model [``MachineID``], serial [``SerialNum``], objective
  [``ObjectiveLabel`` and ``FOVLabel``, else ``Magnification``], technique
  [``MeasMode``: VSI, PSI], acquired [``Date`` (month/day/year), ``Time``];
- Sensofar ``.plu``: model from the hardware configuration code [byte 491, names as in
  Gwyddion's ``sensofar.c``; meaningful from format version 251 on], objective [code at
  byte 440, SurfaceTopography's table], acquired [the date text at byte 0];
- Alicona ``.al3d``: the signature ``AliconaImaging`` and [``CreatingApplication``];
- FRT ``.frt``: serial [block 0x8e], product id and series number [block 0x86], acquired
  [block 0x72, Unix time];
- X3P: [``Record2/Instrument``: Manufacturer, Model, Serial, Version;
  ``ProbingSystem``; ``Date``];
- Digital Surf ``.sur``, NanoFocus ``.nms``, TrueMap ``.tmd``: no instrument field
  (``.sur``: acquisition type 0, "unknown"); the date where the header has one.
"""

from __future__ import annotations

import datetime as _dt
import struct
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ._wyko import header_values

__all__ = ["NOT_STATED", "instrument_text", "format_name", "date_text", "finish", "metropro_header", "opd_header",
           "plu_header", "al3d_header", "frt_header", "x3p_instrument", "x3p_header",
           "library_header"]

#: what is said of a file whose header names no instrument
NOT_STATED = "not stated in the file"

#: the fields that name an instrument (the others describe how it measured)
_IDENTITY = ("manufacturer", "model", "system", "serial")

#: (suffix, the format's name) - whose format it is, not a statement about the instrument
_FORMATS = {
    ".dat": "Zygo MetroPro .dat", ".datx": "Zygo Mx .datx", ".plu": "Sensofar .plu",
    ".plux": "Sensofar .plux", ".opd": "Wyko / Bruker Vision .opd", ".opdx": "Bruker .opdx",
    ".al3d": "Alicona .al3d", ".vk3": "Keyence .vk3", ".vk4": "Keyence .vk4",
    ".vk6": "Keyence .vk6", ".vk7": "Keyence .vk7", ".lext": "Olympus .lext",
    ".oir": "Olympus .oir", ".gwy": "Gwyddion .gwy", ".frt": "FRT MicroProf .frt",
    ".zon": "Keyence .zon", ".x3p": "ISO 25178-72 .x3p", ".sur": "Digital Surf .sur",
    ".sdf": "ISO 25178-71 .sdf", ".os3d": "Olympus .os3d", ".zmg": "Zygo .zmg",
    ".sflz": "surfalize .sflz", ".hdat": ".hdat", ".tmd": "TrueMap / GelSight .tmd",
    ".nms": "NanoFocus .nms", ".exr": "OpenEXR height map", ".zarr": "height-map store (.zarr)",
    ".npy": "NumPy .npy", ".npz": "NumPy .npz"}

#: Sensofar hardware configuration codes (Gwyddion's sensofar.c, SurfaceTopography's
#: PLU reader from 1.19 on); meaningful from PLU format version 251 (0xFB, "2012") on
_PLU_HARDWARE = ("PLu", "PLu 2300 XGA", "PLu 2300 XGA T5", "PLu 2300 SXGA", "PLu 3300",
                 "DCM 3D", "PLu neox", "DCM 3D rev. 2", "PLu Apex (prototype)", "S neox",
                 "DCM8", "PLu Apex")
_PLU_VERSION_2012 = 0xFB
#: objective codes up to this one name the same objective in every SurfaceTopography
#: release (later ones were renumbered)
_PLU_LAST_STABLE_OBJECTIVE = 64
#: counts per fringe by MetroPro's phase_res
_METROPRO_COUNTS = {0: 4096, 1: 32768, 2: 131072}


def format_name(suffix: str) -> str:
    """The name of a file format by its suffix (".plu" -> "Sensofar .plu")."""
    s = suffix.lower()
    return _FORMATS.get(s, s.lstrip(".") or "unknown")


def _clean(v: Any) -> str | None:
    if v is None:
        return None
    if isinstance(v, bytes):
        v = v.split(b"\0", 1)[0].decode("latin-1")
    text = " ".join(str(v).split())
    return None if not text or text.lower() in ("not available", "none", "(none)", "unknown") \
        else text


def instrument_text(fields: Mapping[str, Any]) -> str:
    """One line from the header's fields: make and model, serial, objective, technique,
    software; :data:`NOT_STATED` (with what the header does say) when no field names
    the instrument."""
    f = {k: _clean(v) for k, v in fields.items()}
    make, model = f.get("manufacturer"), f.get("model")
    name = " ".join(v for v in (make, model if model and model != make else None) if v)
    parts = [p for p in (name or None, f.get("system"),
                         f"serial {f['serial']}" if f.get("serial") else None) if p]
    more = [p for p in (f"objective {f['objective']}" if f.get("objective") else None,
                        f.get("technique"),
                        f"probing system {f['probing']}" if f.get("probing") else None,
                        f"software {f['version']}" if f.get("version") else None) if p]
    if not any(f.get(k) for k in _IDENTITY):
        return NOT_STATED + (f" ({', '.join(more)})" if more else "")
    return ", ".join(parts + more)


def date_text(text: Any) -> str | None:
    """A date as the header writes it; one at the Unix epoch (1970-01-01, what some
    exporters write when they have no date) is said to be so."""
    t = _clean(text)
    if t and t.startswith("1970-01-01"):
        return f"{t} (the Unix epoch: no date recorded)"
    return t


def _unix_utc(t: Any) -> str | None:
    if not isinstance(t, int) or t <= 0 or t >= 2**32 - 1:
        return None
    return _dt.datetime.fromtimestamp(t, tz=_dt.timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


def _raw(info: Mapping | None) -> Mapping:
    raw = (info or {}).get("raw_metadata")
    return raw if isinstance(raw, Mapping) else {}


def metropro_header(info: Mapping | None) -> dict:
    """Zygo MetroPro: the fields, the declared units and where they come from."""
    h = _raw(info)
    fields: dict[str, Any] = {"manufacturer": None}
    if h.get("sys_type") is not None:
        fields["system"] = f"MetroPro system type {int(h['sys_type'])}"
    serial = h.get("sys_serial2") or ((int(h["sys_serial"]) & 0xFFFF)
                                      if h.get("sys_serial") else None)
    if serial:
        fields["serial"] = str(serial)
    obj, zoom = _clean(h.get("obj_name")), _clean(h.get("zoom_descr"))
    if obj or zoom:
        fields["objective"] = ", ".join(p for p in (obj, f"zoom {zoom}" if zoom else None) if p)
    if h.get("swinfo_version_major") is not None:
        fields["version"] = (f"MetroPro {h['swinfo_version_major']}."
                             f"{h.get('swinfo_version_minor', 0)}.{h.get('swinfo_version_bug', 0)}")
    counts = _METROPRO_COUNTS.get(h.get("phase_res"))  # type: ignore[arg-type]
    if counts:
        fields["phase_resolution"] = f"phase_res {h['phase_res']}: {counts} counts per fringe"
    if h.get("wavelength_in"):
        fields["wavelength_m"] = float(h["wavelength_in"])
    fields["acquired"] = _unix_utc(h.get("time_stamp"))
    return {"fields": fields, "units": {"lateral": "m", "vertical": "m"},
            "units_from": "header: lateral_res (m per pixel) and wavelength_in (m); heights "
                          "stored as phase counts (wavelength x scale factor / counts per fringe)"}


def opd_header(path: str | Path) -> dict:
    """Wyko / Bruker Vision ``.opd``: the named blocks of the header."""
    b = header_values(path)
    fields: dict[str, Any] = {"model": _clean(b.get("MachineID")),
                              "serial": _clean(b.get("SerialNum"))}
    obj, fov = _clean(b.get("ObjectiveLabel")), _clean(b.get("FOVLabel"))
    mag = b.get("Magnification")
    if obj:
        fields["objective"] = obj + (f", field lens {fov}" if fov else "")
    elif isinstance(mag, float) and mag > 0:
        fields["objective"] = f"magnification {mag:.4g}x"
    mode = _clean(b.get("MeasMode"))
    fields["technique"] = mode
    date, time = _clean(b.get("Date")), _clean(b.get("Time"))
    if date:
        fields["acquired"] = _us_date(date, time)
    title = _clean(b.get("DataSetName")) or _clean(b.get("Title"))
    if title:
        fields["title"] = title
    return {"fields": fields, "units": {"lateral": "mm", "vertical": "nm"},
            "units_from": "the Wyko format: Pixel_size in mm; heights are counts x Wavelength "
                          "(nm) / Mult"}


def _us_date(date: str, time: str | None) -> str:
    """Vision's ``Date`` (month/day/year) and ``Time`` as year-month-day hh:mm:ss; as
    written when it does not read so."""
    try:
        month, day, year = (int(v) for v in date.split("/"))
        text = _dt.date(year, month, day).isoformat()
    except ValueError:
        text = date
    return f"{text} {time or ''}".strip()


def plu_header(path: str | Path) -> dict:
    """Sensofar ``.plu``: the date text, the objective code and the hardware code."""
    with open(path, "rb") as fh:
        head = fh.read(496)
    fields: dict[str, Any] = {}
    if len(head) >= 496:
        fields["acquired"] = _clean(head[:128])
        objective = struct.unpack_from("<I", head, 440)[0]
        version, hardware = head[490], head[491]
        fields["objective"] = _plu_objective(objective)
        if version >= _PLU_VERSION_2012 and hardware < len(_PLU_HARDWARE):
            fields["manufacturer"] = "Sensofar"
            fields["model"] = f"{_PLU_HARDWARE[hardware]} (hardware code {hardware})"
        else:
            fields["system"] = f"hardware code {hardware} (format version {version})"
    return {"fields": fields, "units": {"lateral": "um", "vertical": "um"},
            "units_from": "the PLU format: micrometres per pixel and heights in micrometres"}


def _plu_objective(code: int) -> str:
    # SurfaceTopography's table of Sensofar's objective codes, imported here only when a
    # .plu file is read (the reader that needs it)
    from SurfaceTopography.IO import PLU

    names = getattr(PLU, "_objective_names", None)
    if code and names and code <= _PLU_LAST_STABLE_OBJECTIVE and code < len(names):
        return f"{names[code]} (code {code})"
    return f"code {code}"


def al3d_header(info: Mapping | None) -> dict:
    """Alicona ``.al3d``: the signature names the maker; the creating application."""
    h = _raw(info)
    fields = {"manufacturer": "Alicona Imaging", "version": _clean(h.get("CreatingApplication"))}
    return {"fields": fields, "units": {"lateral": "m", "vertical": "m"},
            "units_from": "header: PixelSizeXMeter / PixelSizeYMeter; depths in metres"}


def frt_header(info: Mapping | None) -> dict:
    """FRT MicroProf ``.frt``: its blocks (the signature FRTM_GLIDER names the maker)."""
    h = _raw(info)
    sn = (h.get("0x8e") or {}).get("serial_number")
    prod = h.get("0x86") or {}
    fields: dict[str, Any] = {"manufacturer": "FRT", "serial": _clean(sn)}
    if prod:
        fields["system"] = (f"product id {prod.get('product_id')}, series number "
                            f"{prod.get('series_no')}")
    title = _clean((h.get("0x77") or {}).get("text"))
    if title:
        fields["title"] = title
    fields["acquired"] = _unix_utc((h.get("0x72") or {}).get("meas_started"))
    unit = _clean((h.get("0x88") or {}).get("unit1")) or "m"
    return {"fields": fields, "units": {"lateral": "m", "vertical": unit},
            "units_from": "header: x / y range in metres (block 0x67), height scale in "
                          "metres per count (block 0x6c)"}


def x3p_instrument(manufacturer: Any, model: Any, serial: Any, version: Any,
                   probing: Any = None, probing_type: Any = None) -> dict:
    """The fields of an X3P's ``Record2/Instrument`` (and its probing system)."""
    kind = _clean(getattr(probing_type, "value", probing_type))
    ident = _clean(probing)
    if ident in (_clean(manufacturer), _clean(model)):  # (said once)
        ident = None
    probe = ", ".join(p for p in (ident, f"type {kind}" if kind else None) if p) or None
    return {"manufacturer": _clean(manufacturer), "model": _clean(model),
            "serial": _clean(serial), "version": _clean(version), "probing": probe}


def x3p_header(metadata: Any) -> dict:
    """``instrument_fields``, ``instrument`` (one line) and ``date`` of an X3P file from its
    ``Record2`` as x3pio reads it (``metadata``: its ``instrument``, ``probing_system``
    and ``date``; None for a file without one)."""
    inst = getattr(metadata, "instrument", None)
    probe = getattr(metadata, "probing_system", None)
    fields = x3p_instrument(getattr(inst, "manufacturer", None), getattr(inst, "model", None),
                            getattr(inst, "serial", None), getattr(inst, "version", None),
                            getattr(probe, "identification", None), getattr(probe, "type", None))
    date = str(getattr(metadata, "date", "") or "")
    fields["acquired"] = date_text(date)
    return {"instrument_fields": finish(fields), "instrument": instrument_text(fields),
            "date": date}


def library_header(info: Mapping | None) -> dict:
    """Formats this module does not parse: what the reading library says of the
    instrument (newer SurfaceTopography releases give ``info["instrument"]``)."""
    inst = (info or {}).get("instrument") or {}
    fields = {"manufacturer": _clean(inst.get("vendor")), "model": _clean(inst.get("name"))}
    return {"fields": fields}


def finish(fields: Mapping[str, Any]) -> dict:
    """The fields without empty ones."""
    return {k: v for k, v in fields.items() if v not in (None, "")}
