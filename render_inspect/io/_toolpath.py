"""Machine programs on disk: turning tool paths (npz of the contracts, a generic C-X-Z NC
program, CSV) and sculpturing programs (npz, CSV, a generic X-Y-Z NC program).

NC program (``toolpath.nc``), a generic, documented dialect (ISO 6983 words):

```
; render_inspect generic C-X-Z turning program
; units: mm, deg [C cumulative: it keeps counting past 360 over the spiral]
; time: inverse-time feed G93, F = 1 / [minutes of the move ending at the block]
; software_version: 0.1.0
; created_utc: 2025-01-31T12:00:00Z
; spindle_rpm: 42
; points: 1368001
; t0_s: 0.0
; blocks: 1368005
; cut_time_s: 1357.142857
; block_rate_max_per_s: 1008
; scene: rcse_circular_array
; clearance_z_mm: 0.112
; plunge_feed_mm_per_min: 10
G18 G21 G40
G90 G93
; approach
N1 G00 Z0.112000
N2 G00 C0.000000 X4.750000 Z0.112000
N3 G01 C0.000000 X4.750000 Z-0.000010 F89.10000000
; cut
N4 G01 C0.250000 X4.749997 Z-0.000010 F60480.00000000
...
; exit
N1368004 G01 C342000.000000 X0.000000 Z0.112000 F90.90909091
N1368005 G00 C342000.000000 X4.750000 Z0.112000
M30
```

- ``G18 G21 G40`` (the Z-X plane, mm, the control's own nose compensation off: the
  path is compensated) and ``G90 G93`` (absolute, inverse time) before the first move,
  ``M30`` at the end; ``; tool:`` and ``; spindle:`` lines say how the tool is set and
  that C is the spindle under position control (the M code for C-axis mode is the
  machine's own, not written).  ``created_utc`` is the time of writing, or the time
  ``SOURCE_DATE_EPOCH`` gives.
- ``;`` starts a comment (to the end of the line); ``(...)`` comments and ``%`` tape
  marks are also skipped by the reader.
- ``C`` in degrees, ``X`` (radius) and ``Z`` (tool tip) in mm, ``decimals`` places
  (default 6: 1 nm and 1 micro-degree).
- Time: the cut starts at ``t0_s`` where the approach leaves the tool; every cutting
  block carries an inverse-time feed word ``F`` (G93: the move ending at this block
  takes 1/F minutes), written with 10 significant digits, so t is recovered to better
  than 1e-6 s.
- Words are modal: a block without a word keeps the previous value.
- With links (:class:`~render_inspect.core.toolpath.Links`, written by the ``toolpath``
  command): ``; approach`` (a rapid ``G00`` up to the clearance plane, Z alone since
  where the machine starts is not known; a rapid within the plane above the first cut
  point; a vertical plunge ``G01`` onto it at the plunge feed), ``; cut`` (the cutting
  blocks), ``; exit`` (a vertical retract at the plunge feed to the clearance plane, a
  rapid within it back above the start).  A sculpturing program has the same approach
  and exit and, between two lines, ``; link``: a vertical retract, a rapid within the
  clearance plane above the next line's start and a vertical plunge; each line's
  cutting blocks follow a ``; line k`` comment.  Without links (a program written by
  :func:`write_nc` without ``links``) every motion block is a cutting block.

CSV (``toolpath.csv``), one row per point, header
``t_s,c_deg,x_mm,z_mm,theta_rad,rho_mm,y_mm``: ``c_deg`` = C (cumulative deg),
``x_mm``/``y_mm`` the Cartesian tool-tip position in the workpiece frame
(rho cos theta, rho sin theta), ``z_mm`` Z, ``theta_rad`` = C in rad, ``rho_mm`` = X axis.
Full double precision (``repr``-exact, 17 significant digits).

The angles of every format are the part's own: C decreases for a path cut with the
spindle turning counter-clockwise (``spindle_direction`` = ``"M04"`` in the path's meta,
the NC header and the npz), and the readers take C decreasing throughout as that turning
(:func:`~render_inspect.core.toolpath.path_from_part`).

Every comment line, the program's own and those carrying scene text (names, comments),
is one ``;`` line of printable ASCII without control characters, with ``;``, ``(`` and
``)`` replaced (:func:`nc_comment_text`), so no text can start a block of its own or open
a comment in a dialect that uses parentheses; scene text never reaches the CSV files.

For a Fanuc-type control (where ``;`` ends a block and only ``( ... )`` is a comment) the
writers take ``comments="parenthesis"``: every comment line is then ``(text)``, the same
text (``(render_inspect generic C-X-Z turning program)``, ``(points: 1368001)``,
``(approach)``, ``(line 3)``), never a parenthesis inside it (``(`` and ``)`` of scene
text become ``[`` and ``]``).  ``block_numbers`` sets the increment of the block numbers
(1: ``N1``, ``N2``, ...; 10: ``N10``, ``N20``, ...) or writes none (0: each block starts
``G00`` / ``G01``).  The readers take every such program as the project's own and read
the same program from it.
"""

from __future__ import annotations

from typing import Any
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import SPINDLE_KEY, LinearProgram, ToolPath, part_angle, path_from_part, turns_m04
from ._atomic import atomic_write_stream
from ._limits import check_npz
from ._nc import (CHUNK_ROWS, COMMENT_STYLES, check_nc_style, cut_points, nc_comment_text,
                  program_axes, program_blocks, read_nc, read_nc_blocks, read_program_nc, write_nc,
                  write_program_nc)
from ._registry import formats, register_writer, writer

__all__ = ["write_nc", "read_nc", "write_csv", "read_csv", "write_toolpath_npz",
           "read_toolpath_npz", "write_program_npz", "write_program_csv", "write_program_nc",
           "export_program", "program_formats", "nc_comment_text", "read_program_nc", "CSV_COLUMNS",
           "PROGRAM_CSV_COLUMNS", "CHUNK_ROWS", "read_nc_blocks", "program_blocks", "cut_points",
           "program_axes", "COMMENT_STYLES", "check_nc_style"]

CSV_COLUMNS = ("t_s", "c_deg", "x_mm", "z_mm", "theta_rad", "rho_mm", "y_mm")
PROGRAM_CSV_COLUMNS = ("t_s", "x_mm", "y_mm", "z_mm", "line")


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


def write_csv(path: str | Path, toolpath: ToolPath) -> Path:
    """Write ``toolpath`` as CSV with header ``t_s,c_deg,x_mm,z_mm,theta_rad,rho_mm,y_mm``
    (atomic; full double precision; written in pieces), the angles the part's own (they
    decrease where the spindle turned M04).  Returns the Path."""
    th = part_angle(toolpath)
    rho = np.asarray(toolpath.rho, dtype=np.float64)
    t = np.asarray(toolpath.t, dtype=np.float64)
    z = np.asarray(toolpath.z, dtype=np.float64)
    cols = [lambda s: t[s], lambda s: np.degrees(th[s]), lambda s: rho[s] * np.cos(th[s]),
            lambda s: z[s], lambda s: th[s], lambda s: rho[s], lambda s: rho[s] * np.sin(th[s])]
    return atomic_write_stream(path, lambda fh: _write_rows(fh, cols, ",".join(CSV_COLUMNS),
                                                              "%.17g"))


def read_csv(path: str | Path) -> ToolPath:
    """Read a CSV written by :func:`write_csv` back into a :class:`ToolPath` (angles that
    decrease: the spindle turned M04)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"CSV file not found: {str(path)!r}")
    with path.open() as fh:
        head = fh.readline().strip().split(",")
    if tuple(head) != CSV_COLUMNS:
        raise InputError(f"{path}: CSV header must be {','.join(CSV_COLUMNS)}, received {','.join(head)}")
    d = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    col = {name: d[:, i] for i, name in enumerate(CSV_COLUMNS)}
    return path_from_part(col["theta_rad"].copy(), col["rho_mm"].copy(), col["z_mm"].copy(),
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
def write_toolpath_npz(path: str | Path, toolpath: ToolPath, **_: Any) -> Path:
    """Write ``toolpath.npz`` with arrays theta, rho, x, y, z, t (atomic), in the part's
    own angles; a path cut turning M04 has its angles decreasing and the member
    ``spindle_direction`` = ``"M04"``."""
    m04 = turns_m04(toolpath)
    theta, y = (part_angle(toolpath), -toolpath.y) if m04 else (toolpath.theta, toolpath.y)
    extra = {SPINDLE_KEY: np.array("M04")} if m04 else {}
    return atomic_write_stream(path, lambda fh: _savez(
        fh, theta=theta, rho=toolpath.rho, x=toolpath.x, y=y, z=toolpath.z, t=toolpath.t,
        **extra))


def read_toolpath_npz(path: str | Path) -> ToolPath:
    """Read a ``toolpath.npz`` written by :func:`write_toolpath_npz`."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"tool-path file not found: {str(path)!r}")
    check_npz(path, what="tool-path file")
    with np.load(path, allow_pickle=False) as d:
        return path_from_part(d["theta"].copy(), d["rho"].copy(), d["z"].copy(), d["t"].copy())


register_writer("toolpath", ".csv")(lambda path, toolpath, **_: write_csv(path, toolpath))
register_writer("toolpath", ".nc")(
    lambda path, toolpath, *, header=None, links=None, comments="semicolon", block_numbers=1,
    **_: write_nc(path, toolpath, header=header, links=links, comments=comments,
                  block_numbers=block_numbers))


# ---------------------------------------------------------------- sculpturing programs
@register_writer("program", ".npz")
def write_program_npz(path: str | Path, program: LinearProgram, **_: Any) -> Path:
    """Write a sculpturing program as ``toolpath.npz``: arrays x, y, z, t, line."""
    return atomic_write_stream(path, lambda fh: _savez(
        fh, x=program.x, y=program.y, z=program.z, t=program.t, line=program.line))


@register_writer("program", ".csv")
def write_program_csv(path: str | Path, program: LinearProgram, **_: Any) -> Path:
    """One row per point, header ``t_s,x_mm,y_mm,z_mm,line``."""
    cols = [lambda s: program.t[s], lambda s: program.x[s], lambda s: program.y[s],
            lambda s: program.z[s], lambda s: program.line[s]]
    return atomic_write_stream(path, lambda fh: _write_rows(
        fh, cols, ",".join(PROGRAM_CSV_COLUMNS), ["%.9f", "%.6f", "%.6f", "%.6f", "%d"]))


register_writer("program", ".nc")(write_program_nc)


def program_formats() -> list[str]:
    """The names ``toolpath --format`` takes: the extensions (without the dot) a machine
    program has a registered writer for (products ``toolpath`` and ``program``)."""
    exts = set(formats("toolpath", kind="write")) | set(formats("program", kind="write"))
    return sorted(e.lstrip(".") for e in exts)


def export_program(program: ToolPath | LinearProgram, out_dir: str | Path, *, fmt: str = "npz",
                   header: dict | None = None,
                   **options: Any) -> Path:
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
        Passed to the writer (``links``: the clearance plane and plunge feed of an NC
        program; ``comments`` and ``block_numbers``: how an NC program writes its
        comments and block numbers, :func:`write_nc`; ``feed_mm_per_min`` for
        sculpturing NC).

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
