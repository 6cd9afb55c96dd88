"""The two NC dialects the project writes (:mod:`render_inspect.io._toolpath` describes
both): their words, sections and axes, the safe comment text and header lines, the moves
that join the cuts through the clearance plane, and the blocks a program is written as,
built in memory (:func:`program_blocks`, what the simulation checks without a file)."""

from __future__ import annotations

import math
import os
import re
from datetime import datetime, timezone
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import (
    ROLE_CUT,
    ROLE_PLUNGE,
    ROLE_RAPID,
    ROLE_RETRACT,
    Blocks,
    LinearProgram,
    Links,
)
from ..core.units import MIN_TO_S
from ..core.toolpath import ToolPath, part_angle

__all__ = ["nc_comment_text", "program_axes", "program_blocks", "created_utc", "CHUNK_ROWS",
           "UTF8_BOM", "TURNING_MODES", "LINEAR_MODES", "COMMENT_STYLES", "check_nc_style",
           "TURNING_TITLE", "LINEAR_TITLE", "MAX_BLOCK_STEP", "comment_line",
           "is_own_title"]

#: rows formatted at a time by the writers (their memory does not grow with the program)
CHUNK_ROWS = 16384

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")
_SECTIONS = ("approach", "cut", "link", "exit")
_TURN_AXES = ("C", "X", "Z")
_LINEAR_AXES = ("X", "Y", "Z")


#: the modal block each program starts with, before its motion blocks: the plane (G18 the
#: lathe's Z-X, G17 X-Y), metric units (G21), the control's own tool-nose compensation off
#: (G40: the nose radius is planned into the path), whatever state the control was left in
TURNING_MODES = "G18 G21 G40"
LINEAR_MODES = "G17 G40"

#: the byte order mark an editor may put before the first line of a UTF-8 file saved
#: again: the readers pass over it
UTF8_BOM = b"\xef\xbb\xbf"

#: the first line (the title comment) of each dialect: how a reader knows the project's
#: own programs
TURNING_TITLE = "render_inspect generic C-X-Z turning program"
LINEAR_TITLE = "render_inspect generic X-Y-Z sculpturing program"

#: how the comment lines are written: ``; text`` (RS274NGC / LinuxCNC, Siemens 840D) or
#: ``(text)`` (Fanuc and the controls that follow it, where ``;`` ends a block)
COMMENT_STYLES = ("semicolon", "parenthesis")
#: the largest increment of the block numbers
MAX_BLOCK_STEP = 1000  # not a unit conversion


def check_nc_style(comments: object, block_numbers: object) -> None:
    """Refuse a comment style other than :data:`COMMENT_STYLES` or a block-number
    increment other than a whole number in 0 (no block numbers) .. :data:`MAX_BLOCK_STEP`,
    in one line naming the option."""
    if comments not in COMMENT_STYLES:
        raise InputError(f"the NC comment style (--nc-comments) must be one of "
                         f"{', '.join(COMMENT_STYLES)}, received {comments!r}")
    if isinstance(block_numbers, bool) or not isinstance(block_numbers, int) \
            or not 0 <= block_numbers <= MAX_BLOCK_STEP:
        raise InputError(f"the NC block-number increment (--nc-block-numbers) must be 'off' or "
                         f"a whole number in [1, {MAX_BLOCK_STEP}], received {block_numbers!r}")


def comment_line(text: object, comments: str = "semicolon") -> str:
    """One comment line of ``text`` (made safe by :func:`nc_comment_text`: no ``;``,
    ``(`` or ``)`` inside) as ``; text`` or ``(text)``."""
    return _wrap(nc_comment_text(text), comments)


def _wrap(body: str, comments: str) -> str:
    """``body`` (text already safe: :func:`nc_comment_text`) as a comment line."""
    return f"({body})" if comments == "parenthesis" else f"; {body}"


def is_own_title(line: str) -> str | None:
    """The comment style of ``line`` when it is the title of one of the project's own
    programs (``"semicolon"`` or ``"parenthesis"``), else None."""
    for style, lead in (("semicolon", "; "), ("parenthesis", "(")):
        if line.startswith(lead + TURNING_TITLE) or line.startswith(lead + LINEAR_TITLE):
            return style
    return None


def nc_comment_text(value: object) -> str:
    """``value`` as text safe inside a comment of an NC program, a ``; ...`` line or a
    ``( ... )`` one: printable ASCII only (every other character, line breaks and carriage
    returns included, becomes a space), ``;`` -> ``,`` and ``(``/``)`` -> ``[``/``]`` (the
    comment and block delimiters of common dialects: a parenthesis comment never holds a
    parenthesis of its own), runs of spaces collapsed."""
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


#: the last second a date of four digits can name (9999-12-31T23:59:59Z)
_LAST_EPOCH_S = 253402300799


def created_utc() -> str:
    """The time a program is written, UTC, ISO 8601 to the second (``2025-01-31T12:00:00Z``);
    the time ``SOURCE_DATE_EPOCH`` gives (seconds since 1970-01-01 UTC, the
    reproducible-builds convention) when that is set, so that a program written twice from
    the same scene is the same file."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch is None:
        when = datetime.now(timezone.utc)
    else:
        text = epoch.strip()
        if not (re.fullmatch(r"\d{1,12}", text) and int(text) <= _LAST_EPOCH_S):
            raise InputError(f"SOURCE_DATE_EPOCH must be whole seconds since 1970-01-01 UTC "
                             f"(0 .. {_LAST_EPOCH_S}), received {epoch!r}")
        when = datetime.fromtimestamp(int(text), timezone.utc)
    return when.strftime("%Y-%m-%dT%H:%M:%SZ")


def _header_lines(title: str, info: dict, comments: str = "semicolon") -> list[str]:
    lines = [comment_line(title, comments)]
    for k, v in info.items():
        if not re.fullmatch(r"[A-Za-z0-9_]+", str(k)):
            raise InputError(f"NC header keys must be words of letters, digits and _, received {k!r}")
        lines.append(_wrap(f"{k}: {nc_comment_text(v)}", comments))
    return lines


def _links_header(links: Links | None) -> dict:
    if links is None:
        return {}
    return {"clearance_z_mm": repr(float(links.clearance_z)),
            "plunge_feed_mm_per_min": repr(float(links.plunge_feed)),
            "part_top_mm": repr(float(links.part_top))}


def _check_links(links) -> None:
    if links is not None and not isinstance(links, Links):
        raise InputError(f"links must be a Links record (clearance plane, plunge feed), "
                         f"received {type(links).__name__}")


def _finite(name: str, arr) -> None:
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} has non-finite values at index "
                         f"{int(np.flatnonzero(~np.isfinite(arr))[0])}")


# ------------------------------------------------------------------------ the moves
def _turning_moves(c, x, z, links: Links):
    """(approach, exit) of a turning program: lists of (motion, role, {axis: value},
    feed mm/min or None) in C (deg), X, Z."""
    zc = float(links.clearance_z)
    first, last = (float(c[0]), float(x[0]), float(z[0])), (float(c[-1]), float(x[-1]), float(z[-1]))
    approach = [(0, ROLE_RAPID, {"Z": zc}, None),
                (0, ROLE_RAPID, {"C": first[0], "X": first[1], "Z": zc}, None),
                (1, ROLE_PLUNGE, {"C": first[0], "X": first[1], "Z": first[2]}, links.plunge_feed)]
    leave = [(1, ROLE_RETRACT, {"C": last[0], "X": last[1], "Z": zc}, links.plunge_feed),
             (0, ROLE_RAPID, {"C": last[0], "X": first[1], "Z": zc}, None)]
    return approach, leave


def _line_bounds(line) -> list[tuple[int, int]]:
    """[start, stop) index ranges of the runs of equal ``line`` values."""
    line = np.asarray(line)
    if line.size == 0:
        return []
    cuts = np.flatnonzero(np.diff(line) != 0) + 1
    starts = np.r_[0, cuts]
    stops = np.r_[cuts, line.size]
    return list(zip(starts.tolist(), stops.tolist()))


def _linear_link(frm, to, links: Links, *, leave=True):
    """Retract from ``frm``, rapid within the clearance plane above ``to``, plunge onto it
    (``leave`` False: no retract, the tool is already in the plane)."""
    zc = float(links.clearance_z)
    moves: list[tuple[int, int, dict[str, Any], float | None]] = []
    if leave:
        moves.append((1, ROLE_RETRACT, {"X": frm[0], "Y": frm[1], "Z": zc}, links.plunge_feed))
    moves.append((0, ROLE_RAPID, {"X": to[0], "Y": to[1], "Z": zc}, None))
    if to is not None and len(to) == 3:
        moves.append((1, ROLE_PLUNGE, {"X": to[0], "Y": to[1], "Z": to[2]}, links.plunge_feed))
    return moves



def program_axes(program: ToolPath | LinearProgram) -> dict:
    """The axes an NC program of ``program`` carries, as written: C (deg), X, Z of a
    turning :class:`ToolPath`, or X, Y, Z of a sculpturing :class:`LinearProgram`."""
    if isinstance(program, LinearProgram):
        return {"X": np.asarray(program.x, np.float64), "Y": np.asarray(program.y, np.float64),
                "Z": np.asarray(program.z, np.float64)}
    return {"C": np.degrees(part_angle(program)),  # (the part's own C, as write_nc writes it)
            "X": np.asarray(program.rho, np.float64), "Z": np.asarray(program.z, np.float64)}


# ------------------------------------------------------------------------ in memory
def program_blocks(program: ToolPath | LinearProgram, links: Links | None = None, *,
                   feed_mm_per_min: float | None = None) -> Blocks:
    """The blocks :func:`write_nc` / :func:`write_program_nc` write for ``program``
    (without rounding to the written places, without block numbers' gaps): what the
    simulation checks the links of without writing a file."""
    _check_links(links)
    if isinstance(program, LinearProgram):
        return _linear_blocks(program, links, feed_mm_per_min)
    c = np.degrees(part_angle(program))
    x = np.asarray(program.rho, dtype=np.float64)
    z = np.asarray(program.z, dtype=np.float64)
    t = np.asarray(program.t, dtype=np.float64)
    n = c.size
    feed = np.r_[np.nan, MIN_TO_S / np.maximum(np.diff(t), 1e-300)] if n else np.zeros(0)
    items = [] if links is None else _turning_moves(c, x, z, links)
    pre, post = (items[0], items[1]) if items else ([], [])
    first = 1 if links is not None else 0
    cols: dict[str, list] = {"C": [], "X": [], "Z": []}
    motion, role, fd = [], [], []
    pos = {"C": math.nan, "X": math.nan, "Z": math.nan}

    def add(items_):
        for m, r, words, f in items_:
            start = dict(pos)
            pos.update(words)
            for a in cols:
                cols[a].append(pos[a])
            motion.append(m)
            role.append(r)
            dist = math.hypot(pos["X"] - start["X"], pos["Z"] - start["Z"]) if m == 1 else 0.0
            fd.append(f / dist if (m == 1 and dist > 0) else math.nan)

    add(pre)
    head = {a: np.asarray(v) for a, v in cols.items()}
    k0 = len(motion)
    cols = {"C": [], "X": [], "Z": []}
    pos.update({"C": float(c[-1]), "X": float(x[-1]), "Z": float(z[-1])} if n else {})
    add(post)
    tail = {a: np.asarray(v) for a, v in cols.items()}
    m_cut = n - first
    axes = {"C": np.r_[head["C"], c[first:], tail["C"]], "X": np.r_[head["X"], x[first:], tail["X"]],
            "Z": np.r_[head["Z"], z[first:], tail["Z"]]}
    count = k0 + m_cut + len(tail["C"])
    return Blocks("turning", np.arange(1, count + 1, dtype=np.int64),
                  np.r_[motion[:k0], np.ones(m_cut), motion[k0:]].astype(np.int8),
                  np.r_[role[:k0], np.full(m_cut, ROLE_CUT), role[k0:]].astype(np.int8),
                  axes, np.r_[fd[:k0], feed[first:], fd[k0:]].astype(np.float64),
                  np.full(count, -1, dtype=np.int64), {})


def _linear_blocks(program: LinearProgram, links, vc) -> Blocks:
    vc = vc if vc is not None else program.meta.get("feed_mm_per_min", math.nan)
    x, y, z = (np.asarray(a, dtype=np.float64) for a in (program.x, program.y, program.z))
    parts: dict[str, list] = {"X": [], "Y": [], "Z": []}
    motion, role, feed, line = [], [], [], []
    pos = {"X": math.nan, "Y": math.nan, "Z": math.nan}

    def add(items):
        for m, r, words, f in items:
            pos.update(words)
            for a in parts:
                parts[a].append(np.asarray([pos[a]]))
            motion.append(np.asarray([m]))
            role.append(np.asarray([r]))
            feed.append(np.asarray([math.nan if f is None else f]))
            line.append(np.asarray([-1]))

    bounds = _line_bounds(program.line)
    prev = None
    for j, (a, b) in enumerate(bounds):
        start = (float(x[a]), float(y[a]), float(z[a]))
        if links is not None:
            items = ([(0, ROLE_RAPID, {"Z": float(links.clearance_z)}, None)]
                     + _linear_link(None, start, links, leave=False)) if j == 0 else \
                _linear_link(prev, start, links)
            add(items)
            a += 1
        for name, arr in (("X", x), ("Y", y), ("Z", z)):
            parts[name].append(arr[a:b])
        motion.append(np.ones(b - a))
        role.append(np.full(b - a, ROLE_CUT))
        feed.append(np.full(b - a, float(vc)))
        line.append(np.full(b - a, int(program.line[bounds[j][0]])))
        pos.update({"X": float(x[b - 1]), "Y": float(y[b - 1]), "Z": float(z[b - 1])})
        prev = (pos["X"], pos["Y"], pos["Z"])
    if links is not None and bounds:
        s0 = bounds[0][0]
        add(_linear_link(prev, (float(x[s0]), float(y[s0])), links))
    cat = (lambda v, dt: np.concatenate(v).astype(dt) if v else np.zeros(0, dt))
    axes = {a: cat(v, np.float64) for a, v in parts.items()}
    n = axes["X"].size
    return Blocks("linear", np.arange(1, n + 1, dtype=np.int64), cat(motion, np.int8),
                  cat(role, np.int8), axes, cat(feed, np.float64), cat(line, np.int64), {})
