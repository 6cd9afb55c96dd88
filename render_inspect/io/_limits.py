"""Guards the readers call before they load anything large: what a file *declares*
(array shapes in ``.npy`` headers, member sizes in zip archives, grid sizes in X3P's
``main.xml``, the data window of an EXR) is checked against the file and against the
memory budget first, so that a small hostile file (a zip bomb, a header claiming
10^6 x 10^6 values, a pickle) is refused with a clear :class:`InputError` instead of
being allocated or executed.

Each function takes ``what`` (the key or option that named the file, e.g.
``design.path`` or ``--measured``), used in its messages, and ``budget`` (bytes; default:
the automatic budget of :func:`~render_inspect.core.limits.memory_budget`).
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
import ast
import contextlib
import contextvars
import json
import re
import struct
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from ._native import library_messages
from ..core.units import MIB_TO_BYTES
from ..core.errors import InputError, MemoryBudgetError
from ..core.limits import format_bytes, format_number, memory_budget
from ._special import not_a_file

__all__ = ["check_npy", "check_npz", "check_zip", "check_x3p", "check_exr", "read_json_file",
           "check_frames",
           "check_real_array", "check_values", "check_file_values", "MAX_JSON_BYTES",
           "MAX_ZIP_MEMBERS", "MAX_ZIP_RATIO", "READ_BYTES_PER_VALUE", "reading_for",
           "per_value_bytes"]

#: largest side-car JSON file read, bytes
MAX_JSON_BYTES = 1 * MIB_TO_BYTES
#: most members an archive (npz, X3P) may hold
MAX_ZIP_MEMBERS = 4096
#: largest uncompressed / compressed size of one zip member above 64 MiB (real height
#: data compresses a few times; a bomb compresses a thousand times)
MAX_ZIP_RATIO = 200.0
_RATIO_FLOOR = 64 * MIB_TO_BYTES
#: what reading a damaged or unusual archive raises
_ZIP_ERRORS = (zipfile.BadZipFile, zipfile.LargeZipFile, zlib.error, OSError, EOFError,
               ValueError, RuntimeError, NotImplementedError, UnicodeDecodeError)
#: bytes of working memory a reader needs per declared value (the value as float64, a
#: copy for the unit conversion and the mask of valid points)
READ_BYTES_PER_VALUE = 24
#: (bytes per value, purpose) of what the caller does with the map once read
#: (:func:`reading_for`)
_AFTER: contextvars.ContextVar = contextvars.ContextVar("render_inspect_after_read",
                                                        default=(0.0, ""))


@contextlib.contextmanager
def reading_for(bytes_per_value: float, purpose: str) -> Iterator[None]:
    """Within the block, the readers' size checks count ``bytes_per_value`` bytes per
    declared value (when more than :data:`READ_BYTES_PER_VALUE`): the peak of what the
    caller does with the map once read, e.g. ``analyze``'s parameters, so that a map too
    large for that is refused before it is read; ``purpose`` ("analyse") goes into the
    message ("would need about 7 GiB to read and analyse")."""
    token = _AFTER.set((float(bytes_per_value), str(purpose)))
    try:
        yield
    finally:
        _AFTER.reset(token)


def per_value_bytes() -> float:
    """Bytes per declared value the size checks count now (see :func:`reading_for`)."""
    return max(float(READ_BYTES_PER_VALUE), _AFTER.get()[0])


def _purpose() -> str:
    after, purpose = _AFTER.get()
    return f"read and {purpose}" if purpose and after > READ_BYTES_PER_VALUE else "read"


def _budget(budget) -> tuple[int, str]:
    if budget is None:
        return memory_budget(None)
    if isinstance(budget, tuple):
        return budget
    return int(budget), "the memory budget"


def _refuse_size(what: str, path, desc: str, nbytes: float, budget) -> None:
    limit, source = _budget(budget)
    if nbytes > limit:
        raise MemoryBudgetError(f"{what} {str(path)!r} declares {desc}, which would need about "
                                f"{format_bytes(nbytes)} to {_purpose()}, more than the memory budget of "
                                f"{format_bytes(limit)} ({source}); crop or resample the map")


def _file(path, what: str) -> Path:
    path = Path(path)
    problem = not_a_file(path)
    if problem == "not found":
        raise InputError(f"{what}: file not found: {str(path)!r}")
    if problem is not None:
        raise InputError(f"{what}: {str(path)!r} {problem}")
    return path


def _npy_header(fh, what: str, name: str) -> tuple[tuple, np.dtype, bool, int]:
    """(shape, dtype, fortran_order, header length) of an open ``.npy`` stream, checked
    without reading the data; a pickled (object) array is refused."""
    magic = fh.read(8)
    if len(magic) < 8 or magic[:6] != b"\x93NUMPY":
        raise InputError(f"{what} {name!r} is not a .npy array (no NumPy header; an empty, "
                         f"truncated or other file)")
    major = magic[6]
    if major == 1:
        raw = fh.read(2)
        size = struct.unpack("<H", raw)[0] if len(raw) == 2 else -1
    elif major in (2, 3):
        raw = fh.read(4)
        size = struct.unpack("<I", raw)[0] if len(raw) == 4 else -1
    else:
        raise InputError(f"{what} {name!r}: unknown .npy format version {major}")
    if size < 0 or size > 65536:
        raise InputError(f"{what} {name!r}: damaged .npy header")
    text = fh.read(size)
    if len(text) != size:
        raise InputError(f"{what} {name!r}: truncated .npy header")
    try:
        d = ast.literal_eval(text.decode("latin1"))
        descr, fortran, shape = d["descr"], bool(d["fortran_order"]), tuple(d["shape"])
        dtype = np.lib.format.descr_to_dtype(descr)
    except Exception:  # a damaged header can fail in many ways; all mean "not readable"
        raise InputError(f"{what} {name!r}: damaged .npy header {text[:80]!r}") from None
    if not all(type(n) is int and n >= 0 for n in shape):  # True is an int, not a size
        raise InputError(f"{what} {name!r}: .npy shape must be non-negative integers, "
                         f"received {shape!r}")
    if dtype.hasobject:
        raise InputError(f"{what} {name!r} holds Python objects (a pickle): refused, as "
                         f"loading it could run code; save the heights as a float array")
    return shape, dtype, fortran, 8 + (2 if major == 1 else 4) + size


def check_values(path: str | Path, *, what: str, desc: str, count: float,
                 budget: int | tuple[int, str] | None = None,
                 extra_bytes: float = 0) -> None:
    """Refuse a file that declares ``count`` height values (``desc`` says how, e.g. "a
    4096 x 4096 grid") when reading them would not fit the budget
    (:func:`per_value_bytes` each, plus ``extra_bytes`` the reader holds besides)."""
    _refuse_size(what, path, desc, float(count) * per_value_bytes() + float(extra_bytes), budget)


def check_file_values(path: str | Path, *, what: str, bytes_per_value: int,
                      budget: int | tuple[int, str] | None = None) -> int:
    """For a reader that loads a whole uncompressed file at once: refuse it when the
    values the file can hold (its size / ``bytes_per_value``) would not fit the budget.
    Returns the file's size in bytes."""
    path = _file(path, what)
    size = path.stat().st_size
    _refuse_size(what, path, f"{format_bytes(size)} of data (up to "
                             f"{format_number(size / bytes_per_value)} values)",
                 size + size / bytes_per_value * per_value_bytes(), budget)
    return size


def check_real_array(dtype: np.dtype, shape: tuple[int, ...], *, what: str, name: str,
                     ndim: int | None = 2) -> None:
    """Refuse arrays that are not real numbers (complex, text, records) or not ``ndim``-D."""
    dtype = np.dtype(dtype)
    if dtype.kind == "c":
        raise InputError(f"{what} {name!r} holds complex numbers ({dtype}); a height map must "
                         f"be real (save np.real(z) or np.abs(z) explicitly)")
    if dtype.kind not in "fiub":
        raise InputError(f"{what} {name!r} must hold real numbers, got dtype {dtype}")
    if ndim is not None and len(shape) != ndim:
        raise InputError(f"{what} {name!r} must be a {ndim}-D array, got shape {tuple(shape)}")


def check_npy(path: str | Path, *, what: str, budget: int | tuple[int, str] | None = None,
              ndim: int | None = 2) -> tuple[tuple, np.dtype]:
    """Check a ``.npy`` file before loading: a NumPy header, a real-number dtype (no
    pickles, no complex), ``ndim`` dimensions, a file long enough for what the header
    declares, and a size within the budget.  Returns (shape, dtype)."""
    path = _file(path, what)
    with open(path, "rb") as fh:
        shape, dtype, _, offset = _npy_header(fh, what, str(path))
    check_real_array(dtype, shape, what=what, name=str(path), ndim=ndim)
    count = 1
    for n in shape:
        count *= n
    nbytes = count * dtype.itemsize
    _refuse_size(what, path, f"a {' x '.join(format_number(n) for n in shape)} array",
                 count * per_value_bytes(), budget)
    have = path.stat().st_size - offset
    if have < nbytes:
        raise InputError(f"{what} {str(path)!r} is truncated: its header declares "
                         f"{format_bytes(nbytes)} of data, the file holds {format_bytes(have)}")
    return shape, dtype


def check_zip(path: str | Path, *, what: str, budget: int | tuple[int, str] | None = None,
              max_members: int = MAX_ZIP_MEMBERS,
              kind: str = "zip archive") -> list[zipfile.ZipInfo]:
    """Check a zip archive (npz, X3P) before reading members: a readable central
    directory, at most ``max_members`` members, a declared uncompressed total within the
    budget and no member that expands implausibly (a zip bomb).  Returns the members."""
    path = _file(path, what)
    try:
        with zipfile.ZipFile(path) as zf:
            infos = zf.infolist()
    except _ZIP_ERRORS as err:
        raise InputError(f"{what} {str(path)!r} is not a readable {kind} ({err})") from None
    if len(infos) > max_members:
        raise InputError(f"{what} {str(path)!r} holds {len(infos)} members (at most {max_members})")
    total = sum(i.file_size for i in infos)
    _refuse_size(what, path, f"{format_bytes(total)} of uncompressed content", total * 2, budget)
    for i in infos:
        if i.file_size > _RATIO_FLOOR and i.file_size > MAX_ZIP_RATIO * max(i.compress_size, 1):
            raise InputError(f"{what} {str(path)!r}: member {i.filename!r} expands from "
                             f"{format_bytes(i.compress_size)} to {format_bytes(i.file_size)} "
                             f"(more than {MAX_ZIP_RATIO:g} times): refused as a zip bomb")
    return infos


def check_npz(path: str | Path, *, what: str, budget: int | tuple[int, str] | None = None,
              names: Iterable[str] | None = None) -> dict[str, tuple]:
    """Check a ``.npz`` archive before loading: :func:`check_zip`, then the header of each
    ``.npy`` member (``names``: only those) as :func:`check_npy` does (no pickles, sizes
    within the budget).  Returns ``{name: (shape, dtype)}``."""
    path = _file(path, what)
    infos = check_zip(path, what=what, budget=budget, kind=".npz archive (a zip archive)")
    out = {}
    total = 0
    with zipfile.ZipFile(path) as zf:
        for i in infos:
            if not i.filename.endswith(".npy"):
                continue
            name = i.filename[:-4]
            if names is not None and name not in names:
                continue
            try:
                with zf.open(i) as fh:
                    shape, dtype, _, _ = _npy_header(fh, what, f"{path}:{i.filename}")
            except _ZIP_ERRORS as err:
                raise InputError(f"{what} {str(path)!r}: member {i.filename!r} cannot be read "
                                 f"({err})") from None
            count = 1
            for n in shape:
                count *= n
            if count * dtype.itemsize > i.file_size:
                raise InputError(f"{what} {str(path)!r}: member {i.filename!r} is truncated "
                                 f"(its header declares more data than it holds)")
            total += count
            out[name] = (shape, dtype)
    _refuse_size(what, path, f"{format_number(total)} values", total * per_value_bytes(), budget)
    return out


def _x3p_sizes(text: bytes, what: str, path) -> tuple[int, int, int]:
    """SizeX, SizeY, SizeZ of an X3P ``main.xml`` (0 where not declared), parsed as XML
    with defusedxml (no DTDs, entities or external references), whatever the spacing,
    comments or namespace prefixes."""
    try:
        from defusedxml import ElementTree as SafeET
        from defusedxml.common import DefusedXmlException
    except ImportError:  # pragma: no cover - installed with x3pio
        raise InputError(f"{what} {str(path)!r}: reading X3P files needs the defusedxml package "
                         f"(pip install render_inspect[metrology])") from None
    try:
        root = SafeET.fromstring(text, forbid_dtd=True, forbid_entities=True,
                                 forbid_external=True)
    except DefusedXmlException as err:
        raise InputError(f"{what} {str(path)!r}: main.xml uses XML features refused for safety "
                         f"({type(err).__name__})") from None
    except Exception as err:  # ParseError, UnicodeDecodeError, ValueError
        raise InputError(f"{what} {str(path)!r}: main.xml is not well-formed XML "
                         f"({type(err).__name__}: {err})") from None
    found: dict[str, list[str]] = {"X": [], "Y": [], "Z": []}
    for el in root.iter():
        tag = el.tag.rsplit("}", 1)[-1] if isinstance(el.tag, str) else ""
        if tag in ("SizeX", "SizeY", "SizeZ"):
            found[tag[-1]].append("".join(el.itertext()).strip())
    sizes = []
    for axis in "XYZ":
        vals = []
        for t in found[axis]:
            if not re.fullmatch(r"\+?\d{1,19}", t):
                raise InputError(f"{what} {str(path)!r}: main.xml Size{axis} must be a whole "
                                 f"number >= 0, received {t[:40]!r}")
            vals.append(int(t))
        sizes.append(max(vals, default=0))  # several declarations: the largest counts
    return sizes[0], sizes[1], sizes[2]


def check_x3p(path: str | Path, *, what: str,
              budget: int | tuple[int, str] | None = None) -> tuple[int, int, int]:
    """Check an X3P file before reading: :func:`check_zip`, then the grid size its
    ``main.xml`` declares (SizeX x SizeY x SizeZ, read as XML: :func:`_x3p_sizes`) within
    the budget.  Returns the sizes (0 where not declared)."""
    path = _file(path, what)
    infos = check_zip(path, what=what, budget=budget, kind="X3P file (a zip archive)")
    main = [i for i in infos if i.filename.replace("\\", "/").rsplit("/", 1)[-1] == "main.xml"]
    if not main:
        raise InputError(f"{what} {str(path)!r} is not an X3P file (no main.xml in the archive)")
    if main[0].file_size > 64 * MIB_TO_BYTES:
        raise InputError(f"{what} {str(path)!r}: main.xml is {format_bytes(main[0].file_size)}; "
                         f"refused (an X3P's main.xml is a few kB unless it lists the points)")
    with zipfile.ZipFile(path) as zf:
        try:
            text = zf.read(main[0])
        except _ZIP_ERRORS as err:
            raise InputError(f"{what} {str(path)!r}: main.xml cannot be read ({err})") from None
    sx, sy, sz = _x3p_sizes(text, what, path)
    count = max(sx, 1) * max(sy, 1) * max(sz, 1)
    _refuse_size(what, path, f"a {sx} x {sy} x {sz} grid", count * (per_value_bytes() + 16),
                 budget)
    return sx, sy, sz


def check_exr(path: str | Path, *, what: str,
              budget: int | tuple[int, str] | None = None) -> tuple[int, int, int]:
    """Check an OpenEXR file before reading the pixels: a readable header and a data
    window whose channels fit the budget.  Returns (height, width, channels)."""
    import OpenEXR

    path = _file(path, what)
    held = None
    try:
        with open(path, "rb") as fh:
            if fh.read(4) != b"\x76\x2f\x31\x01":
                raise InputError(f"{what} {str(path)!r} is not an OpenEXR file (no EXR magic "
                                 f"number; an empty, truncated or other file)")
        with library_messages() as held, OpenEXR.File(str(path), header_only=True) as f:
            header = dict(f.header())
    except InputError:
        raise
    except Exception as err:  # OpenEXR raises RuntimeError/ValueError/OSError on damaged files
        raise InputError(f"{what} {str(path)!r} is not a readable OpenEXR file "
                         f"({type(err).__name__}: {err}{held.summary() if held else ''})") from None
    win: Any = header.get("dataWindow")  # what the file says; checked below
    chans = header.get("channels") or []
    try:
        (x0, y0), (x1, y1) = (tuple(int(v) for v in p) for p in win)
        w, h = x1 - x0 + 1, y1 - y0 + 1
    except (TypeError, ValueError):
        raise InputError(f"{what} {str(path)!r}: the EXR header has no valid data window") from None
    if w <= 0 or h <= 0:
        raise InputError(f"{what} {str(path)!r}: the EXR data window is empty ({w} x {h})")
    n = max(len(chans), 1)
    _refuse_size(what, path, f"{n} channel(s) of {w} x {h} pixels",
                 w * h * n * (4 + 8 + 8) + w * h * (per_value_bytes() - READ_BYTES_PER_VALUE),
                 budget)
    return h, w, n


def check_frames(frames: np.ndarray, valid: np.ndarray | None = None, *, what: str,
                 path: str | Path) -> np.ndarray:
    """Check an interferogram's frames (``(n, ny, nx)``) before a measurement: a pixel is
    usable when it is ``valid`` and every frame holds a finite intensity there.  Returns
    that mask; refuses (one line naming ``what`` and the file) a stack in which no pixel
    is usable, e.g. all-NaN frames, which would otherwise give an empty height map and
    exit 0."""
    frames = np.asarray(frames)
    if frames.ndim != 3 or frames.shape[0] < 1:
        raise InputError(f"{what} {str(path)!r} must hold frames of shape (n, rows, columns), "
                         f"received shape {frames.shape}")
    if frames.dtype.kind not in "fiu":
        raise InputError(f"{what} {str(path)!r} must hold real intensities, received dtype "
                         f"{frames.dtype}")
    usable = np.ones(frames.shape[1:], dtype=bool) if valid is None else np.asarray(valid, bool).copy()
    if usable.shape != frames.shape[1:]:
        raise InputError(f"{what} {str(path)!r}: the valid mask has shape {usable.shape}, the "
                         f"frames {frames.shape[1:]}")
    for k in range(frames.shape[0]):
        usable &= np.isfinite(frames[k])
    if not usable.any():
        bad = int(np.count_nonzero(~np.isfinite(frames[0])))
        raise InputError(f"{what} {str(path)!r} has no pixel with a finite intensity in every "
                         f"frame ({bad} of {frames[0].size} pixels of the first frame are NaN or "
                         f"infinite): nothing can be measured")
    return usable


def read_json_file(path: str | Path, *, what: str, max_bytes: int = MAX_JSON_BYTES) -> dict:
    """Read a small JSON object (a side-car file): at most ``max_bytes``, UTF-8, strict
    JSON (no NaN), an object at the top.  Malformed content is an :class:`InputError`."""
    path = _file(path, what)
    size = path.stat().st_size
    if size > max_bytes:
        raise InputError(f"{what} {str(path)!r} is {format_bytes(size)}; a side-car JSON file "
                         f"is at most {format_bytes(max_bytes)}")

    def no_constants(name):
        raise ValueError(f"{name} is not strict JSON")

    try:
        d = json.loads(path.read_bytes().decode("utf-8"), parse_constant=no_constants)
    except (UnicodeDecodeError, ValueError, RecursionError) as err:
        raise InputError(f"{what} {str(path)!r} is not valid JSON ({err})") from None
    if not isinstance(d, dict):
        raise InputError(f"{what} {str(path)!r} must hold a JSON object {{...}}, got "
                         f"{type(d).__name__}")
    return d
