"""Writing NC programs in the two dialects (:mod:`render_inspect.io._toolpath` describes
both): a turning :class:`ToolPath` as a C-X-Z program with inverse-time feeds, a
sculpturing :class:`LinearProgram` as an X-Y-Z program, each with its :class:`Links`
through the clearance plane when given."""

from __future__ import annotations

from typing import Any
import math
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.toolpath import ROLE_RAPID, SPINDLE_KEY, LinearProgram, Links, part_angle
from ..core.units import MIN_TO_S
from ._atomic import atomic_write_stream
from ._nc_format import format_linear_rows, format_turning_rows
from ._nc_dialect import (
    CHUNK_ROWS,
    LINEAR_TITLE,
    TURNING_TITLE,
    _check_links,
    _finite,
    LINEAR_MODES,
    TURNING_MODES,
    _header_lines,
    _line_bounds,
    _linear_link,
    _links_header,
    _turning_moves,
    check_nc_style,
    comment_line,
    created_utc,
    nc_comment_text,
)
from ..core.toolpath import ToolPath

__all__ = ["write_nc", "write_program_nc"]


# ------------------------------------------------------------------------ turning
def _turning_header(header: dict | None, toolpath, links, comments: str) -> list[str]:
    info = {"software_version": __version__, "created_utc": created_utc()}
    meta = getattr(toolpath, "meta", {}) or {}
    for k in ("spindle_rpm", "compensation", "method", "feed_per_rev_mm", SPINDLE_KEY):
        if k in meta:
            info[k] = meta[k]
    if "nose_radius" in meta:
        info["nose_radius_mm"] = meta["nose_radius"]
    info.update(header or {})
    info.update(_links_header(links))
    lines = _header_lines(TURNING_TITLE, {}, comments)
    lines += [comment_line(text, comments) for text in (
        "units: mm, deg [C cumulative: it keeps counting past 360 over the spiral]",
        "time: inverse-time feed G93, F = 1 / [minutes of the move ending at the block]",
        "tool: X, Z are the nose's lowest point, the nose radius [nose_radius_mm] planned "
        "into the path: run with G40, no G41 / G42, the tool set to its tip",
        "spindle: C is the spindle as a position-controlled axis [switching it to C-axis "
        "mode is the machine's own M code, not written], spindle_rpm the planned speed")]
    return lines + _header_lines("", info, comments)[1:]


def _number(step: int):
    """``k -> "N<k step> "``, the block number word of the k-th motion block (k from 1),
    or no word where ``step`` is 0."""
    return (lambda k: f"N{k * step} ") if step else (lambda k: "")


def _block_facts(n_blocks: int, dt: np.ndarray) -> dict:
    """The header's ``blocks`` (every motion block), ``cut_time_s`` and
    ``block_rate_max_per_s`` (the blocks per second the control must start at the
    shortest cutting block, 1 / its time)."""
    facts: dict[str, Any] = {"blocks": n_blocks}
    if dt.size:
        facts["cut_time_s"] = "%.10g" % float(np.sum(dt))
        facts["block_rate_max_per_s"] = "%.6g" % (1.0 / float(np.min(dt)))
    return facts


def write_nc(path: str | Path, toolpath: ToolPath, *, header: dict | None = None, decimals: int = 6,
             links: Links | None = None, comments: str = "semicolon",
             block_numbers: int = 1) -> Path:
    """Write ``toolpath`` as a generic C-X-Z NC program (format in
    :mod:`render_inspect.io._toolpath`).

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
    links : Links, optional
        The clearance plane and plunge feed: the program then approaches the first point
        from the clearance plane and leaves the part to it (``; approach``, ``; cut``,
        ``; exit``).  Without links every block is a cutting block.
    comments : {"semicolon", "parenthesis"}
        How every comment line (the header, the sections) is written: ``; text`` (RS274NGC
        / LinuxCNC, Siemens 840D) or ``(text)`` (Fanuc-type controls, where ``;`` ends a
        block); the text is the same, ``;``, ``(`` and ``)`` in it replaced
        (:func:`nc_comment_text`).
    block_numbers : int
        The increment of the block numbers: 1 writes ``N1``, ``N2``, ...; 10 ``N10``,
        ``N20``, ...; 0 writes none.  At most 1000.

    Returns
    -------
    Path
    """
    if not (isinstance(decimals, int) and 3 <= decimals <= 12):
        raise InputError(f"decimals must be an integer in [3, 12], received {decimals!r}")
    check_nc_style(comments, block_numbers)
    _check_links(links)
    t = np.asarray(toolpath.t, dtype=np.float64)
    n = t.size
    if n == 0:
        raise InputError("cannot write an NC program of an empty tool path (0 points)")
    dt = np.diff(t)
    if np.any(~(dt > 0)):
        i = int(np.flatnonzero(~(dt > 0))[0])
        raise InputError(f"ToolPath.t must be strictly increasing to write inverse-time feeds; "
                         f"t[{i}] = {t[i]!r} s, t[{i + 1}] = {t[i + 1]!r} s")
    # C: the part's own angle (decreasing where the spindle turned M04)
    c = np.degrees(part_angle(toolpath))
    x = np.asarray(toolpath.rho, dtype=np.float64)
    z = np.asarray(toolpath.z, dtype=np.float64)
    for name, arr in (("theta", c), ("rho", x), ("z", z), ("t", t)):
        _finite(f"ToolPath.{name}", arr)
    f = "{:.%df}" % decimals
    if links is not None:
        approach, leave = _turning_moves(c, x, z, links)
        first = 1  # the plunge leaves the tool on point 0
    else:
        approach, leave, first = [], [], 0
    hdr = {"points": n, "t0_s": repr(float(t[0]))}
    hdr.update(_block_facts(len(approach) + n - first + len(leave), dt))
    hdr.update(header or {})
    lines = _turning_header(hdr, toolpath, links, comments)
    lines += [TURNING_MODES, "G90 G93"]
    number = _number(block_numbers)
    section = {name: (comment_line(name, comments) + "\n").encode("ascii")
               for name in ("approach", "cut", "exit")}

    def block(k, motion, words, feed_inv=None):
        text = f"{number(k)}G0{motion} " + " ".join(f"{a}{f.format(v)}" for a, v in words.items())
        return text if feed_inv is None else text + " F%.10g" % feed_inv

    def moves(fh, k, items, start):
        rows, pos = [], dict(start)
        for motion, _, words, feed in items:
            inv = None
            if motion == 1:  # inverse time of a straight move at ``feed`` mm/min
                dist = math.sqrt(sum((float(f.format(words[a])) - float(f.format(pos[a]))) ** 2
                                     for a in ("X", "Z") if a in words and a in pos))
                inv = feed / max(dist, 10.0 ** -decimals)
            rows.append(block(k, motion, words, inv))
            pos.update(words)
            k += 1
        fh.write(("\n".join(rows) + "\n").encode("ascii"))
        return k

    def write(fh):
        fh.write(("\n".join(lines) + "\n").encode("ascii"))
        k = 1
        if approach:
            fh.write(section["approach"])
            k = moves(fh, k, approach, {})
            fh.write(section["cut"])
        for a in range(first, n, CHUNK_ROWS):
            b = min(a + CHUNK_ROWS, n)
            # lo: the first point whose block has a feed, the inverse time of the move
            # ending there; the blocks written by a compiled loop, the text Python's
            # formatting gives (io._nc_format)
            lo = max(a, 1)
            inv = np.empty(b - a)
            inv[lo - a:] = MIN_TO_S / dt[lo - 1:b - 1]
            fh.write(format_turning_rows(k, c[a:b], x[a:b], z[a:b], inv, lo - a, decimals,
                                         block_numbers))
            k += b - a
        if leave:
            fh.write(section["exit"])
            moves(fh, k, leave, {"C": c[-1], "X": x[-1], "Z": z[-1]})
        fh.write(b"M30\n")

    return atomic_write_stream(path, write)


# ------------------------------------------------------------------------ sculpturing
def write_program_nc(path: str | Path, program: LinearProgram, *, header: dict | None = None,
                     feed_mm_per_min: float | None = None, links: Links | None = None,
                     comments: str = "semicolon", block_numbers: int = 1, **_: Any) -> Path:
    """A generic X-Y-Z program (``G90 G94 G21``, ``G01`` moves at the cutting speed
    ``feed_mm_per_min``), a ``; line k`` comment before each target line.  With ``links``
    the lines are joined by retract - rapid - plunge moves through the clearance plane
    (``; approach``, ``; link``, ``; exit``); without, the tool feeds straight from one
    line's end to the next line's start.  ``comments`` and ``block_numbers``: as
    :func:`write_nc` takes them."""
    vc = feed_mm_per_min if feed_mm_per_min is not None else program.meta.get("feed_mm_per_min")
    if vc is None or isinstance(vc, bool) or not (vc > 0 and math.isfinite(vc)):
        raise InputError(f"feed_mm_per_min must be > 0 for an X-Y-Z program, received {vc!r}")
    check_nc_style(comments, block_numbers)
    _check_links(links)
    info = {"software_version": __version__, "created_utc": created_utc()}
    info.update(header or {})
    info.update(_links_header(links))
    lines = _header_lines(f"{LINEAR_TITLE} [mm, mm/min]", info, comments)
    lines += [LINEAR_MODES, "G90 G94 G21"]
    x, y, z, ln = program.x, program.y, program.z, program.line
    for name, arr in (("x", x), ("y", y), ("z", z)):
        _finite(f"LinearProgram.{name}", arr)
    if program.points == 0:
        raise InputError("cannot write an NC program of an empty sculpturing program (0 points)")
    feed = nc_comment_text(f"{float(vc):g}")
    bounds = _line_bounds(ln)

    number = _number(block_numbers)

    def row(k, motion, words, fd):
        text = f"{number(k)}G0{motion} " + " ".join(f"{a}{v:.6f}" for a, v in words.items())
        return text if fd is None else f"{text} F{nc_comment_text(f'{float(fd):g}')}"

    def write(fh):
        fh.write(("\n".join(lines) + "\n").encode("ascii"))
        k = 1
        prev_end = None
        for j, (a, b) in enumerate(bounds):
            rows = []
            start = (float(x[a]), float(y[a]), float(z[a]))
            if links is not None:
                if j == 0:
                    rows.append(comment_line("approach", comments))
                    items = [(0, ROLE_RAPID, {"Z": float(links.clearance_z)}, None)]
                    items += _linear_link(None, start, links, leave=False)
                else:
                    rows.append(comment_line("link", comments))
                    items = _linear_link(prev_end, start, links)
                for motion, _, words, fd in items:
                    rows.append(row(k, motion, words, fd))
                    k += 1
                a += 1  # the plunge leaves the tool on the line's first point
            rows.append(comment_line(f"line {int(ln[bounds[j][0]])}", comments))
            fh.write(("\n".join(rows) + "\n").encode("ascii"))
            for a0 in range(a, b, CHUNK_ROWS):
                # (a compiled loop, the text Python's formatting gives: io._nc_format)
                b0 = min(a0 + CHUNK_ROWS, b)
                fh.write(format_linear_rows(k, x[a0:b0], y[a0:b0], z[a0:b0], feed, block_numbers))
                k += b0 - a0
            prev_end = (float(x[b - 1]), float(y[b - 1]), float(z[b - 1]))
        if links is not None:
            s0 = bounds[0][0]
            items = _linear_link(prev_end, (float(x[s0]), float(y[s0])), links)
            rows = [comment_line("exit", comments)] + [row(k + i, m, w, fd)
                                                       for i, (m, _, w, fd) in enumerate(items)]
            fh.write(("\n".join(rows) + "\n").encode("ascii"))
        fh.write(b"M30\n")

    return atomic_write_stream(path, write)
