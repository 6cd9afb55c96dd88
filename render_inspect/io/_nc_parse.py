"""Reading NC programs: every block as written (:func:`read_nc_blocks`, what the program
verifier checks; a fast reader for the writers' own form, a line-by-line one for any
other), the cutting points among them, and the program read back as a turning
:class:`ToolPath` or a sculpturing :class:`LinearProgram`."""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import cast

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import (
    ROLE_CUT,
    ROLE_PLUNGE,
    ROLE_RAPID,
    ROLE_RETRACT,
    Blocks,
    LinearProgram,
    ToolPath,
    path_from_part,
)
from ..core.units import MIN_TO_S
from ._nc_dialect import (LINEAR_MODES, TURNING_MODES, _LINEAR_AXES, _SECTIONS, _TURN_AXES, _WORD,
                          UTF8_BOM, is_own_title)
from ._nc_scan import FORM_LONG, FORM_OK, scan_uniform

__all__ = ["read_nc", "read_program_nc", "read_nc_blocks", "cut_points"]


# ------------------------------------------------------------------------ reading
#: a block as the writers write it, with its block number or without (the fast reader's
#: form; anything else is read line by line)
_STRICT = re.compile(r"^(?:N(\d+) )?G0([01])(?: C(-?\d+\.\d+))?(?: X(-?\d+\.\d+))?"
                     r"(?: Y(-?\d+\.\d+))?(?: Z(-?\d+\.\d+))?(?: F([0-9][0-9.eE+-]*))?$", re.M)
# the section and header comment lines of each comment style (the style the program's
# title is written in).  (The "; " first and the line start behind it: the search skips
# to each "; " at once, where "^; " would be tried at every character of a long program;
# the same for "(".)
_SECTION_LINE = {
    "semicolon": re.compile(r"; (?<=^; )(approach|cut|link|exit|line \d+)$", re.M),
    "parenthesis": re.compile(r"\((?<=^\()(approach|cut|link|exit|line \d+)\)$", re.M)}
_HEADER_LINE = {"semicolon": re.compile(r"; (?<=^; )([A-Za-z0-9_]+):(.*)$", re.M),
                "parenthesis": re.compile(r"\((?<=^\()([A-Za-z0-9_]+):(.*)\)$", re.M)}
_PREAMBLE = {"G90 G93": {90.0, 93.0}, "G90 G94 G21": {90.0, 94.0, 21.0}, "M30": set(),
             TURNING_MODES: {18.0, 21.0, 40.0}, LINEAR_MODES: {17.0, 40.0}}


def read_nc_blocks(path: str | Path) -> Blocks:
    """Every motion block of an NC program in either dialect, as written: block number,
    ``G00`` / ``G01``, the role its section gives it (``; approach``, ``; cut``,
    ``; line k``, ``; link``, ``; exit``; without sections ``G00`` is a rapid and ``G01``
    a cut), the axes at the end of the block (modal words filled in), the ``F`` word.

    Raises :class:`InputError` naming the file and line of anything it cannot parse."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"NC file not found: {str(path)!r}")
    try:
        fast = _fast_blocks(path)
    except UnicodeDecodeError:
        fast = None
    return fast if fast is not None else _blocks_line_by_line(path)


def _ffill(vals: np.ndarray, start: float) -> np.ndarray:
    """``vals`` with each NaN replaced by the last value before it (``start`` before the
    first)."""
    vals = np.r_[start, vals]
    ok = ~np.isnan(vals)
    idx = np.where(ok, np.arange(vals.size), 0)
    np.maximum.accumulate(idx, out=idx)
    return vals[idx][1:]


_NUM = r"-?\d+\.\d+"
#: an F word as the writers' form takes it (with an exponent too)
_FEED = r"[0-9][0-9.eE+-]*"


def _uniform(region: str, words: str, numbered: bool = True):
    """(n, k) values of a run of blocks that all carry exactly ``words`` (e.g. ``"CXZF"``)
    in the writers' form (each after its block number, or none: ``numbered``; -1 for the
    number of a block without one), or None.  The plain form (no exponent, up to 15 digits a number)
    is checked and read in one compiled pass (:func:`~render_inspect.io._nc_scan.scan_uniform`);
    a run with a longer number, or with F words that have exponents, is checked with one
    regular expression and its numbers read as :func:`float` reads them."""
    status, read = scan_uniform(region, words, numbered)
    if status == FORM_OK:
        return read
    if status != FORM_LONG:  # not the plain form: the writers' form with F exponents, or not
        if "F" not in words:
            return None
        blk = (r"N\d+ G0[01]" if numbered else r"G0[01]") + "".join(
            f" {w}{_FEED if w == 'F' else _NUM}" for w in words)
        # possessive: a block ends at its line break, so the repetition has one way to match
        if re.fullmatch(rf"(?:{blk}\n)*+", region) is None:
            return None
    table = str.maketrans({c: " " for c in "NG" + words})
    vals = np.fromstring(region.translate(table), sep=" ")
    k = (2 if numbered else 1) + len(words)
    if vals.size % k:
        return None
    vals = vals.reshape(-1, k)
    return vals if numbered else np.c_[np.full(len(vals), -1.0), vals]


def _words_of(line: str) -> tuple[str, bool] | None:
    """The words a block line carries after its motion, and whether it has a block
    number; None for a line not in the writers' form."""
    m = _STRICT.match(line)
    if m is None:
        return None
    return "".join(w for w, v in zip("CXYZF", m.groups()[2:]) if v), m.group(1) is not None


def _line_values(lines) -> np.ndarray | None:
    vals = []
    for line in lines:
        m = _STRICT.match(line)
        if m is None:
            return None
        g = m.groups()
        vals.append([float(g[0]) if g[0] else -1.0, float(g[1])]
                    + [float(v) if v else math.nan for v in g[2:]])
    return np.asarray(vals, dtype=np.float64).reshape(-1, 7)


def _chunk_rows(region: str) -> np.ndarray | None:
    """(n, 7) values N, G, C, X, Y, Z, F (NaN where a word is absent) of a run of block
    lines in the writers' form; None when a line is not.  A run whose lines (after the
    first) all carry the same words is parsed in bulk (:func:`_uniform`), a short one line
    by line."""
    for skip in (0, 1):
        head_end = 0
        for _ in range(skip):
            head_end = region.find("\n", head_end) + 1
        rest = region[head_end:]
        if not rest:
            break
        form = _words_of(rest[:rest.find("\n")])
        if form is None:
            return None
        words, numbered = form
        vals = _uniform(rest, words, numbered)
        if vals is None:
            continue
        full = np.full((vals.shape[0], 7), math.nan)
        full[:, :2] = vals[:, :2]
        for k, w in enumerate(words):
            full[:, 2 + "CXYZF".index(w)] = vals[:, 2 + k]
        if skip:
            first = _line_values(region[:head_end].split("\n")[:1])
            if first is None:
                return None
            full = np.vstack([first, full])
        return full
    lines = region.split("\n")[:-1]
    return _line_values(lines) if len(lines) <= 100_000 else None


#: bytes of a program read and parsed at a time by the fast reader
_PIECE_BYTES = 1 << 22


def _pieces(path: Path):
    """The file in pieces of about :data:`_PIECE_BYTES` that end at a line break (ASCII
    text); raises UnicodeDecodeError for other bytes."""
    rest = b""
    with path.open("rb") as fh:
        if fh.read(len(UTF8_BOM)) != UTF8_BOM:  # (a byte order mark an editor put first)
            fh.seek(0)
        while True:
            data = fh.read(_PIECE_BYTES)
            if not data:
                break
            data = rest + data
            cut = data.rfind(b"\n") + 1
            if cut == 0:
                rest = data
                continue
            rest = data[cut:]
            yield data[:cut].decode("ascii")
    if rest:
        yield rest.decode("ascii")


def _fast_blocks(path: Path) -> Blocks | None:
    """The blocks of a program every block line of which has the writers' exact form
    (:data:`_STRICT`), read in bulk piece by piece (memory a few times
    :data:`_PIECE_BYTES`); None for any other program."""
    meta, modes = {}, set()
    cols: dict[str, list] = {a: [] for a in ("C", "X", "Y", "Z")}
    number, motion, feed, section_of, line_of, lineno = [], [], [], [], [], []
    section = None
    lines_before = 0
    style = None  # the comment style of the program's title (the first line)
    for piece in _pieces(path):
        if style is None:
            style = is_own_title(piece[:piece.find("\n")]) or "semicolon"
        paren = style == "parenthesis"
        for k, v in _HEADER_LINE[style].findall(piece):
            meta[k] = v.strip()
        parts = _SECTION_LINE[style].split(piece)
        for name, chunk in [(section, parts[0])] + list(zip(parts[1::2], parts[2::2])):
            section = name
            # a block starts a line with its number, or with G00 / G01 where it has none
            first = re.search(r"^(?:N|G0[01] )", chunk, flags=re.M)
            if first is None:
                region, around = "", chunk
            else:
                last = max(chunk.rfind("\nN"), chunk.rfind("\nG0"))
                end = chunk.find("\n", (last + 1) if last >= 0 else first.start())
                end = len(chunk) - 1 if end < 0 else end
                region = chunk[first.start():end + 1]
                around = chunk[:first.start()] + chunk[end + 1:]
            for other in around.split("\n"):
                other = other.strip()
                if other.startswith(";") or not other or other == "%" or \
                        (paren and other.startswith("(") and other.endswith(")")):
                    continue
                if other not in _PREAMBLE:
                    return None
                modes |= _PREAMBLE[other]
            if not region:
                continue
            if not region.endswith("\n"):
                region += "\n"
            vals = _chunk_rows(region)
            if vals is None:
                return None
            number.append(vals[:, 0].astype(np.int64))
            motion.append(vals[:, 1].astype(np.int8))
            for k, a in enumerate(("C", "X", "Y", "Z"), start=2):
                cols[a].append(vals[:, k])
            feed.append(vals[:, 6])
            kind = None if name is None else ("cut" if name.startswith("line") else name)
            section_of.append(np.full(len(vals), -1 if kind is None else _SECTIONS.index(kind),
                                      dtype=np.int8))
            line_of.append(np.full(len(vals), int(cast(str, name)[5:]) if kind == "cut" and name != "cut"
                                   else -1, dtype=np.int64))
        # the file line (1-based) of each block of the piece: the lines that start with N,
        # or with G0 (no mode line does)
        raw = np.frombuffer(piece.encode("ascii"), dtype=np.uint8)
        newlines = np.flatnonzero(raw == 10)
        starts = np.r_[0, newlines + 1]
        starts = starts[starts < raw.size]
        lead, after = raw[starts], raw[np.minimum(starts + 1, raw.size - 1)]
        starts = starts[(lead == ord("N")) | ((lead == ord("G")) & (after == ord("0")))]
        lineno.append(lines_before + np.searchsorted(newlines, starts) + 1)
        lines_before += newlines.size
    if not number:
        return None
    cat = np.concatenate
    raw_axes = {a: cat(v) for a, v in cols.items()}
    lineno = cat(lineno)
    if lineno.size != raw_axes["Z"].size:
        return None
    axes = {a: _ffill(v, math.nan) for a, v in raw_axes.items()}
    mot = cat(motion)
    sec = cat(section_of)
    z_start = np.r_[math.nan, axes["Z"][:-1]]
    down = np.isnan(z_start) | (axes["Z"] < z_start)
    role = np.where(mot == 0, ROLE_RAPID,
                    np.where((sec == -1) | (sec == _SECTIONS.index("cut")), ROLE_CUT,
                             np.where(down, ROLE_PLUNGE, ROLE_RETRACT))).astype(np.int8)
    turning = not np.all(np.isnan(raw_axes["C"])) or 93.0 in modes
    keep = _TURN_AXES if turning else _LINEAR_AXES
    meta["_modes"] = sorted(modes)
    meta["_file_line"] = lineno.astype(np.int64)
    return Blocks("turning" if turning else "linear", cat(number), mot, role,
                  {a: axes[a] for a in keep}, cat(feed), cat(line_of), meta)


def _blocks_line_by_line(path: Path) -> Blocks:
    """:func:`read_nc_blocks` of any program, one line at a time."""
    meta: dict = {}
    cur = {a: math.nan for a in ("C", "X", "Y", "Z")}
    number, motion, role, feed, line_of, lineno_of = [], [], [], [], [], []
    pos: dict[str, list[float]] = {a: [] for a in cur}
    section, line_no, mode = None, -1, 1
    modes = set()
    paren = False  # a program of the project's own whose comments are in parentheses
    with path.open("r", encoding="utf-8-sig", errors="strict") as fh:
        for lineno, raw in enumerate(fh, 1):
            text = raw.strip()
            if lineno == 1:
                paren = is_own_title(text) == "parenthesis"
            body = None
            if text.startswith(";"):
                body = text[1:].strip()
            elif paren and text.startswith("(") and text.endswith(")"):
                body = text[1:-1].strip()
            if body is not None:
                m = re.fullmatch(r"line (\d+)", body)
                if m:
                    section, line_no = "cut", int(m.group(1))
                elif body in _SECTIONS:
                    section, line_no = body, -1
                elif ":" in body:
                    k, note = body.split(":", 1)
                    if re.fullmatch(r"[A-Za-z0-9_]+", k.strip()):
                        meta[k.strip()] = note.strip()
                continue
            text = re.sub(r"\([^)]*\)", " ", text.split(";", 1)[0]).strip().upper()
            if not text or text == "%":  # '%' marks the start / end of a program
                continue
            words = _WORD.findall(text)
            rest = _WORD.sub("", text).strip()
            if rest:
                raise InputError(f"{path}:{lineno}: cannot parse {rest!r} in block {raw.strip()!r}")
            d = {}
            for letter, num in words:
                if letter == "G":
                    g = float(num)
                    if g in (0.0, 1.0):
                        mode = int(g)
                    else:
                        modes.add(g)
                elif letter in d:
                    raise InputError(f"{path}:{lineno}: the word {letter} appears twice in "
                                     f"block {raw.strip()!r}")
                else:
                    d[letter] = num
            if not any(a in d for a in cur):
                continue
            start_z = cur["Z"]
            for a in cur:
                if a in d:
                    v = float(d[a])
                    if not math.isfinite(v):
                        raise InputError(f"{path}:{lineno}: {a} must be a finite number, "
                                         f"received {d[a]!r}")
                    cur[a] = v
                pos[a].append(cur[a])
            number.append(int(float(d["N"])) if "N" in d else -1)
            motion.append(mode)
            feed.append(float(d["F"]) if "F" in d else math.nan)
            line_of.append(line_no if section == "cut" else -1)
            lineno_of.append(lineno)
            if section in (None, "cut"):
                role.append(ROLE_CUT if mode == 1 else ROLE_RAPID)
            elif mode == 0:
                role.append(ROLE_RAPID)
            else:
                down = math.isnan(start_z) or cur["Z"] < start_z
                role.append(ROLE_PLUNGE if down else ROLE_RETRACT)
    dialect = "turning" if any(not math.isnan(v) for v in pos["C"]) or 93.0 in modes \
        else "linear"
    axes = _TURN_AXES if dialect == "turning" else _LINEAR_AXES
    meta["_modes"] = sorted(modes)
    meta["_file_line"] = np.asarray(lineno_of, dtype=np.int64)
    return Blocks(dialect, np.asarray(number, dtype=np.int64), np.asarray(motion, dtype=np.int8),
                  np.asarray(role, dtype=np.int8),
                  {a: np.asarray(pos[a], dtype=np.float64) for a in axes},
                  np.asarray(feed, dtype=np.float64), np.asarray(line_of, dtype=np.int64), meta)


def _cut_start(blocks: Blocks, i0: int, path, axes) -> int:
    """Index of the block whose end is the first point of the cut starting at block
    ``i0``: the block before it when that one placed the tool (a plunge), else ``i0``."""
    if i0 > 0 and blocks.role[i0 - 1] != ROLE_CUT:
        j = i0 - 1
    else:
        j = i0
    for a in axes:
        if math.isnan(blocks.axes[a][j]):
            raise InputError(f"{path}:{int(blocks.meta['_file_line'][j])}: first motion block "
                             f"lacks the {a} word")
    return j


def cut_points(blocks: Blocks, path: str | Path = "program") -> np.ndarray:
    """Indices of the blocks whose ends are the cutting points, in order: each run of
    cutting blocks (a ``; cut`` section, a ``; line k``), starting with the point the
    plunge before it leaves the tool on."""
    axes = _TURN_AXES if blocks.dialect == "turning" else _LINEAR_AXES
    cut = np.asarray(blocks.role) == ROLE_CUT
    if not cut.any():
        return np.zeros(0, dtype=np.int64)
    # the runs: a cutting block after a block that does not cut, or with another line
    # label than the block before it, starts one; one ends before the next block that does
    # not cut or starts another (the runs in order, each [start, end))
    line = np.asarray(blocks.line)
    other = np.r_[True, line[1:] != line[:-1]]
    starts = np.flatnonzero(cut & (other | ~np.r_[False, cut[:-1]]))
    ends = np.flatnonzero(np.r_[cut[:-1] & (~cut[1:] | other[1:]), cut[-1:]]) + 1
    return np.concatenate([np.arange(_cut_start(blocks, int(i), path, axes), int(j), dtype=np.int64)
                           for i, j in zip(starts, ends)])


def read_nc(path: str | Path) -> ToolPath:
    """Parse a turning program written by :func:`write_nc` (or any program in that dialect)
    back into a :class:`ToolPath` (theta from C, rho = X, z = Z, t from ``t0_s`` and the
    inverse-time ``F`` words): the cutting blocks, starting where the approach leaves the
    tool.  Header ``; key: value`` lines become ``meta``.  Raises :class:`InputError`
    naming the line of malformed blocks."""
    return read_nc_lines(path)[0]


def read_nc_lines(path: str | Path) -> tuple[ToolPath, np.ndarray]:
    """:func:`read_nc`, and the file line (1-based) of each point's block."""
    path = Path(path)
    b = read_nc_blocks(path)
    if b.count == 0 or "C" not in b.axes or not np.any(b.role == ROLE_CUT):
        raise InputError(f"{path}: no motion blocks (C/X/Z words) found")
    idx = cut_points(b, path)
    lines = b.meta["_file_line"]
    missing = np.flatnonzero(np.isnan(b.feed[idx[1:]]))
    if missing.size:
        raise InputError(f"{path}:{int(lines[idx[1 + missing[0]]])}: motion block without an F "
                         f"(inverse-time) word")
    if idx.size > 1 and 93.0 not in b.meta["_modes"]:
        raise InputError(f"{path}: the program must select inverse-time feed (G93) to carry time")
    f = b.feed[idx[1:]]
    if np.any(~(f > 0)):
        raise InputError(f"{path}: F words must be > 0 (inverse time, 1/min)")
    meta = {k: v for k, v in b.meta.items() if not k.startswith("_")}
    try:
        t0 = float(meta.get("t0_s", 0.0))
    except ValueError:
        raise InputError(f"{path}: the header's t0_s must be a number, received "
                         f"{meta['t0_s']!r}") from None
    t = t0 + np.concatenate([[0.0], np.cumsum(MIN_TO_S / f)])
    if "points" in meta and str(meta["points"]).isdigit() and int(meta["points"]) != idx.size:
        raise InputError(f"{path}: header says {meta['points']} points, the program has {idx.size}")
    # C decreasing throughout: the spindle turned M04 (core.toolpath.path_from_part)
    return (path_from_part(np.radians(b.axes["C"][idx]), b.axes["X"][idx].copy(),
                           b.axes["Z"][idx].copy(), t, meta), lines[idx].astype(np.int64))


def read_program_nc(path: str | Path) -> LinearProgram:
    """Parse an X-Y-Z program written by :func:`write_program_nc` back into a
    :class:`LinearProgram`: the cutting blocks of each ``; line k`` (a line starts where
    the plunge before it leaves the tool), ``t`` from the path length along the lines at
    the ``F`` feed, mm/min (lines end to end, as planned: the moves between them take no
    time).  Header ``; key: value`` lines become ``meta``.  Raises :class:`InputError`
    naming the line of malformed blocks."""
    return read_program_nc_lines(path)[0]


def read_program_nc_lines(path: str | Path) -> tuple[LinearProgram, np.ndarray]:
    """:func:`read_program_nc`, and the file line (1-based) of each point's block."""
    path = Path(path)
    b = read_nc_blocks(path)
    if b.count == 0 or b.dialect != "linear" or not np.any(b.role == ROLE_CUT):
        raise InputError(f"{path}: no motion blocks (X/Y/Z words) found")
    lines = b.meta["_file_line"]
    fmod = _ffill(b.feed, math.nan)  # F is modal
    idx = cut_points(b, path)
    # a line's label: that of its cutting blocks (the plunge's end point takes the next one's)
    lab = b.line[np.minimum(idx + (b.role[idx] != ROLE_CUT), b.count - 1)]
    for a in _LINEAR_AXES:
        bad = np.flatnonzero(np.isnan(b.axes[a][idx]))
        if bad.size:
            raise InputError(f"{path}:{int(lines[idx[bad[0]]])}: first motion block lacks the "
                             f"{a} word")
    f = fmod[idx]
    if np.any(~(f > 0)):
        raise InputError(f"{path}: F words must be > 0 (mm/min)")
    x, y, z = (b.axes[a][idx].copy() for a in _LINEAR_AXES)
    line = np.asarray(lab, dtype=np.int64)
    seg = np.sqrt(np.diff(x) ** 2 + np.diff(y) ** 2 + np.diff(z) ** 2)
    seg[np.diff(line) != 0] = 0.0  # lines end to end: the links take no time
    t = np.concatenate([[0.0], np.cumsum(seg / (f[1:] / MIN_TO_S))])  # mm/min -> mm/s
    meta = {k: v for k, v in b.meta.items() if not k.startswith("_")}
    if "points" in meta and str(meta["points"]).isdigit() and int(meta["points"]) != x.size:
        raise InputError(f"{path}: header says {meta['points']} points, the program has {x.size}")
    return LinearProgram(x, y, z, t, line, meta), lines[idx].astype(np.int64)
