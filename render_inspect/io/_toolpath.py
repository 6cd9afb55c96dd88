"""Machine programs on disk: turning tool paths (npz of the contracts, a generic C-X-Z NC
program, CSV) and sculpturing programs (npz, CSV, a generic X-Y-Z NC program).

NC program (``toolpath.nc``), a generic, documented dialect (ISO 6983 words):

```
; render_inspect generic C-X-Z turning program
; units: mm, deg [C cumulative: it keeps counting past 360 over the spiral]
; time: inverse-time feed G93, F = 1 / [minutes of the move ending at the block]
; software_version: 0.1.0
; scene: rcse_circular_array
; spindle_rpm: 42
; points: 1368001
; t0_s: 0.0
G90 G93
N1 G01 C0.000000 X4.750000 Z-0.000010
N2 G01 C0.250000 X4.749997 Z-0.000010 F60480.00000000
...
M30
```

- ``;`` starts a comment (to the end of the line); ``(...)`` comments and ``%`` tape
  marks are also skipped by the reader.
- ``C`` in degrees, ``X`` (radius) and ``Z`` (tool tip) in mm, ``decimals`` places
  (default 6: 1 nm and 1 micro-degree).
- Time: the first block is the start position at ``t0_s``; every later block carries an
  inverse-time feed word ``F`` (G93: the move ending at this block takes 1/F minutes),
  written with 10 significant digits, so t is recovered to better than 1e-6 s.
- Words are modal: a block without a word keeps the previous value.

CSV (``toolpath.csv``), one row per point, header
``t_s,c_deg,x_mm,z_mm,theta_rad,rho_mm,y_mm``: ``c_deg`` = C (cumulative deg),
``x_mm``/``y_mm`` the Cartesian tool-tip position in the workpiece frame
(rho cos theta, rho sin theta), ``z_mm`` Z, ``theta_rad`` = C in rad, ``rho_mm`` = X axis.
Full double precision (``repr``-exact, 17 significant digits).

Every comment line, the program's own and those carrying scene text (names, comments),
is one ``;`` line of printable ASCII without control characters, with ``;``, ``(`` and
``)`` replaced (:func:`nc_comment_text`), so no text can start a block of its own or open
a comment in a dialect that uses parentheses; scene text never reaches the CSV files.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.toolpath import LinearProgram, ToolPath
from ..core.units import MIN_TO_S
from ._atomic import atomic_write_stream
from ._limits import check_npz
from ._registry import formats, register_writer, writer

__all__ = ["write_nc", "read_nc", "write_csv", "read_csv", "write_toolpath_npz",
           "read_toolpath_npz", "write_program_npz", "write_program_csv", "write_program_nc",
           "export_program", "program_formats", "nc_comment_text", "read_program_nc", "CSV_COLUMNS",
           "PROGRAM_CSV_COLUMNS", "CHUNK_ROWS"]

#: rows formatted at a time by the writers (their memory does not grow with the program)
CHUNK_ROWS = 16384

CSV_COLUMNS = ("t_s", "c_deg", "x_mm", "z_mm", "theta_rad", "rho_mm", "y_mm")
PROGRAM_CSV_COLUMNS = ("t_s", "x_mm", "y_mm", "z_mm", "line")
_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


def nc_comment_text(value) -> str:
    """``value`` as text safe inside a ``;`` comment of an NC program: printable ASCII only
    (every other character, line breaks and carriage returns included, becomes a space),
    ``;`` -> ``,`` and ``(``/``)`` -> ``[``/``]`` (comment delimiters of common dialects),
    runs of spaces collapsed."""
    text = str(value)
    out = []
    for ch in text:
        o = ord(ch)
        if ch == ";":
            out.append(",")
        elif ch == "(":
            out.append("[")
        elif ch == ")":
            out.append("]")
        elif 32 <= o < 127:
            out.append(ch)
        else:
            out.append(" ")
    return re.sub(r" {2,}", " ", "".join(out)).strip()


def _header_lines(title: str, info: dict) -> list[str]:
    lines = [f"; {nc_comment_text(title)}"]
    for k, v in info.items():
        if not re.fullmatch(r"[A-Za-z0-9_]+", str(k)):
            raise InputError(f"NC header keys must be words of letters, digits and _, received {k!r}")
        lines.append(f"; {k}: {nc_comment_text(v)}")
    return lines


def _turning_header(header: dict | None, toolpath) -> list[str]:
    info = {"software_version": __version__}
    meta = getattr(toolpath, "meta", {}) or {}
    for k in ("spindle_rpm", "compensation", "method", "feed_per_rev_mm", "nose_radius"):
        if k in meta:
            info[k] = meta[k]
    info.update(header or {})
    lines = _header_lines("render_inspect generic C-X-Z turning program", {})
    lines += ["; units: mm, deg [C cumulative: it keeps counting past 360 over the spiral]",
              "; time: inverse-time feed G93, F = 1 / [minutes of the move ending at the block]"]
    return lines + _header_lines("", info)[1:]


def write_nc(path, toolpath, *, header: dict | None = None, decimals: int = 6) -> Path:
    """Write ``toolpath`` as a generic C-X-Z NC program (format in the module docstring).

    Parameters
    ----------
    path : str or Path
        Output file (written atomically).
    toolpath : ToolPath
        ``t`` must be strictly increasing.
    header : dict, optional
        Extra ``; key: value`` header lines (e.g. ``{"scene": name, "spindle_rpm": 42}``);
        values pass through :func:`nc_comment_text`.
    decimals : int
        Places for C (deg), X and Z (mm), 3..12.

    Returns
    -------
    Path
    """
    if not (isinstance(decimals, int) and 3 <= decimals <= 12):
        raise InputError(f"decimals must be an integer in [3, 12], received {decimals!r}")
    t = np.asarray(toolpath.t, dtype=np.float64)
    n = t.size
    if n == 0:
        raise InputError("cannot write an NC program of an empty tool path (0 points)")
    dt = np.diff(t)
    if np.any(~(dt > 0)):
        i = int(np.flatnonzero(~(dt > 0))[0])
        raise InputError(f"ToolPath.t must be strictly increasing to write inverse-time feeds; "
                         f"t[{i}] = {t[i]!r} s, t[{i + 1}] = {t[i + 1]!r} s")
    c = np.degrees(np.asarray(toolpath.theta, dtype=np.float64))
    x = np.asarray(toolpath.rho, dtype=np.float64)
    z = np.asarray(toolpath.z, dtype=np.float64)
    for name, arr in (("theta", c), ("rho", x), ("z", z), ("t", t)):
        if not np.all(np.isfinite(arr)):
            raise InputError(f"ToolPath.{name} has non-finite values at index "
                             f"{int(np.flatnonzero(~np.isfinite(arr))[0])}")
    hdr = {"points": n, "t0_s": repr(float(t[0]))}
    hdr.update(header or {})
    lines = _turning_header(hdr, toolpath)
    lines.append("G90 G93")
    f = "{:.%df}" % decimals

    def write(fh):
        fh.write(("\n".join(lines) + "\n").encode("ascii"))
        for a in range(0, n, CHUNK_ROWS):
            b = min(a + CHUNK_ROWS, n)
            rows = []
            for i in range(a, b):
                words = f"N{i + 1} G01 C{f.format(c[i])} X{f.format(x[i])} Z{f.format(z[i])}"
                rows.append(words if i == 0 else words + " F%.10g" % (MIN_TO_S / dt[i - 1]))
            fh.write(("\n".join(rows) + "\n").encode("ascii"))
        fh.write(b"M30\n")

    return atomic_write_stream(path, write)


def read_nc(path):
    """Parse a program written by :func:`write_nc` (or any program in that dialect) back
    into a :class:`ToolPath` (theta from C, rho = X, z = Z, t from t0 and the F words).

    Header ``; key: value`` lines become ``meta``.  Raises :class:`InputError` naming the
    line for malformed blocks."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"NC file not found: {str(path)!r}")
    meta: dict = {}
    C, X, Z, F = [], [], [], []
    cur = {"C": None, "X": None, "Z": None}
    inverse_time = False
    with path.open("r", encoding="utf-8") as fh:
        for lineno, raw in enumerate(fh, 1):
            line = raw.strip()
            if line.startswith(";"):
                body = line[1:].strip()
                if ":" in body:
                    k, v = body.split(":", 1)
                    if re.fullmatch(r"[A-Za-z0-9_]+", k.strip()):
                        meta[k.strip()] = v.strip()
                continue
            line = re.sub(r"\([^)]*\)", " ", line.split(";", 1)[0]).strip().upper()
            if not line or line == "%":  # '%' marks the start / end of a program
                continue
            words = _WORD.findall(line)
            rest = _WORD.sub("", line).strip()
            if rest:
                raise InputError(f"{path}:{lineno}: cannot parse {rest!r} in block {raw.strip()!r}")
            d = {}
            for letter, num in words:
                if letter == "G" and float(num) == 93:
                    inverse_time = True
                d[letter] = num
            if not any(k in d for k in ("C", "X", "Z")):
                continue
            for k in ("C", "X", "Z"):
                if k in d:
                    cur[k] = float(d[k])
                if cur[k] is None:
                    raise InputError(f"{path}:{lineno}: first motion block lacks the {k} word")
            if C and "F" not in d:
                raise InputError(f"{path}:{lineno}: motion block without an F (inverse-time) word")
            C.append(cur["C"])
            X.append(cur["X"])
            Z.append(cur["Z"])
            F.append(float(d["F"]) if "F" in d else math.nan)
    if not C:
        raise InputError(f"{path}: no motion blocks (C/X/Z words) found")
    if len(C) > 1 and not inverse_time:
        raise InputError(f"{path}: the program must select inverse-time feed (G93) to carry time")
    f = np.asarray(F[1:], dtype=np.float64)
    if np.any(~(f > 0)):
        raise InputError(f"{path}: F words must be > 0 (inverse time, 1/min)")
    t0 = float(meta.get("t0_s", 0.0))
    t = t0 + np.concatenate([[0.0], np.cumsum(MIN_TO_S / f)])
    if "points" in meta and int(meta["points"]) != len(C):
        raise InputError(f"{path}: header says {meta['points']} points, the program has {len(C)}")
    return ToolPath(np.radians(np.asarray(C)), np.asarray(X), np.asarray(Z), t, meta)


def _write_rows(fh, columns, header: str, fmt) -> None:
    """CSV rows of ``columns`` (callables of a slice -> array), :data:`CHUNK_ROWS` at a
    time, each value formatted with ``fmt`` (one format, or one per column)."""
    fmts = [fmt] * len(columns) if isinstance(fmt, str) else list(fmt)
    row = ",".join(fmts)
    fh.write((header + "\n").encode("ascii"))
    n = len(columns[0](slice(0, None)))
    for a in range(0, n, CHUNK_ROWS):
        s = slice(a, min(a + CHUNK_ROWS, n))
        data = zip(*(col(s).tolist() for col in columns))
        fh.write(("\n".join(row % r for r in data) + "\n").encode("ascii"))


def write_csv(path, toolpath) -> Path:
    """Write ``toolpath`` as CSV with header ``t_s,c_deg,x_mm,z_mm,theta_rad,rho_mm,y_mm``
    (atomic; full double precision; written in pieces).  Returns the Path."""
    th = np.asarray(toolpath.theta, dtype=np.float64)
    rho = np.asarray(toolpath.rho, dtype=np.float64)
    t = np.asarray(toolpath.t, dtype=np.float64)
    z = np.asarray(toolpath.z, dtype=np.float64)
    cols = [lambda s: t[s], lambda s: np.degrees(th[s]), lambda s: rho[s] * np.cos(th[s]),
            lambda s: z[s], lambda s: th[s], lambda s: rho[s], lambda s: rho[s] * np.sin(th[s])]
    return atomic_write_stream(path, lambda fh: _write_rows(fh, cols, ",".join(CSV_COLUMNS),
                                                              "%.17g"))


def read_csv(path):
    """Read a CSV written by :func:`write_csv` back into a :class:`ToolPath`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"CSV file not found: {str(path)!r}")
    with path.open() as fh:
        head = fh.readline().strip().split(",")
    if tuple(head) != CSV_COLUMNS:
        raise InputError(f"{path}: CSV header must be {','.join(CSV_COLUMNS)}, received {','.join(head)}")
    d = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    col = {name: d[:, i] for i, name in enumerate(CSV_COLUMNS)}
    return ToolPath(col["theta_rad"].copy(), col["rho_mm"].copy(), col["z_mm"].copy(),
                    col["t_s"].copy())


def _savez(fh, **arrays) -> None:
    """``numpy.savez`` into an open binary file: the same archive (stored ``NAME.npy``
    members), with a fixed member date so the same arrays give the same bytes, and the
    archive closed even when a write fails."""
    import zipfile

    with zipfile.ZipFile(fh, mode="w", compression=zipfile.ZIP_STORED, allowZip64=True) as zf:
        for name, arr in arrays.items():
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            with zf.open(info, "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(arr), allow_pickle=False)


@register_writer("toolpath", ".npz")
def write_toolpath_npz(path, toolpath: ToolPath, **_) -> Path:
    """Write ``toolpath.npz`` with arrays theta, rho, x, y, z, t (atomic)."""
    return atomic_write_stream(path, lambda fh: _savez(
        fh, theta=toolpath.theta, rho=toolpath.rho, x=toolpath.x, y=toolpath.y, z=toolpath.z,
        t=toolpath.t))


def read_toolpath_npz(path) -> ToolPath:
    """Read a ``toolpath.npz`` written by :func:`write_toolpath_npz`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"tool-path file not found: {str(path)!r}")
    check_npz(path, what="tool-path file")
    with np.load(path, allow_pickle=False) as d:
        return ToolPath(d["theta"].copy(), d["rho"].copy(), d["z"].copy(), d["t"].copy())


register_writer("toolpath", ".csv")(lambda path, toolpath, **_: write_csv(path, toolpath))
register_writer("toolpath", ".nc")(
    lambda path, toolpath, *, header=None, **_: write_nc(path, toolpath, header=header))


# ---------------------------------------------------------------- sculpturing programs
@register_writer("program", ".npz")
def write_program_npz(path, program: LinearProgram, **_) -> Path:
    """Write a sculpturing program as ``toolpath.npz``: arrays x, y, z, t, line."""
    return atomic_write_stream(path, lambda fh: _savez(
        fh, x=program.x, y=program.y, z=program.z, t=program.t, line=program.line))


@register_writer("program", ".csv")
def write_program_csv(path, program: LinearProgram, **_) -> Path:
    """One row per point, header ``t_s,x_mm,y_mm,z_mm,line``."""
    cols = [lambda s: program.t[s], lambda s: program.x[s], lambda s: program.y[s],
            lambda s: program.z[s], lambda s: program.line[s]]
    return atomic_write_stream(path, lambda fh: _write_rows(
        fh, cols, ",".join(PROGRAM_CSV_COLUMNS), ["%.9f", "%.6f", "%.6f", "%.6f", "%d"]))


@register_writer("program", ".nc")
def write_program_nc(path, program: LinearProgram, *, header: dict | None = None,
                     feed_mm_per_min: float | None = None, **_) -> Path:
    """A generic X-Y-Z program (``G90 G94 G21``, ``G01`` moves at the cutting speed
    ``feed_mm_per_min``), a ``; line k`` comment before each target line."""
    vc = feed_mm_per_min if feed_mm_per_min is not None else program.meta.get("feed_mm_per_min")
    if vc is None or isinstance(vc, bool) or not (vc > 0 and math.isfinite(vc)):
        raise InputError(f"feed_mm_per_min must be > 0 for an X-Y-Z program, received {vc!r}")
    info = {"software_version": __version__}
    info.update(header or {})
    lines = _header_lines("render_inspect generic X-Y-Z sculpturing program [mm, mm/min]", info)
    lines.append("G90 G94 G21")
    x, y, z, ln = program.x, program.y, program.z, program.line
    for name, arr in (("x", x), ("y", y), ("z", z)):
        if not np.all(np.isfinite(arr)):
            raise InputError(f"LinearProgram.{name} has non-finite values at index "
                             f"{int(np.flatnonzero(~np.isfinite(arr))[0])}")
    feed = nc_comment_text(f"{float(vc):g}")

    def write(fh):
        fh.write(("\n".join(lines) + "\n").encode("ascii"))
        prev = None
        for a in range(0, program.points, CHUNK_ROWS):
            rows = []
            for i in range(a, min(a + CHUNK_ROWS, program.points)):
                if ln[i] != prev:
                    rows.append(f"; line {int(ln[i])}")
                    prev = ln[i]
                rows.append(f"N{i + 1} G01 X{x[i]:.6f} Y{y[i]:.6f} Z{z[i]:.6f} F{feed}")
            fh.write(("\n".join(rows) + "\n").encode("ascii"))
        fh.write(b"M30\n")

    return atomic_write_stream(path, write)


def read_program_nc(path) -> LinearProgram:
    """Parse an X-Y-Z program written by :func:`write_program_nc` back into a
    :class:`LinearProgram` (``line`` from the ``; line k`` comments, ``t`` from the path
    length at the ``F`` feed, mm/min).  Header ``; key: value`` lines become ``meta``.
    Raises :class:`InputError` naming the line for malformed blocks."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"NC file not found: {str(path)!r}")
    meta: dict = {}
    X, Y, Z, L, F = [], [], [], [], []
    cur = {"X": None, "Y": None, "Z": None, "F": None}
    line_no = -1
    with path.open("r", encoding="utf-8") as fh:
        for lineno, raw in enumerate(fh, 1):
            text = raw.strip()
            if text.startswith(";"):
                body = text[1:].strip()
                m = re.fullmatch(r"line (\d+)", body)
                if m:
                    line_no = int(m.group(1))
                elif ":" in body:
                    k, v = body.split(":", 1)
                    if re.fullmatch(r"[A-Za-z0-9_]+", k.strip()):
                        meta[k.strip()] = v.strip()
                continue
            text = re.sub(r"\([^)]*\)", " ", text.split(";", 1)[0]).strip().upper()
            if not text or text == "%":
                continue
            words = _WORD.findall(text)
            rest = _WORD.sub("", text).strip()
            if rest:
                raise InputError(f"{path}:{lineno}: cannot parse {rest!r} in block {raw.strip()!r}")
            d = dict(words)
            if not any(k in d for k in ("X", "Y", "Z")):
                continue
            for k in ("X", "Y", "Z", "F"):
                if k in d:
                    cur[k] = float(d[k])
                if cur[k] is None:
                    raise InputError(f"{path}:{lineno}: first motion block lacks the {k} word")
            X.append(cur["X"])
            Y.append(cur["Y"])
            Z.append(cur["Z"])
            F.append(cur["F"])
            L.append(line_no)
    if not X:
        raise InputError(f"{path}: no motion blocks (X/Y/Z words) found")
    x, y, z, f = (np.asarray(v, dtype=np.float64) for v in (X, Y, Z, F))
    if np.any(~(f > 0)):
        raise InputError(f"{path}: F words must be > 0 (mm/min)")
    seg = np.sqrt(np.diff(x) ** 2 + np.diff(y) ** 2 + np.diff(z) ** 2)
    t = np.concatenate([[0.0], np.cumsum(seg / (f[1:] / MIN_TO_S))])  # mm/min -> mm/s
    if "points" in meta and meta["points"].isdigit() and int(meta["points"]) != x.size:
        raise InputError(f"{path}: header says {meta['points']} points, the program has {x.size}")
    return LinearProgram(x, y, z, t, np.asarray(L, dtype=np.int64), meta)


def program_formats() -> list[str]:
    """The names ``toolpath --format`` takes: the extensions (without the dot) a machine
    program has a registered writer for (products ``toolpath`` and ``program``)."""
    exts = set(formats("toolpath", kind="write")) | set(formats("program", kind="write"))
    return sorted(e.lstrip(".") for e in exts)


def export_program(program, out_dir, *, fmt: str = "npz", header: dict | None = None,
                   **options) -> Path:
    """Write a turning :class:`ToolPath` or a sculpturing :class:`LinearProgram` into
    ``out_dir`` as ``toolpath.<fmt>`` (atomically) with the writer registered for it.

    Parameters
    ----------
    program : ToolPath or LinearProgram
    out_dir : str or Path
        Folder (created if needed).
    fmt : str
        One of :func:`program_formats` (``npz``, ``csv``, ``nc``, ...).
    header : dict, optional
        NC header lines (``scene``, ``spindle_rpm``, ...); ignored by npz and csv.
    **options
        Passed to the writer (``feed_mm_per_min`` for sculpturing NC).

    Returns
    -------
    Path of the file written.
    """
    product = "program" if isinstance(program, LinearProgram) else "toolpath"
    if fmt not in program_formats():
        raise InputError(f"--format must be one of {program_formats()}, received {fmt!r}")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return writer(product, fmt)(out / f"toolpath.{fmt}", program, header=header, **options)
