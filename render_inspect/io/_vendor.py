"""Parsers written here for the instrument files that neither SurfaceTopography nor
surfalize reads correctly (see docs/metrology.md, "Reading measured files"):

- TrueMap / GelSight ``.tmd``: lengths and heights in mm (GelSight's ``readtmd.m``); the
  comment after the 32-byte magic line is NUL-terminated and may be empty.
- NanoFocus ``.nms`` ("@OM_MS_2.0"): uint16 codes 0..65535 spanning the header's ``zmin``
  .. ``zmax`` (micrometres); lateral steps in nm.  (surfalize 0.19.2 adds ``zmax`` instead
  of ``zmin``, shifting every height by the range; SurfaceTopography 1.18.2 has no reader.)
- X3P whose ``main.xml`` root lacks the ISO 5436-2 namespace (some exports, e.g. fix3p's),
  read from its own axes description.

Each returns ``(z_mm, (pixel_x_mm, pixel_y_mm), origin_mm, meta)`` with row 0 the first
row stored in the file.
"""

from __future__ import annotations

import hashlib
import struct
import zipfile
import zlib
from pathlib import Path
from xml.etree import ElementTree

import numpy as np

from ..core.errors import InputError
from ..core.units import M_TO_MM, NM_TO_MM, UM_TO_MM
from ._instrument import date_text, finish, instrument_text, x3p_instrument

__all__ = ["read_tmd", "read_nms", "read_x3p_plain"]

_TMD_MAGIC = b"Binary TrueMap Data File v2.0\r\n\x00"


def read_tmd(path: str | Path) -> tuple[np.ndarray, tuple[float, float], tuple[float, float], dict]:
    """TrueMap / GelSight ``.tmd``: float32 heights (mm), ``lengthx`` / ``lengthy`` (mm) over
    ``cols`` / ``rows`` pixels, ``offsetx`` / ``offsety`` (mm)."""
    path = Path(path)
    buf = path.read_bytes()
    if not buf.startswith(_TMD_MAGIC):
        raise InputError(f"{path}: not a TrueMap .tmd file (the first 32 bytes must be "
                         f"{_TMD_MAGIC!r})")
    end = buf.find(b"\x00", len(_TMD_MAGIC))
    if end < 0:
        raise InputError(f"{path}: truncated .tmd header (comment not terminated)")
    comment = buf[len(_TMD_MAGIC):end].decode("latin-1").strip()
    head = end + 1
    if len(buf) < head + 24:
        raise InputError(f"{path}: truncated .tmd header")
    cols, rows = struct.unpack_from("<2I", buf, head)
    lx, ly, ox, oy = struct.unpack_from("<4f", buf, head + 8)
    n = cols * rows
    data = head + 24
    if cols < 2 or rows < 2 or len(buf) < data + 4 * n:
        raise InputError(f"{path}: .tmd header says {rows} x {cols} points but the file holds "
                         f"{(len(buf) - data) // 4} values")
    if not (lx > 0 and ly > 0):
        raise InputError(f"{path}: .tmd lengths must be > 0 mm, got lengthx={lx}, lengthy={ly}")
    z = np.frombuffer(buf, dtype="<f4", count=n, offset=data).reshape(rows, cols).astype(np.float64)
    px, py = float(lx) / cols, float(ly) / rows
    meta = {"format": "tmd", "reader": "render_inspect (TrueMap/GelSight readtmd.m layout)",
            "comment": comment, "length_x_mm": float(lx), "length_y_mm": float(ly),
            "offset_x_mm": float(ox), "offset_y_mm": float(oy),
            "units_in_file": {"lateral": "mm", "vertical": "mm"},
            "units_in_file_from": "the TrueMap format: lengths and heights in mm "
                                  "(GelSight's readtmd.m)"}
    side = path.with_name(path.name[:-len(path.suffix)] + ".scan.yaml")
    if not side.is_file():
        side = path.parent / "scan.yaml"
    if side.is_file():
        # GelSight writes mm per pixel into the scan's scan.yaml: it must match the header
        for line in side.read_text(errors="replace").splitlines():
            if line.strip().startswith("mmperpixel:"):
                mmpp = float(line.split(":", 1)[1])
                meta["scan_yaml_mm_per_pixel"] = mmpp
                if not np.isclose(mmpp, px, rtol=1e-5):
                    raise InputError(f"{path}: header pixel {px:.9g} mm disagrees with "
                                     f"{side.name} mmperpixel {mmpp:.9g} mm")
    return z, (px, py), (float(ox), float(oy)), meta


_NMS_HEADER = 3468


def read_nms(path: str | Path) -> tuple[np.ndarray, tuple[float, float], tuple[float, float], dict]:
    """NanoFocus ``.nms`` height image (see the module docstring for the layout)."""
    path = Path(path)
    buf = path.read_bytes()
    if len(buf) < _NMS_HEADER or b"@OM_MS" not in buf[:64]:
        raise InputError(f"{path}: not a NanoFocus .nms file (no '@OM_MS' signature)")
    zmin, zmax = struct.unpack_from("<2d", buf, 16)
    nx, ny = struct.unpack_from("<2I", buf, 1368)
    dx_nm, dy_nm = struct.unpack_from("<2d", buf, 1376)
    if nx < 2 or ny < 2 or len(buf) < _NMS_HEADER + 2 * nx * ny:
        raise InputError(f"{path}: .nms header says {ny} x {nx} points but the file is "
                         f"{len(buf)} bytes long")
    if not (dx_nm > 0 and dy_nm > 0 and zmax > zmin):
        raise InputError(f"{path}: .nms header has step {dx_nm} x {dy_nm} nm and z range "
                         f"[{zmin}, {zmax}] um; expected steps > 0 and zmax > zmin")
    raw = np.frombuffer(buf, dtype="<u2", count=nx * ny, offset=_NMS_HEADER).reshape(ny, nx)
    # code 0 is zmin and 65535 is zmax: in the reference file both codes occur once, at
    # the two ends of a smooth tilt, where the header's zmin / zmax are the data's extremes
    z = (raw / 65535.0 * (zmax - zmin) + zmin) * UM_TO_MM
    text = buf[:_NMS_HEADER]
    kind = text[52:52 + 64].split(b"\x00")[0].decode("latin-1").strip()
    date = text[1076:1076 + 16].split(b"\x00")[0].decode("latin-1").strip()
    meta = {"format": "nms", "reader": "render_inspect (NanoFocus @OM_MS_2.0 layout)",
            "content": kind, "date": date, "z_range_um": [float(zmin), float(zmax)],
            "instrument_fields": finish({"technique": kind, "acquired": date}),
            "units_in_file": {"lateral": "nm", "vertical": "um"},
            "units_in_file_from": "the NanoFocus format: steps in nm, z range in um"}
    return z, (dx_nm * NM_TO_MM, dy_nm * NM_TO_MM), (0.0, 0.0), meta


_X3P_DTYPES = {"I": "<i2", "L": "<i4", "F": "<f4", "D": "<f8"}


def _text(el, tag, default=None):
    found = el.find(tag)
    if found is None or found.text is None or not found.text.strip():
        return default
    return found.text.strip()


#: what a damaged container or main.xml raises while it is read
_X3P_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, ElementTree.ParseError,
               OSError, EOFError, KeyError, ValueError, TypeError, AttributeError,
               NotImplementedError, RuntimeError)


def read_x3p_plain(path: str | Path
                   ) -> tuple[np.ndarray, tuple[float, float], tuple[float, float], dict]:
    """An X3P container whose ``main.xml`` has no namespace (and may sit in a sub-folder of
    the archive): regular-grid surfaces (``FeatureType`` SUR, axes I/I/A) in metres.  A
    damaged container, ``main.xml`` or point file is an :class:`InputError`."""
    path = Path(path)
    try:
        return _read_x3p_plain(path)
    except _X3P_ERRORS as err:
        raise InputError(f"{path}: not a readable X3P container ({type(err).__name__}: "
                         f"{err})") from None


def _read_x3p_plain(path: Path):
    zf = zipfile.ZipFile(path)
    with zf:
        names = [n for n in zf.namelist() if not n.startswith("__MACOSX/")]
        mains = sorted((n for n in names if n.rsplit("/", 1)[-1] == "main.xml"), key=len)
        if not mains:
            raise InputError(f"{path}: X3P container has no main.xml")
        main = mains[0]
        base = main[:-len("main.xml")]
        root = ElementTree.fromstring(zf.read(main))
        for el in root.iter():  # drop any namespace: match on local names only
            if isinstance(el.tag, str) and "}" in el.tag:
                el.tag = el.tag.split("}", 1)[1]
        r1, r3 = root.find("Record1"), root.find("Record3")
        if r1 is None or r3 is None:
            raise InputError(f"{path}: main.xml lacks Record1 or Record3")
        if _text(r1, "FeatureType", "SUR") != "SUR":
            raise InputError(f"{path}: X3P feature type {_text(r1, 'FeatureType')!r}; only "
                             f"surfaces (SUR) are supported")
        axes = r1.find("Axes")
        # (no Axes: the AttributeError is reported as an unreadable container, _X3P_ERRORS)
        cx, cy, cz = (axes.find(a) for a in ("CX", "CY", "CZ"))  # type: ignore[union-attr]
        if _text(cx, "AxisType") != "I" or _text(cy, "AxisType") != "I":
            raise InputError(f"{path}: X3P x/y axes must be incremental (AxisType I)")
        px = float(_text(cx, "Increment"))
        py = float(_text(cy, "Increment"))
        ox = float(_text(cx, "Offset", "0"))
        oy = float(_text(cy, "Offset", "0"))
        z_inc = float(_text(cz, "Increment", "1"))
        z_off = float(_text(cz, "Offset", "0"))
        dtype = _X3P_DTYPES.get(_text(cz, "DataType", "D"))
        if dtype is None:
            raise InputError(f"{path}: X3P z data type {_text(cz, 'DataType')!r} is not one of "
                             f"{sorted(_X3P_DTYPES)}")
        dim = r3.find("MatrixDimension")
        nx, ny, nz = (int(_text(dim, k)) for k in ("SizeX", "SizeY", "SizeZ"))
        link = r3.find("DataLink")
        if link is None:
            raise InputError(f"{path}: X3P holds its points inline (DataList); only binary "
                             f"point data (DataLink) is supported")
        point_file = _text(link, "PointDataLink")
        blob = zf.read(base + point_file)
        md5 = _text(link, "MD5ChecksumPointData")
        checksum_ok = None if md5 is None else hashlib.md5(blob).hexdigest().lower() == md5.lower()
        n = nx * ny * nz
        item = np.dtype(dtype).itemsize
        if nz != 1 or len(blob) != n * item:
            raise InputError(f"{path}: X3P point data has {len(blob)} bytes, expected "
                             f"{nx} x {ny} x {nz} values of {item} bytes (one layer)")
        z = np.frombuffer(blob, dtype=dtype).reshape(ny, nx).astype(np.float64)
        if dtype in ("<i2", "<i4"):
            z = z * z_inc
        z = z + z_off
        valid_link = _text(r3, "ValidPointsLink")
        if valid_link:
            bits = np.unpackbits(np.frombuffer(zf.read(base + valid_link), dtype=np.uint8),
                                 bitorder="little")[:n].reshape(ny, nx)
            z[bits == 0] = np.nan
        r2 = root.find("Record2")
        inst = r2.find("Instrument") if r2 is not None else None
        probe = r2.find("ProbingSystem") if r2 is not None else None
    said = [None if inst is None else _text(inst, k)
            for k in ("Manufacturer", "Model", "Serial", "Version")]
    said += [None if probe is None else _text(probe, k) for k in ("Identification", "Type")]
    fields = x3p_instrument(*said)
    date = _text(r2, "Date", "") if r2 is not None else ""
    fields["acquired"] = date_text(date)
    meta = {"format": "x3p", "reader": "render_inspect (X3P without namespace)",
            "pixel_x_mm": px * M_TO_MM, "pixel_y_mm": py * M_TO_MM,
            "instrument": instrument_text(fields), "instrument_fields": finish(fields),
            "date": date,
            "comment": _text(r2, "Comment") if r2 is not None else None,
            "md5_ok": checksum_ok, "non_conformant": "main.xml root has no ISO 5436-2 namespace",
            "units_in_file": {"lateral": "m", "vertical": "m"},
            "units_in_file_from": "ISO 25178-72: X3P stores metres"}
    return z * M_TO_MM, (px * M_TO_MM, py * M_TO_MM), (ox * M_TO_MM, oy * M_TO_MM), meta
