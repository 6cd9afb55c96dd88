"""The streaming word scanner of machine programs (:func:`scan_program`): any NC program
in ISO 6983 / RS-274 word address form, read in pieces of a few MiB, every piece checked
and parsed with numpy (no Python loop over blocks), the modal state (motion, distance,
feed and unit modes, positions, F, S) carried from piece to piece.

What it returns (:class:`ScannedProgram`) is one row per motion block: the end point
(X, Y, Z, C as written, modal and incremental words resolved, inches converted to mm),
the motion (G00 .. G03), the feed mode and F, the spindle speed and mode, the arc words
and the file line.  What the blocks mean (a lathe's spindle, a raster) is decided by
:mod:`render_inspect.io._program`.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import InputError

__all__ = ["ScannedProgram", "scan_program", "PIECE_BYTES", "INCH_MM"]

#: bytes read and parsed at a time (the scanner's memory does not grow with the program)
PIECE_BYTES = 1 << 23
#: one inch, mm
INCH_MM = 25.4

# byte classes: 0 not allowed, 1 letter, 2 digit, 3 '.', 4 sign, 5 line break
_CLASS = np.zeros(256, dtype=np.uint8)
_CLASS[ord("A"):ord("Z") + 1] = 1
_CLASS[ord("0"):ord("9") + 1] = 2
_CLASS[ord(".")] = 3
_CLASS[ord("+")] = 4
_CLASS[ord("-")] = 4
_CLASS[ord("\n")] = 5
#: byte pairs (class of a byte * 8 + class of the next) that no program holds
_BAD_PAIR = np.ones(64, dtype=bool)
for _a, _b in [(1, 2), (1, 3), (1, 4), (2, 1), (2, 2), (2, 3), (2, 5), (3, 1), (3, 2), (3, 5),
               (4, 2), (4, 3), (5, 1), (5, 5)]:
    _BAD_PAIR[_a * 8 + _b] = False
_POW10 = 10.0 ** np.arange(301)
_CLASS_TABLE = _CLASS.tobytes()
_BAD_PAIR_TABLE = np.r_[_BAD_PAIR, np.ones(192, dtype=bool)].astype(np.uint8).tobytes()

_PAREN = re.compile(rb"\([^()\n]*\)")
_SEMI = re.compile(rb";[^\n]*")
_PERCENT = re.compile(rb"(?m)^[ \t]*%[^\n]*")
_COLON = re.compile(rb"(?m)^[ \t]*:[0-9]*")
_SLASH = re.compile(rb"(?m)^[ \t]*/")

#: the G codes read, by modal group (anything else is refused with its line)
MOTION = (0, 1, 2, 3)
_GROUPS = {
    "motion": MOTION,
    "distance": (90, 91),
    "feed": (93, 94, 95),
    "units": (20, 21, 70, 71),        # G20/G70 inch, G21/G71 metric
    "plane": (17, 18, 19),
    "spindle": (96, 97),              # constant surface speed / constant rpm
    "radius_comp": (40,),
}
#: G codes taken as written without effect on the path (work offsets, exact stop, cancel
#: canned cycles, ...)
_NO_EFFECT = (8, 9, 54, 55, 56, 57, 58, 59, 61, 64, 80)
#: non-modal G codes: dwell, return home, spindle clamp
_DWELL, _HOME, _CLAMP = 4, 28, 50
_REFUSED = {41: "controller tool-nose radius compensation (G41/G42) moves the tool by an "
                "offset the program does not state; program the tool centre or tip path",
            42: "controller tool-nose radius compensation (G41/G42) moves the tool by an "
                "offset the program does not state; program the tool centre or tip path"}
_KNOWN_G = sorted({g for v in _GROUPS.values() for g in v} | set(_NO_EFFECT)
                  | {_DWELL, _HOME, _CLAMP} | set(_REFUSED))

#: letters whose value is one per block; G and M may repeat
_SINGLE = "XYZCUVWHIJKRFSNOTPQDL"
#: axis letter -> its incremental letter (lathe controllers' U, V, W, H)
_INCREMENTAL = {"X": "U", "Y": "V", "Z": "W", "C": "H"}


@dataclass
class ScannedProgram:
    """The motion blocks of a program, one row each (see the module docstring)."""

    path: Path
    line: np.ndarray            # file line of the block (1-based)
    motion: np.ndarray          # 0 rapid, 1 linear, 2 clockwise arc, 3 counter-clockwise arc
    axes: dict                  # "X", "Y", "Z", "C": end point (NaN where not yet known)
    written: dict               # "X", "Y", "Z", "C": True where the block wrote the axis
    arc: dict                   # "I", "J", "K", "R": mm, NaN where absent
    feed: np.ndarray            # modal F (mm/min, 1/min under G93, mm/rev under G95)
    feed_mode: np.ndarray       # 93, 94 or 95
    spindle: np.ndarray         # modal S (rpm under G97, m/min under G96)
    spindle_mode: np.ndarray    # 96 or 97
    clamp_rpm: np.ndarray       # modal G50 S clamp (NaN: none)
    plane: np.ndarray           # 17, 18 or 19
    header: dict = field(default_factory=dict)   # leading "; key: value" comment lines
    title: str = ""             # the first comment line
    blocks: int = 0             # blocks read (all kinds)
    g_codes: set = field(default_factory=set)
    m_codes: set = field(default_factory=set)
    notes: list = field(default_factory=list)    # what was read but does not move the tool
    words: set = field(default_factory=set)      # letters present
    lines: int = 0              # lines of the file read

    @property
    def count(self) -> int:
        return int(self.line.size)


def _fail(path, lineno: int, block: bytes, text: str):
    shown = block.decode("ascii", "replace").strip()
    if len(shown) > 120:
        shown = shown[:117] + "..."
    raise InputError(f"{path}:{lineno}: {text} in block {shown!r}")


def _pieces(path: Path, piece_bytes: int):
    """(bytes ending at a line break, line number of its first line)."""
    line = 1
    rest = b""
    with path.open("rb") as fh:
        while True:
            data = fh.read(piece_bytes)
            if not data:
                break
            data = rest + data
            cut = data.rfind(b"\n")
            if cut < 0:
                rest = data
                continue
            piece, rest = data[:cut + 1], data[cut + 1:]
            yield piece, line
            line += piece.count(b"\n")
    if rest:
        yield rest + b"\n", line


def _header(first: bytes) -> tuple[str, dict]:
    """The title (first comment line) and the ``; key: value`` lines before the first
    block."""
    title, info = "", {}
    for raw in first.split(b"\n"):
        text = raw.decode("ascii", "replace").strip()
        if not text:
            continue
        if not text.startswith(";") and not (text.startswith("(") and text.endswith(")")):
            if text != "%" and not text.startswith("%"):
                break
            continue
        body = text[1:-1] if text.startswith("(") else text[1:]
        body = body.strip()
        if not title:
            title = body
        if ":" in body:
            k, v = body.split(":", 1)
            if re.fullmatch(r"[A-Za-z0-9_]+", k.strip()):
                info[k.strip()] = v.strip()
    return title, info


def _ffill(vals: np.ndarray, start: float) -> np.ndarray:
    """``vals`` with each NaN replaced by the last value before it (``start`` first)."""
    vals = np.r_[start, vals]
    ok = ~np.isnan(vals)
    idx = np.where(ok, np.arange(vals.size), 0)
    np.maximum.accumulate(idx, out=idx)
    return vals[idx][1:]


class _Scanner:
    def __init__(self, path: Path):
        self.path = path
        self.state = {"motion": 1.0, "distance": 90.0, "feed": 94.0, "units": 21.0,
                      "plane": 18.0, "spindle": 97.0, "F": math.nan, "S": math.nan,
                      "clamp": math.nan}
        self.pos = {a: math.nan for a in "XYZC"}
        self.out = []
        self.g_codes, self.m_codes, self.words, self.notes = set(), set(), set(), []
        self.blocks = 0
        self.ended = False

    # ------------------------------------------------------------------ one piece
    def piece(self, raw: bytes, line0: int) -> None:
        path = self.path

        def fail(pos_line: int, text: str):
            _fail(path, line0 + pos_line, raw.split(b"\n")[pos_line], text)

        up = raw.upper()
        if b"(" in up or b")" in up:
            up = _PAREN.sub(b"", up)
            for ch in (b"(", b")"):
                k = up.find(ch)
                if k >= 0:
                    fail(up.count(b"\n", 0, k), "a comment '(' without its ')' on the same line"
                         if ch == b"(" else "a ')' without its '('")
        if b";" in up:
            up = _SEMI.sub(b"", up)
        if b"%" in up:
            up = _PERCENT.sub(b"", up)
        if b":" in up:
            up = _COLON.sub(b"", up)
        if b"/" in up:
            n0 = len(up)
            up = _SLASH.sub(b"", up)
            if len(up) != n0 and "block delete" not in " ".join(self.notes):
                self.notes.append("blocks marked '/' (block delete) are run, as with the "
                                  "block-delete switch off")
        s = up.translate(None, b" \t\r")
        a = np.frombuffer(s, dtype=np.uint8)
        cls_b = s.translate(_CLASS_TABLE)
        cls = np.frombuffer(cls_b, dtype=np.uint8)
        # one pass over the byte pairs: a bad byte, a letter without its number, a number
        # without its letter, a sign inside a number
        pair = np.empty(cls.size, dtype=np.uint8)
        pair[0] = 5 * 8 + cls[0]
        np.multiply(cls[:-1], 8, out=pair[1:])
        pair[1:] += cls[1:]
        k = pair.tobytes().translate(_BAD_PAIR_TABLE).find(b"\x01")
        if k >= 0:
            code = int(pair[k])
            first, second = divmod(code, 8)
            at = k if second == 0 or first != 1 else k - 1
            line = s.count(b"\n", 0, at)
            if second == 0:
                ch = chr(a[k]) if 32 <= a[k] < 127 else f"byte 0x{a[k]:02x}"
                fail(line, f"cannot read {ch!r} (a block holds words: a letter and a number, "
                           f"e.g. X1.25)")
            if first == 1:
                fail(line, f"the word {chr(a[k - 1])!r} has no number")
            if second == 4:
                fail(line, "a sign inside a number")
            if first in (2, 3, 4):
                fail(line, "a malformed number (two points or a sign without digits)")
            fail(line, "a number without its letter")
        letter = cls == 1
        pos = np.flatnonzero(letter)
        nw = pos.size
        if nw == 0:
            return
        wid = np.cumsum(letter, dtype=np.int32)
        wid -= 1
        dig = np.flatnonzero(cls == 2)
        dots = np.flatnonzero(cls == 3)
        nlpos = np.flatnonzero(cls == 5)
        dw = wid[dig]
        ndig = np.bincount(dw, minlength=nw)
        ndot = np.bincount(wid[dots], minlength=nw)
        err = np.flatnonzero((ndot > 1) | (ndig == 0))
        if err.size:
            k = int(pos[err[0]])
            fail(s.count(b"\n", 0, k), f"the word {chr(a[k])!r} has no valid number")
        # the numbers: digits weighted by their powers of ten (exact integers below 2^53),
        # divided by 10^(digits after the point): the correctly rounded value, as float()
        before = np.cumsum(ndig) - ndig            # digits of the words before
        rank = np.arange(dig.size, dtype=np.int64) - before[dw]    # digit's index in its word
        power = ndig[dw] - 1 - rank
        mant = np.bincount(dw, weights=(a[dig] - 48) * _POW10[np.minimum(power, 300)], minlength=nw)
        frac = np.zeros(nw, dtype=np.int64)
        if dots.size:
            dword = wid[dots]
            # digits after the point: those of the word at positions after the dot
            after = np.searchsorted(dig, dots)      # first digit after each dot
            frac[dword] = (before[dword] + ndig[dword]) - after
        vals = mant / _POW10[np.minimum(frac, 300)]
        long = np.flatnonzero(ndig > 15)
        if long.size:  # more digits than a double holds exactly: read as float() reads them
            nxt_nl = nlpos[np.searchsorted(nlpos, pos[long])]
            nxt_letter = np.r_[pos, a.size][long + 1]
            ends = np.minimum(nxt_nl, nxt_letter)
            for j, e in zip(long.tolist(), ends.tolist()):
                vals[j] = abs(float(s[pos[j] + 1:e]))
        neg = np.flatnonzero(a[np.minimum(pos + 1, a.size - 1)] == ord("-"))
        vals[neg] = -vals[neg]
        letters = a[pos]
        wline = np.searchsorted(nlpos, pos)  # line index inside the piece
        self._blocks(letters, vals, wline, raw, line0, fail)

    # ------------------------------------------------------------------ blocks
    def _blocks(self, letters, vals, wline, raw, line0, fail):
        new = np.r_[True, wline[1:] != wline[:-1]]
        bid = np.cumsum(new) - 1
        nb = int(bid[-1]) + 1
        bline = wline[new]
        present = set(chr(c) for c in np.unique(letters))
        self.words |= present
        col = {}
        for ch in present:
            if ch in "GM":
                continue
            if ch not in _SINGLE:
                k = int(np.flatnonzero(letters == ord(ch))[0])
                fail(int(wline[k]), f"the word {ch!r} is not a word this reader takes "
                                    f"(axes X Y Z C, U V W H, arcs I J K R, F, S, N, O, T, M, G, P)")
            m = letters == ord(ch)
            b = bid[m]
            dup = np.flatnonzero(b[1:] == b[:-1])
            if dup.size:
                fail(int(bline[b[dup[0]]]), f"the word {ch!r} appears twice")
            v = np.full(nb, math.nan)
            v[b] = vals[m]
            col[ch] = v
        nan = np.full(nb, math.nan)
        # ---- G codes
        grp = {g: nan.copy() for g in _GROUPS}
        dwell = np.zeros(nb, bool)
        home = np.zeros(nb, bool)
        clamp = np.zeros(nb, bool)
        if "G" in present:
            m = letters == ord("G")
            gv, gb = vals[m], bid[m]
            known = np.isin(gv, _KNOWN_G)
            if not known.all():
                k = int(np.flatnonzero(~known)[0])
                fail(int(bline[gb[k]]), f"G{gv[k]:g} is not a G code this reader takes "
                                        f"(it takes {', '.join(f'G{g:02d}' for g in _KNOWN_G if g not in _REFUSED)})")
            refused = np.isin(gv, list(_REFUSED))
            if refused.any():
                k = int(np.flatnonzero(refused)[0])
                fail(int(bline[gb[k]]), f"G{gv[k]:g} is refused: {_REFUSED[int(gv[k])]}")
            self.g_codes |= {int(g) for g in np.unique(gv)}
            for name, codes in _GROUPS.items():
                sel = np.isin(gv, codes)
                if not sel.any():
                    continue
                b = gb[sel]
                dup = np.flatnonzero(b[1:] == b[:-1])
                if dup.size:
                    fail(int(bline[b[dup[0]]]), f"two G codes of the same group ({name})")
                grp[name][b] = gv[sel]
            dwell[gb[gv == _DWELL]] = True
            home[gb[gv == _HOME]] = True
            clamp[gb[gv == _CLAMP]] = True
        if "M" in present:
            m = letters == ord("M")
            mv, mb = vals[m], bid[m]
            self.m_codes |= {int(v) for v in np.unique(mv)}
            end = np.flatnonzero(np.isin(mv, (2, 30)))
            if end.size:  # the program ends here: blocks after it are not run
                last = int(mb[end[0]])
                self.ended = True
                keep = bid <= last
                return self._blocks(letters[keep], vals[keep], wline[keep], raw, line0, fail) \
                    if last < nb - 1 else self._finish(nb, col, grp, dwell, home, clamp, bline,
                                                       line0, fail)
        return self._finish(nb, col, grp, dwell, home, clamp, bline, line0, fail)

    def _finish(self, nb, col, grp, dwell, home, clamp, bline, line0, fail):
        st = self.state
        nan = np.full(nb, math.nan)
        self.blocks += nb
        modal = {}
        for name in _GROUPS:
            if name == "radius_comp":
                continue
            modal[name] = _ffill(grp[name], st[name])
            st[name] = float(modal[name][-1])
        inch = (modal["units"] == 20) | (modal["units"] == 70)
        scale = np.where(inch, INCH_MM, 1.0)
        # G50 S: the spindle clamp (G50 with axis words would set coordinates: refused)
        if clamp.any():
            for ax in "XZUW":
                if ax in col and np.any(clamp & ~np.isnan(col[ax])):
                    k = int(np.flatnonzero(clamp & ~np.isnan(col[ax]))[0])
                    fail(int(bline[k]), "G50 with axis words sets the coordinate system; the "
                                        "reader takes G50 S (the spindle clamp) only")
        s_words = col.get("S", nan)
        clamp_v = np.where(clamp, s_words, math.nan)
        clamp_m = _ffill(clamp_v, st["clamp"])
        st["clamp"] = float(clamp_m[-1])
        s_spindle = np.where(clamp, math.nan, s_words)
        s_m = _ffill(s_spindle, st["S"])
        st["S"] = float(s_m[-1])
        f_words = col.get("F", nan)
        # F in length units is scaled by the unit mode; inverse time (G93) is not
        fscale = np.where(modal["feed"] == 93, 1.0, scale)
        f_m = _ffill(f_words * fscale, st["F"])
        st["F"] = float(f_m[-1])
        non_motion = dwell | home | clamp
        if dwell.any():
            self.notes.append("dwells (G04) are not simulated (the tool stands still)")
        if home.any():
            self.notes.append("returns home (G28) are not simulated (the home position is not "
                              "known; the next move starts from the last point programmed)")
        # ---- positions
        inc_mode = modal["distance"] == 91
        axes, written = {}, {}
        any_axis = np.zeros(nb, bool)
        for ax, inc_letter in _INCREMENTAL.items():
            v = col.get(ax, nan)
            u = col.get(inc_letter, nan)
            if ax != "C":
                v, u = v * scale, u * scale
            has_v, has_u = ~np.isnan(v) & ~non_motion, ~np.isnan(u) & ~non_motion
            both = np.flatnonzero(has_v & has_u)
            if both.size:
                fail(int(bline[both[0]]), f"both {ax} and {inc_letter} (absolute and incremental "
                                          f"{ax}) in one block")
            absolute = has_v & ~inc_mode
            step = np.where(has_v & inc_mode, v, 0.0) + np.where(has_u, u, 0.0)
            cs = np.cumsum(step)
            anchor = np.where(absolute, v - cs, math.nan)
            start = self.pos[ax]
            p = _ffill(anchor, start) + cs
            self.pos[ax] = float(p[-1])
            axes[ax] = p
            written[ax] = has_v | has_u
            any_axis |= written[ax]
        arcs = {k: col.get(k, nan) * scale for k in "IJKR"}
        moving = np.flatnonzero(any_axis)
        if moving.size:
            self.out.append({
                "line": (bline[moving] + line0).astype(np.int64),
                "motion": modal["motion"][moving].astype(np.int8),
                "axes": {a: v[moving] for a, v in axes.items()},
                "written": {a: v[moving] for a, v in written.items()},
                "arc": {a: v[moving] for a, v in arcs.items()},
                "feed": f_m[moving], "feed_mode": modal["feed"][moving].astype(np.int16),
                "spindle": s_m[moving], "spindle_mode": modal["spindle"][moving].astype(np.int16),
                "clamp": clamp_m[moving], "plane": modal["plane"][moving].astype(np.int16)})


def scan_program(path, *, piece_bytes: int = PIECE_BYTES) -> ScannedProgram:
    """Read every block of the NC program ``path`` (see the module docstring).

    Raises :class:`InputError` naming the file, the line, the block and the word of the
    first block it cannot read."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"program file not found: {str(path)!r}")
    sc = _Scanner(path)
    title, header, lines = "", {}, 0
    for k, (raw, line0) in enumerate(_pieces(path, piece_bytes)):
        if k == 0:
            title, header = _header(raw[:1 << 16])
        if np.any(np.frombuffer(raw, np.uint8) > 127):
            i = int(np.flatnonzero(np.frombuffer(raw, np.uint8) > 127)[0])
            _fail(path, line0 + raw.count(b"\n", 0, i), raw.split(b"\n")[raw.count(b"\n", 0, i)],
                  "a byte that is not ASCII text (is this an NC program?)")
        lines = line0 + raw.count(b"\n") - 1
        sc.piece(raw, line0)
        if sc.ended:
            break
    out = sc.out
    cat = (lambda key, dt: np.concatenate([o[key] for o in out]).astype(dt) if out
           else np.zeros(0, dt))
    sub = (lambda key, name, dt: np.concatenate([o[key][name] for o in out]).astype(dt) if out
           else np.zeros(0, dt))
    return ScannedProgram(
        path=path, line=cat("line", np.int64), motion=cat("motion", np.int8),
        axes={a: sub("axes", a, np.float64) for a in "XYZC"},
        written={a: sub("written", a, bool) for a in "XYZC"},
        arc={a: sub("arc", a, np.float64) for a in "IJKR"},
        feed=cat("feed", np.float64), feed_mode=cat("feed_mode", np.int16),
        spindle=cat("spindle", np.float64), spindle_mode=cat("spindle_mode", np.int16),
        clamp_rpm=cat("clamp", np.float64), plane=cat("plane", np.int16),
        header=header, title=title, blocks=sc.blocks, g_codes=sc.g_codes, m_codes=sc.m_codes,
        notes=list(dict.fromkeys(sc.notes)), words=sc.words, lines=lines)
