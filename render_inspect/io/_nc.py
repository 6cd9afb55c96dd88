"""NC programs in the two dialects the project writes (:mod:`render_inspect.io._toolpath`
describes both): writing a turning :class:`ToolPath` or a sculpturing
:class:`LinearProgram` with its :class:`Links`, reading the cutting path back, and
reading every block as written (:func:`read_nc_blocks`, what the program verifier
checks).  :func:`program_blocks` builds the same blocks in memory without a file."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.toolpath import (
    ROLE_CUT,
    ROLE_PLUNGE,
    ROLE_RAPID,
    ROLE_RETRACT,
    Blocks,
    LinearProgram,
    Links,
    ToolPath,
)
from ..core.units import MIN_TO_S
from ._atomic import atomic_write_stream

__all__ = ["write_nc", "read_nc", "write_program_nc", "read_program_nc", "read_nc_blocks",
           "program_blocks", "cut_points", "program_axes", "nc_comment_text", "CHUNK_ROWS"]

#: rows formatted at a time by the writers (their memory does not grow with the program)
CHUNK_ROWS = 16384

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)")
_SECTIONS = ("approach", "cut", "link", "exit")
_TURN_AXES = ("C", "X", "Z")
_LINEAR_AXES = ("X", "Y", "Z")


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
    moves = []
    if leave:
        moves.append((1, ROLE_RETRACT, {"X": frm[0], "Y": frm[1], "Z": zc}, links.plunge_feed))
    moves.append((0, ROLE_RAPID, {"X": to[0], "Y": to[1], "Z": zc}, None))
    if to is not None and len(to) == 3:
        moves.append((1, ROLE_PLUNGE, {"X": to[0], "Y": to[1], "Z": to[2]}, links.plunge_feed))
    return moves


# ------------------------------------------------------------------------ turning
def _turning_header(header: dict | None, toolpath, links) -> list[str]:
    info = {"software_version": __version__}
    meta = getattr(toolpath, "meta", {}) or {}
    for k in ("spindle_rpm", "compensation", "method", "feed_per_rev_mm", "nose_radius"):
        if k in meta:
            info[k] = meta[k]
    info.update(header or {})
    info.update(_links_header(links))
    lines = _header_lines("render_inspect generic C-X-Z turning program", {})
    lines += ["; units: mm, deg [C cumulative: it keeps counting past 360 over the spiral]",
              "; time: inverse-time feed G93, F = 1 / [minutes of the move ending at the block]"]
    return lines + _header_lines("", info)[1:]


def write_nc(path, toolpath, *, header: dict | None = None, decimals: int = 6,
             links: Links | None = None) -> Path:
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

    Returns
    -------
    Path
    """
    if not (isinstance(decimals, int) and 3 <= decimals <= 12):
        raise InputError(f"decimals must be an integer in [3, 12], received {decimals!r}")
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
    c = np.degrees(np.asarray(toolpath.theta, dtype=np.float64))
    x = np.asarray(toolpath.rho, dtype=np.float64)
    z = np.asarray(toolpath.z, dtype=np.float64)
    for name, arr in (("theta", c), ("rho", x), ("z", z), ("t", t)):
        _finite(f"ToolPath.{name}", arr)
    hdr = {"points": n, "t0_s": repr(float(t[0]))}
    hdr.update(header or {})
    lines = _turning_header(hdr, toolpath, links)
    lines.append("G90 G93")
    f = "{:.%df}" % decimals
    if links is not None:
        approach, leave = _turning_moves(c, x, z, links)
        first = 1  # the plunge leaves the tool on point 0
    else:
        approach, leave, first = [], [], 0

    def block(k, motion, words, feed_inv=None):
        text = f"N{k} G0{motion} " + " ".join(f"{a}{f.format(v)}" for a, v in words.items())
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
            fh.write(b"; approach\n")
            k = moves(fh, k, approach, {})
            fh.write(b"; cut\n")
        for a in range(first, n, CHUNK_ROWS):
            b = min(a + CHUNK_ROWS, n)
            rows = []
            for i in range(a, b):
                words = f"N{k} G01 C{f.format(c[i])} X{f.format(x[i])} Z{f.format(z[i])}"
                rows.append(words if i == 0 else words + " F%.10g" % (MIN_TO_S / dt[i - 1]))
                k += 1
            fh.write(("\n".join(rows) + "\n").encode("ascii"))
        if leave:
            fh.write(b"; exit\n")
            moves(fh, k, leave, {"C": c[-1], "X": x[-1], "Z": z[-1]})
        fh.write(b"M30\n")

    return atomic_write_stream(path, write)


# ------------------------------------------------------------------------ sculpturing
def write_program_nc(path, program: LinearProgram, *, header: dict | None = None,
                     feed_mm_per_min: float | None = None, links: Links | None = None,
                     **_) -> Path:
    """A generic X-Y-Z program (``G90 G94 G21``, ``G01`` moves at the cutting speed
    ``feed_mm_per_min``), a ``; line k`` comment before each target line.  With ``links``
    the lines are joined by retract - rapid - plunge moves through the clearance plane
    (``; approach``, ``; link``, ``; exit``); without, the tool feeds straight from one
    line's end to the next line's start."""
    vc = feed_mm_per_min if feed_mm_per_min is not None else program.meta.get("feed_mm_per_min")
    if vc is None or isinstance(vc, bool) or not (vc > 0 and math.isfinite(vc)):
        raise InputError(f"feed_mm_per_min must be > 0 for an X-Y-Z program, received {vc!r}")
    _check_links(links)
    info = {"software_version": __version__}
    info.update(header or {})
    info.update(_links_header(links))
    lines = _header_lines("render_inspect generic X-Y-Z sculpturing program [mm, mm/min]", info)
    lines.append("G90 G94 G21")
    x, y, z, ln = program.x, program.y, program.z, program.line
    for name, arr in (("x", x), ("y", y), ("z", z)):
        _finite(f"LinearProgram.{name}", arr)
    if program.points == 0:
        raise InputError("cannot write an NC program of an empty sculpturing program (0 points)")
    feed = nc_comment_text(f"{float(vc):g}")
    bounds = _line_bounds(ln)

    def row(k, motion, words, fd):
        text = f"N{k} G0{motion} " + " ".join(f"{a}{v:.6f}" for a, v in words.items())
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
                    rows.append("; approach")
                    items = [(0, ROLE_RAPID, {"Z": float(links.clearance_z)}, None)]
                    items += _linear_link(None, start, links, leave=False)
                else:
                    rows.append("; link")
                    items = _linear_link(prev_end, start, links)
                for motion, _, words, fd in items:
                    rows.append(row(k, motion, words, fd))
                    k += 1
                a += 1  # the plunge leaves the tool on the line's first point
            rows.append(f"; line {int(ln[bounds[j][0]])}")
            fh.write(("\n".join(rows) + "\n").encode("ascii"))
            for a0 in range(a, b, CHUNK_ROWS):
                rows = []
                for i in range(a0, min(a0 + CHUNK_ROWS, b)):
                    rows.append(f"N{k} G01 X{x[i]:.6f} Y{y[i]:.6f} Z{z[i]:.6f} F{feed}")
                    k += 1
                fh.write(("\n".join(rows) + "\n").encode("ascii"))
            prev_end = (float(x[b - 1]), float(y[b - 1]), float(z[b - 1]))
        if links is not None:
            s0 = bounds[0][0]
            items = _linear_link(prev_end, (float(x[s0]), float(y[s0])), links)
            rows = ["; exit"] + [row(k + i, m, w, fd) for i, (m, _, w, fd) in enumerate(items)]
            fh.write(("\n".join(rows) + "\n").encode("ascii"))
        fh.write(b"M30\n")

    return atomic_write_stream(path, write)


# ------------------------------------------------------------------------ reading
#: a block as the writers write it (the fast reader's form; anything else is read line by line)
_STRICT = re.compile(r"^N(\d+) G0([01])(?: C(-?\d+\.\d+))?(?: X(-?\d+\.\d+))?"
                     r"(?: Y(-?\d+\.\d+))?(?: Z(-?\d+\.\d+))?(?: F([0-9][0-9.eE+-]*))?$", re.M)
_SECTION_LINE = re.compile(r"^; (approach|cut|link|exit|line \d+)$", re.M)
_PREAMBLE = {"G90 G93": {90.0, 93.0}, "G90 G94 G21": {90.0, 94.0, 21.0}, "M30": set()}


def read_nc_blocks(path) -> Blocks:
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
_FEED = r"[0-9][0-9.eE+-]*"


def _uniform(region: str, words: str):
    """(n, k) values of a run of blocks that all carry exactly ``words`` (e.g. ``"CXZF"``)
    in the writers' form, or None: checked with one regular expression over the run, the
    numbers parsed in bulk."""
    pat = r"N\d+ G0[01]" + "".join(f" {w}{_FEED if w == 'F' else _NUM}" for w in words)
    if re.fullmatch(rf"(?:{pat}\n)*", region) is None:
        return None
    table = str.maketrans({c: " " for c in "NG" + words})
    vals = np.fromstring(region.translate(table), sep=" ")
    k = 2 + len(words)
    if vals.size % k:
        return None
    return vals.reshape(-1, k)


def _words_of(line: str) -> str | None:
    m = _STRICT.match(line)
    return None if m is None else "".join(w for w, v in zip("CXYZF", m.groups()[2:]) if v)


def _line_values(lines) -> np.ndarray | None:
    vals = []
    for line in lines:
        m = _STRICT.match(line)
        if m is None:
            return None
        g = m.groups()
        vals.append([float(g[0]), float(g[1])] + [float(v) if v else math.nan for v in g[2:]])
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
        words = _words_of(rest[:rest.find("\n")])
        if words is None:
            return None
        vals = _uniform(rest, words)
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
    cols = {a: [] for a in ("C", "X", "Y", "Z")}
    number, motion, feed, section_of, line_of, lineno = [], [], [], [], [], []
    section = None
    lines_before = 0
    for piece in _pieces(path):
        for k, v in re.findall(r"^; ([A-Za-z0-9_]+):(.*)$", piece, flags=re.M):
            meta[k] = v.strip()
        parts = _SECTION_LINE.split(piece)
        for name, chunk in [(section, parts[0])] + list(zip(parts[1::2], parts[2::2])):
            section = name
            first = re.search(r"^N", chunk, flags=re.M)
            if first is None:
                region, around = "", chunk
            else:
                last = chunk.rfind("\nN")
                end = chunk.find("\n", (last + 1) if last >= 0 else first.start())
                end = len(chunk) - 1 if end < 0 else end
                region = chunk[first.start():end + 1]
                around = chunk[:first.start()] + chunk[end + 1:]
            for other in around.split("\n"):
                other = other.strip()
                if other.startswith(";") or not other or other == "%":
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
            line_of.append(np.full(len(vals), int(name[5:]) if kind == "cut" and name != "cut"
                                   else -1, dtype=np.int64))
        # the file line (1-based) of each block of the piece
        raw = np.frombuffer(piece.encode("ascii"), dtype=np.uint8)
        newlines = np.flatnonzero(raw == 10)
        starts = np.flatnonzero(raw == ord("N"))
        starts = starts[(starts == 0) | np.isin(starts - 1, newlines)]
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
    pos = {a: [] for a in cur}
    section, line_no, mode = None, -1, 1
    modes = set()
    with path.open("r", encoding="utf-8", errors="strict") as fh:
        for lineno, raw in enumerate(fh, 1):
            text = raw.strip()
            if text.startswith(";"):
                body = text[1:].strip()
                m = re.fullmatch(r"line (\d+)", body)
                if m:
                    section, line_no = "cut", int(m.group(1))
                elif body in _SECTIONS:
                    section, line_no = body, -1
                elif ":" in body:
                    k, v = body.split(":", 1)
                    if re.fullmatch(r"[A-Za-z0-9_]+", k.strip()):
                        meta[k.strip()] = v.strip()
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


def cut_points(blocks: Blocks, path="program") -> np.ndarray:
    """Indices of the blocks whose ends are the cutting points, in order: each run of
    cutting blocks (a ``; cut`` section, a ``; line k``), starting with the point the
    plunge before it leaves the tool on."""
    axes = _TURN_AXES if blocks.dialect == "turning" else _LINEAR_AXES
    cut = blocks.role == ROLE_CUT
    idx = []
    i, n = 0, blocks.count
    while i < n:
        if not cut[i]:
            i += 1
            continue
        j = i
        while j < n and cut[j] and blocks.line[j] == blocks.line[i]:
            j += 1
        s = _cut_start(blocks, i, path, axes)
        idx.extend(range(s, j) if s != i else range(i, j))
        i = j
    return np.asarray(idx, dtype=np.int64)


def program_axes(program) -> dict:
    """The axes an NC program of ``program`` carries, as written: C (deg), X, Z of a
    turning :class:`ToolPath`, or X, Y, Z of a sculpturing :class:`LinearProgram`."""
    if isinstance(program, LinearProgram):
        return {"X": np.asarray(program.x, np.float64), "Y": np.asarray(program.y, np.float64),
                "Z": np.asarray(program.z, np.float64)}
    return {"C": np.degrees(np.asarray(program.theta, np.float64)),
            "X": np.asarray(program.rho, np.float64), "Z": np.asarray(program.z, np.float64)}


def read_nc(path):
    """Parse a turning program written by :func:`write_nc` (or any program in that dialect)
    back into a :class:`ToolPath` (theta from C, rho = X, z = Z, t from ``t0_s`` and the
    inverse-time ``F`` words): the cutting blocks, starting where the approach leaves the
    tool.  Header ``; key: value`` lines become ``meta``.  Raises :class:`InputError`
    naming the line of malformed blocks."""
    path = Path(path)
    b = read_nc_blocks(path)
    if b.count == 0 or "C" not in b.axes or not np.any(b.role == ROLE_CUT):
        raise InputError(f"{path}: no motion blocks (C/X/Z words) found")
    idx = cut_points(b, path)
    lines = b.meta["_file_line"]
    for i in idx[1:]:
        if math.isnan(b.feed[i]):
            raise InputError(f"{path}:{int(lines[i])}: motion block without an F (inverse-time) word")
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
    return ToolPath(np.radians(b.axes["C"][idx]), b.axes["X"][idx].copy(), b.axes["Z"][idx].copy(),
                    t, meta)


def read_program_nc(path) -> LinearProgram:
    """Parse an X-Y-Z program written by :func:`write_program_nc` back into a
    :class:`LinearProgram`: the cutting blocks of each ``; line k`` (a line starts where
    the plunge before it leaves the tool), ``t`` from the path length along the lines at
    the ``F`` feed, mm/min (lines end to end, as planned: the moves between them take no
    time).  Header ``; key: value`` lines become ``meta``.  Raises :class:`InputError`
    naming the line of malformed blocks."""
    path = Path(path)
    b = read_nc_blocks(path)
    if b.count == 0 or b.dialect != "linear" or not np.any(b.role == ROLE_CUT):
        raise InputError(f"{path}: no motion blocks (X/Y/Z words) found")
    lines = b.meta["_file_line"]
    fmod = b.feed.copy()
    last = math.nan
    for i in range(b.count):  # F is modal
        if math.isnan(fmod[i]):
            fmod[i] = last
        last = fmod[i]
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
    return LinearProgram(x, y, z, t, line, meta)


# ------------------------------------------------------------------------ in memory
def program_blocks(program, links: Links | None = None, *,
                   feed_mm_per_min: float | None = None) -> Blocks:
    """The blocks :func:`write_nc` / :func:`write_program_nc` write for ``program``
    (without rounding to the written places, without block numbers' gaps): what the
    simulation checks the links of without writing a file."""
    _check_links(links)
    if isinstance(program, LinearProgram):
        return _linear_blocks(program, links, feed_mm_per_min)
    c = np.degrees(np.asarray(program.theta, dtype=np.float64))
    x = np.asarray(program.rho, dtype=np.float64)
    z = np.asarray(program.z, dtype=np.float64)
    t = np.asarray(program.t, dtype=np.float64)
    n = c.size
    feed = np.r_[np.nan, MIN_TO_S / np.maximum(np.diff(t), 1e-300)] if n else np.zeros(0)
    items = [] if links is None else _turning_moves(c, x, z, links)
    pre, post = (items[0], items[1]) if items else ([], [])
    first = 1 if links is not None else 0
    cols = {"C": [], "X": [], "Z": []}
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
    parts = {"X": [], "Y": [], "Z": []}
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
