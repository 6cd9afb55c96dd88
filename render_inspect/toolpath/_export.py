"""Tool-path export: a generic C-X-Z NC program, CSV, and the npz of the contracts.

NC program (``toolpath.nc``), a generic, documented dialect (ISO 6983 words):

```
; render_inspect generic C-X-Z turning program
; units: mm, deg (C cumulative: it keeps counting past 360 over the spiral)
; time: inverse-time feed (G93); F = 1 / (minutes of the move ending at the block)
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
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["write_nc", "read_nc", "write_csv", "read_csv", "export_toolpath", "FORMATS",
           "CSV_COLUMNS"]

CSV_COLUMNS = ("t_s", "c_deg", "x_mm", "z_mm", "theta_rad", "rho_mm", "y_mm")
_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")


def _header_lines(header: dict | None, toolpath) -> list[str]:
    from .. import __version__

    info = {"software_version": __version__}
    meta = getattr(toolpath, "meta", {}) or {}
    for k in ("spindle_rpm", "compensation", "method", "feed_per_rev_mm", "nose_radius"):
        if k in meta:
            info[k] = meta[k]
    info.update(header or {})
    lines = ["; render_inspect generic C-X-Z turning program",
             "; units: mm, deg (C cumulative: it keeps counting past 360 over the spiral)",
             "; time: inverse-time feed (G93); F = 1 / (minutes of the move ending at the block)"]
    for k, v in info.items():
        text = str(v).replace("\n", " ")
        if not re.fullmatch(r"[A-Za-z0-9_]+", str(k)):
            raise InputError(f"NC header keys must be words of letters, digits and _, received {k!r}")
        lines.append(f"; {k}: {text}")
    return lines


def write_nc(path, toolpath, *, header: dict | None = None, scene=None, decimals: int = 6) -> Path:
    """Write ``toolpath`` as a generic C-X-Z NC program (format in the module docstring).

    Parameters
    ----------
    path : str or Path
        Output file (written atomically).
    toolpath : ToolPath
        ``t`` must be strictly increasing.
    header : dict, optional
        Extra ``; key: value`` header lines (e.g. ``{"scene": name, "spindle_rpm": 42}``).
    scene : Scene, optional
        Adds ``scene`` (name), ``process``, ``spindle_rpm``, ``feed_per_rev_mm``,
        ``compensation`` and ``nose_radius`` header lines (``header`` wins on a clash).
    decimals : int
        Places for C (deg), X and Z (mm), 3..12.

    Returns
    -------
    Path
    """
    from ..io import atomic_write_text

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
    if scene is not None:
        hdr.update({"scene": scene.name, "process": scene.process.kind,
                    "spindle_rpm": scene.process.spindle_rpm,
                    "feed_per_rev_mm": scene.process.feed_per_rev,
                    "compensation": scene.process.compensation,
                    "nose_radius": scene.tool.nose_radius})
    hdr.update(header or {})
    lines = _header_lines(hdr, toolpath)
    lines.append("G90 G93")
    f = "{:.%df}" % decimals
    cs = [f.format(v) for v in c]
    xs = [f.format(v) for v in x]
    zs = [f.format(v) for v in z]
    feed = ["%.10g" % v for v in (60.0 / dt)] if n > 1 else []
    lines.append(f"N1 G01 C{cs[0]} X{xs[0]} Z{zs[0]}")
    lines.extend(f"N{i + 1} G01 C{cs[i]} X{xs[i]} Z{zs[i]} F{feed[i - 1]}" for i in range(1, n))
    lines.append("M30")
    return atomic_write_text(path, "\n".join(lines) + "\n")


def read_nc(path):
    """Parse a program written by :func:`write_nc` (or any program in that dialect) back
    into a :class:`ToolPath` (theta from C, rho = X, z = Z, t from t0 and the F words).

    Header ``; key: value`` lines become ``meta``.  Raises :class:`InputError` naming the
    line for malformed blocks."""
    from ._path import ToolPath

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
    t = t0 + np.concatenate([[0.0], np.cumsum(60.0 / f)])
    if "points" in meta and int(meta["points"]) != len(C):
        raise InputError(f"{path}: header says {meta['points']} points, the program has {len(C)}")
    return ToolPath(np.radians(np.asarray(C)), np.asarray(X), np.asarray(Z), t, meta)


def write_csv(path, toolpath) -> Path:
    """Write ``toolpath`` as CSV with header ``t_s,c_deg,x_mm,z_mm,theta_rad,rho_mm,y_mm``
    (atomic; full double precision).  Returns the Path."""
    import io

    from ..io import atomic_write_text

    th = np.asarray(toolpath.theta, dtype=np.float64)
    rho = np.asarray(toolpath.rho, dtype=np.float64)
    data = np.column_stack([toolpath.t, np.degrees(th), rho * np.cos(th), toolpath.z, th, rho,
                            rho * np.sin(th)])
    buf = io.StringIO()
    np.savetxt(buf, data, delimiter=",", fmt="%.17g", header=",".join(CSV_COLUMNS), comments="")
    return atomic_write_text(path, buf.getvalue())


def read_csv(path):
    """Read a CSV written by :func:`write_csv` back into a :class:`ToolPath`."""
    from ._path import ToolPath

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


def _write_npz(path, toolpath, header=None, scene=None):
    return toolpath.save_npz(path)


def _write_csv(path, toolpath, header=None, scene=None):
    return write_csv(path, toolpath)


def _write_nc(path, toolpath, header=None, scene=None):
    return write_nc(path, toolpath, header=header, scene=scene)


#: format name -> (file name, writer(path, toolpath, header, scene))
FORMATS = {"npz": ("toolpath.npz", _write_npz), "csv": ("toolpath.csv", _write_csv),
           "nc": ("toolpath.nc", _write_nc)}


def export_toolpath(toolpath, out_dir, *, fmt: str = "npz", header: dict | None = None,
                    scene=None) -> Path:
    """Write ``toolpath`` into ``out_dir`` as ``toolpath.npz`` / ``.csv`` / ``.nc``.

    Parameters
    ----------
    toolpath : ToolPath
    out_dir : str or Path
        Folder (created if needed); the file is written atomically.
    fmt : {"npz", "csv", "nc"}
    header : dict, optional
        NC header lines (``scene``, ``spindle_rpm``, ...); ignored by npz and csv.
    scene : Scene, optional
        NC header lines from the scene (see :func:`write_nc`); ignored by npz and csv.

    Returns
    -------
    Path of the file written.
    """
    if fmt not in FORMATS:
        raise InputError(f"--format must be one of {sorted(FORMATS)}, received {fmt!r}")
    name, writer = FORMATS[fmt]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return writer(out / name, toolpath, header, scene)
