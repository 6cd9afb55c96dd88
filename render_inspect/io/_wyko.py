"""Invalid points of Wyko OPD files with 16-bit heights.

Bruker/Veeco Wyko Vision writes an OPD file as a directory of named blocks (a 2-byte
header, then 24-byte entries: a 16-byte name, a 2-byte type, a 4-byte length, a 2-byte
attribute; the blocks' data follow in the same order).  The height block (``RAW_DATA``,
``RAW DATA``, ``OPD`` or ``Raw``) starts with its columns, rows and bytes per element.
With 2-byte elements the heights are signed 16-bit integers, and a point the instrument
did not measure holds the largest values (32766 and 32767), the same threshold Gwyddion's
OPD reader uses.

SurfaceTopography up to 1.18.2 (the last release for NumPy 1) masks only values beyond
1e32, so it reads those markers as heights (on a real file, 809 points of 11 um); 1.19.1
masks 16-bit values from 32766 up.  :func:`invalid_points` finds them in the file itself
so that the reading is right with either version.
"""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np

#: A 16-bit height at or above this marks a point that was not measured.
INVALID_INT16 = 32766
_HEIGHT_BLOCKS = {"RAW_DATA", "RAW DATA", "OPD", "Raw"}
_ENTRY = 24


def invalid_points(path: str | Path) -> np.ndarray | None:
    """Boolean map of the points a 16-bit Wyko OPD file marks as not measured, in
    SurfaceTopography's layout of the heights (``[x, y]``, y from the last row of the
    file), or None when the heights are not 16-bit integers (4-byte floats mark invalid
    points with values SurfaceTopography already masks) or no height block is found."""
    data = Path(path).read_bytes()
    if len(data) < 2 + _ENTRY:
        return None
    pos = 2

    def entry(at):
        name = data[at:at + 16].split(b"\0", 1)[0].decode("latin-1")
        _kind, length, _attr = struct.unpack_from("<hlH", data, at + 16)
        return name, length

    name, dir_len = entry(pos)
    if name != "Directory" or dir_len % _ENTRY:
        return None
    blocks = [entry(pos + _ENTRY * (i + 1)) for i in range(dir_len // _ENTRY - 1)]
    offset = pos + _ENTRY * (dir_len // _ENTRY)  # the blocks' data, in directory order
    for name, length in blocks:
        if length <= 0:
            continue
        if name in _HEIGHT_BLOCKS:
            nx, ny, size = struct.unpack_from("<HHH", data, offset)
            if size != 2:
                return None
            raw = np.frombuffer(data, dtype="<i2", count=nx * ny, offset=offset + 6)
            return np.fliplr(raw.reshape(nx, ny) >= INVALID_INT16)
        offset += length
    return None


#: block types whose value is one number or a text (type 15: a tagged value, read when
#: it holds a text: 0x12 0x01, the length, the characters)
_SCALARS = {6: "<H", 7: "<f", 12: "<I"}


def header_values(path: str | Path) -> dict:
    """The header's named values of a Wyko OPD file: texts (``MachineID``, ``SerialNum``,
    ``ObjectiveLabel``, ``MeasMode``, ``Date``, ...) and numbers (``Magnification``,
    ``Wavelength``, ...); empty when the file has no block directory."""
    data = Path(path).read_bytes()
    out: dict = {}
    if len(data) < 2 + _ENTRY:
        return out
    name, kind, dir_len = _entry(data, 2)
    if name != "Directory" or dir_len % _ENTRY:
        return out
    offset = 2 + _ENTRY * (dir_len // _ENTRY)
    for i in range(dir_len // _ENTRY - 1):
        name, kind, length = _entry(data, 2 + _ENTRY * (i + 1))
        if length <= 0:
            continue
        raw = data[offset:offset + length]
        offset += length
        if kind == 5:
            out[name] = raw.split(b"\0", 1)[0].decode("latin-1").strip()
        elif kind in _SCALARS and len(raw) >= struct.calcsize(_SCALARS[kind]):
            out[name] = struct.unpack_from(_SCALARS[kind], raw)[0]
        elif kind == 15 and len(raw) >= 3 and raw[:2] == b"\x12\x01" and raw[2] <= len(raw) - 3:
            out[name] = raw[3:3 + raw[2]].decode("latin-1").strip()
    return out


def _entry(data: bytes, at: int) -> tuple[str, int, int]:
    name = data[at:at + 16].split(b"\0", 1)[0].decode("latin-1")
    kind, length, _attr = struct.unpack_from("<hlH", data, at + 16)
    return name, kind, length


def mask_invalid(path: str | Path, z: np.ndarray) -> np.ndarray:
    """``z`` (rows = y, columns = x, as render_inspect's readers return heights) with the
    points the OPD file marks as not measured set to NaN."""
    mask = invalid_points(path)
    if mask is None or not mask.any():
        return z
    mask = mask.T
    if mask.shape != z.shape:
        return z
    z = np.array(z, dtype=np.float64, copy=True)
    z[mask] = np.nan
    return z
