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

from ..core.units import MIB_TO_BYTES
from ..core.errors import InputError
from ._program_integers import check_integers
from ._program_kernel import (G_GROUP, GROUP_NAMES, INCR_SLOT, INIT_STATE, ROW_FIELDS,
                              clean_piece, scan_piece)

__all__ = ["ScannedProgram", "scan_program", "PIECE_BYTES", "INCH_MM"]

#: bytes read and parsed at a time (the scanner's memory does not grow with the program)
PIECE_BYTES = MIB_TO_BYTES
#: one inch, mm
INCH_MM = 25.4

_PAREN = re.compile(rb"\([^()\n]*\)")
_SEMI = re.compile(rb";[^\n]*")
_PERCENT = re.compile(rb"(?m)^[ \t]*%[^\n]*")
_COLON = re.compile(rb"(?m)^[ \t]*:[0-9]*")
_SLASH = re.compile(rb"(?m)^[ \t]*/")
#: the byte order mark some editors write at the start of a UTF-8 file
_BOM = b"\xef\xbb\xbf"

_REFUSED = {41: "controller tool-nose radius compensation (G41/G42) moves the tool by an "
                "offset the program does not state; program the tool centre or tip path",
            42: "controller tool-nose radius compensation (G41/G42) moves the tool by an "
                "offset the program does not state; program the tool centre or tip path"}
#: the G codes read (the others are refused with their line)
_KNOWN_G = sorted(int(g) for g in np.flatnonzero(G_GROUP >= 0))


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
    held: np.ndarray = field(default_factory=lambda: np.zeros(0))  # 1 where G97 came
    # without S after G96 (the spindle keeps its speed of the switch; ``spindle`` is then
    # the surface speed of G96, m/min), NaN elsewhere
    spindle_dir: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int8))  # the
    # spindle's last M03 / M04 / M05 before the move (3, 4, 5; 0 where none came yet)
    x_unit: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int8))  # the unit
    # the move's X was written in: 0 mm (G21 / G71), 1 inch (G20 / G70), 2 both (incremental
    # words of the other unit added to it), -1 where X is not yet known
    header: dict = field(default_factory=dict)   # leading "; key: value" comment lines
    title: str = ""             # the first comment line
    blocks: int = 0             # blocks read (all kinds)
    g_codes: set = field(default_factory=set)
    m_codes: set = field(default_factory=set)
    notes: list = field(default_factory=list)    # what was read but does not move the tool
    words: set = field(default_factory=set)      # letters present
    lines: int = 0              # lines of the file read
    integers: str = "whole"     # how numbers without a decimal point were read
    # nonzero position and angle words of the moves "with" and "without" a decimal point;
    # "first" without one: (word as written, file line, value, unit 0 mm 1 in 2 deg)
    decimals: dict = field(default_factory=lambda: {"with": 0, "without": 0, "first": None})

    @property
    def count(self) -> int:
        return int(self.line.size)


def _fail(path, lineno: int, block: bytes, text: str):
    shown = block.decode("ascii", "replace").strip()
    if len(shown) > 120:
        shown = shown[:117] + "..."
    raise InputError(f"{path}:{lineno}: {text} in block {shown!r}")


def _pieces(path: Path, piece_bytes: int):
    """(bytes ending at a line break, line number of its first line, line breaks in it)."""
    line = 1
    rest = b""
    first, cr_only = True, False
    with path.open("rb") as fh:
        while True:
            data = fh.read(piece_bytes)
            if not data:
                break
            if first:  # a byte order mark; lines ended by CR alone (old Mac editors)
                first = False
                if data.startswith(_BOM):
                    data = data[len(_BOM):]
                cr_only = b"\n" not in data and b"\r" in data
            if cr_only:
                data = data.replace(b"\r", b"\n")
            if rest:
                data = rest + data
            cut = data.rfind(b"\n")
            if cut < 0:
                rest = data
                continue
            if cut + 1 == len(data):
                piece, rest = data, b""
            else:
                piece, rest = data[:cut + 1], data[cut + 1:]
            newlines = piece.count(b"\n")
            yield piece, line, newlines
            line += newlines
    if rest:
        yield rest + b"\n", line, rest.count(b"\n") + 1


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


class _Scanner:
    def __init__(self, path: Path, integers: str = "whole"):
        self.path = path
        self.integers = integers
        self.state = INIT_STATE.copy()
        self.state[INCR_SLOT] = check_integers(integers)
        # (see scan_piece: counts with and without a point; the first without one)
        self.undotted = np.array([0.0, 0.0, -1.0, math.nan, -1.0, 0.0])
        self.seen_g = np.zeros(100, dtype=np.bool_)
        self.seen_m = np.zeros(100, dtype=np.bool_)
        self.seen_letter = np.zeros(26, dtype=np.bool_)
        self.flags = np.zeros(4, dtype=np.bool_)   # dwell, return home, M00, M01
        self.out: list[dict] = []
        self.buf = np.empty(0, np.uint8)                    # a piece's cleaned bytes
        self.rows = np.empty((len(ROW_FIELDS), 0))          # a piece's rows (reused)
        self.notes: list[str] = []
        self.blocks = 0
        self.ended = False

    # ------------------------------------------------------------------ one piece
    def _text(self, raw: bytes, line0: int, fail) -> bytes:
        """The bytes of the piece ``raw`` as :func:`scan_piece` reads them, the general
        way (comments of every form, ``%``, ``:`` and ``/`` at a line's start; one line
        for anything else)."""
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
        # text in comments may be in any encoding (a degree sign, a diameter sign); the
        # words outside them are ASCII (comments do not span lines: the line numbers stay)
        if np.any(np.frombuffer(up, np.uint8) > 127):
            i = int(np.flatnonzero(np.frombuffer(up, np.uint8) > 127)[0])
            fail(up.count(b"\n", 0, i), "a byte that is not ASCII text outside a comment (is "
                 "this an NC program?)")
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
        return up.translate(None, b" \t\r")

    def piece(self, raw: bytes, line0: int, newlines: int) -> None:
        """Scan the piece ``raw`` (whole lines, ``newlines`` of them, the first is file
        line ``line0``)."""
        path = self.path

        def fail(pos_line: int, text: str):
            _fail(path, line0 + pos_line, raw.split(b"\n")[pos_line], text)

        if self.buf.size < len(raw):
            self.buf = np.empty(len(raw), np.uint8)
        # the usual piece (words, spaces, closed comments) cleaned by the compiled pass
        m, ok = clean_piece(np.frombuffer(raw, np.uint8), self.buf)
        if ok:
            a = self.buf[:m]
        else:
            a = np.frombuffer(self._text(raw, line0, fail), dtype=np.uint8)
        if self.rows.shape[1] < newlines + 1:
            self.rows = np.empty((len(ROW_FIELDS), newlines + 1))
        rows = self.rows
        first_before = self.undotted[2] >= 0
        nrow, blocks, err, at, detail, line = scan_piece(
            a, self.state, rows, self.seen_g, self.seen_m, self.seen_letter, self.flags,
            self.undotted)
        if not first_before and self.undotted[2] >= 0:
            self.undotted[4] += line0
        self.blocks += int(blocks)
        if err:
            self._error(err, a.tobytes(), int(at), int(detail), int(line), fail)
        if self.state[13]:
            self.ended = True
        if nrow:
            r = rows[:, :nrow]

            def kept(k):  # a column nothing in this piece sets is not stored
                v = r[k]
                return None if np.isnan(v).all() else v.copy()
            w = r[16].astype(np.int8)
            line_no = r[0].astype(np.int64)
            line_no += line0
            self.out.append({
                "n": int(nrow),
                "line": line_no,
                "motion": r[1].astype(np.int8),
                "axes": {ax: kept(2 + k) for k, ax in enumerate("XYZC")},
                "written": {ax: (w & (1 << k)) != 0 for k, ax in enumerate("XYZC")},
                "arc": {ax: kept(6 + k) for k, ax in enumerate("IJKR")},
                "feed": kept(10), "feed_mode": r[11].astype(np.int16),
                "spindle": kept(12), "spindle_mode": r[13].astype(np.int16),
                "clamp": kept(14), "plane": r[15].astype(np.int16), "held": kept(17),
                "spindle_dir": r[18].astype(np.int8), "x_unit": r[19].astype(np.int8)})

    def _error(self, err, s, at, detail, line, fail):
        """One line for the error ``err`` of :func:`scan_piece` (see its module)."""
        a = s
        if err == 1:
            ch = chr(a[at]) if 32 <= a[at] < 127 else f"byte 0x{a[at]:02x}"
            fail(line, f"cannot read {ch!r} (a block holds words: a letter and a number, "
                       f"e.g. X1.25; macro variables '#', expressions and named words "
                       f"such as LIMS= are not taken)")
        letter = chr(65 + detail) if 0 <= detail < 26 else "?"
        if err == 2:
            nxt = a[at + 1] if at + 1 < len(a) else 10
            named = 65 <= nxt <= 90
            fail(line, f"the word {letter!r} has no number" + (
                " (a block holds words: a letter and a number; named words such as "
                "DIAMON, LIMS= or CR= are not taken)" if named else ""))
        if err == 5 and letter == "E" and at > 0 and (48 <= a[at - 1] <= 57 or a[at - 1] == 46):
            fail(line, "a number with an exponent ('E'): NC words take plain decimals "
                       "(write X0.001, not X1.E-3)")
        if err == 3:
            prev = a[at - 1] if at > 0 else 10
            if 48 <= prev <= 57 or prev == 46:
                fail(line, "a sign inside a number")
            fail(line, "a number without its letter")
        if err == 4:
            fail(line, f"the word {letter!r} has no valid number")
        if err == 5:
            fail(line, f"the word {letter!r} is not a word this reader takes (axes X Y Z C, "
                       f"U V W H, arcs I J K R, F, S, N, O, T, M, G, P)")
        if err == 6:
            fail(line, f"the word {letter!r} appears twice")
        text = s.split(b"\n")[line].decode("ascii", "replace")
        gs = re.findall(r"G([-+]?[0-9.]+)", text)
        if err in (7, 8):
            g = gs[detail] if detail < len(gs) else "?"
            try:
                gv = f"G{float(g):g}"
            except ValueError:
                gv = f"G{g}"
            if err == 8:
                fail(line, f"{gv} is refused: {_REFUSED[int(float(g))]}")
            fail(line, f"{gv} is not a G code this reader takes (it takes "
                       f"{', '.join(f'G{g:02d}' for g in _KNOWN_G if g not in _REFUSED)})")
        if err == 9:
            fail(line, f"two G codes of the same group ({GROUP_NAMES[detail]})")
        if err == 10:
            fail(line, "G50 with axis words sets the coordinate system; the reader takes "
                       "G50 S (the spindle clamp) only")
        if err == 11:
            inc = {"X": "U", "Y": "V", "Z": "W", "C": "H"}[letter]
            fail(line, f"both {letter} and {inc} (absolute and incremental {letter}) in one "
                       f"block")
        if err == 12:
            fail(line, "G90 / G94 with axis words in a program with G98 / G99 (Fanuc lathe "
                       "G-code system A) is the turning / facing cycle, which this reader "
                       "does not take; program the cycle's moves with G00 / G01")
        if err == 13:  # detail: the feed mode, + 1000 in inches
            f = re.search(r"F([-+]?[0-9]+)(?![0-9.])", text)
            n = f.group(1) if f else "?"
            fm = detail % 1000
            unit = "per minute (inverse time, G93)" if fm == 93 else \
                ("in" if detail >= 1000 else "mm") + ("/rev (G95)" if fm == 95 else "/min (G94)")
            fail(line, f"F{n} has no decimal point: with process.program_integers = "
                       f"{self.integers!r} the position words without one count least input "
                       f"increments, and controls read F without one in different ways; write "
                       f"the feed with its decimal point (F{n}. for {n} {unit})")
        fail(line, "cannot read the block")


def scan_program(path: str | Path, *, piece_bytes: int = PIECE_BYTES,
                 integers: str = "whole") -> ScannedProgram:
    """Read every block of the NC program ``path`` (see the module docstring); position
    and angle words without a decimal point in whole units (``integers="whole"``) or in
    least input increments of the increment system ``integers`` (``"IS-A"`` ..
    ``"IS-E"``: :mod:`~render_inspect.io._program_integers`).

    Raises :class:`InputError` naming the file, the line, the block and the word of the
    first block it cannot read."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"program file not found: {str(path)!r}")
    sc = _Scanner(path, integers)
    header: dict = {}
    title, lines = "", 0
    for k, (raw, line0, newlines) in enumerate(_pieces(path, piece_bytes)):
        if k == 0:
            title, header = _header(raw[:1 << 16])
        lines = line0 + newlines - 1
        sc.piece(raw, line0, newlines)
        if sc.ended:
            break
    # the piece buffers are not needed past the last piece
    sc.buf, sc.rows = np.empty(0, np.uint8), np.empty((len(ROW_FIELDS), 0))
    out = sc.out

    def join(parts, dt):
        """The pieces' columns end to end; NaN for pieces that did not store one."""
        if not out:
            return np.zeros(0, dt)
        if all(v is None for v in parts):  # never set: a read-only view, no memory
            return np.broadcast_to(np.asarray(math.nan, dt), (sum(o["n"] for o in out),))
        return np.concatenate([np.full(o["n"], math.nan) if v is None else v
                               for o, v in zip(out, parts)]).astype(dt, copy=False)

    cat = (lambda key, dt: join([o[key] for o in out], dt))
    sub = (lambda key, name, dt: join([o[key][name] for o in out], dt))
    notes = list(sc.notes)
    if sc.flags[0]:
        notes.append("dwells (G04) are not simulated (the tool stands still)")
    if sc.flags[1]:
        notes.append("returns home (G28) are not simulated (the home position is not known; "
                     "the next move starts from the last point programmed)")
    stops = [f"{m} ({what})" for m, what, on in (("M00", "program stop", sc.flags[2]),
                                                 ("M01", "optional stop", sc.flags[3])) if on]
    if stops:
        notes.append(f"{' and '.join(stops)}: the program stops there for the operator; the "
                     f"stop takes no machining time in the model (the program resumes with "
                     f"the tool where it stood and the spindle as it was)")
    return ScannedProgram(
        path=path, line=cat("line", np.int64), motion=cat("motion", np.int8),
        axes={a: sub("axes", a, np.float64) for a in "XYZC"},
        written={a: sub("written", a, bool) for a in "XYZC"},
        arc={a: sub("arc", a, np.float64) for a in "IJKR"},
        feed=cat("feed", np.float64), feed_mode=cat("feed_mode", np.int16),
        spindle=cat("spindle", np.float64), spindle_mode=cat("spindle_mode", np.int16),
        clamp_rpm=cat("clamp", np.float64), plane=cat("plane", np.int16),
        held=cat("held", np.float64), spindle_dir=cat("spindle_dir", np.int8),
        x_unit=cat("x_unit", np.int8),
        header=header, title=title, blocks=sc.blocks,
        g_codes={int(g) for g in np.flatnonzero(sc.seen_g)},
        m_codes={int(m) for m in np.flatnonzero(sc.seen_m)},
        notes=list(dict.fromkeys(notes)),
        words={chr(65 + int(k)) for k in np.flatnonzero(sc.seen_letter)}, lines=lines,
        integers=integers, decimals=_decimals(sc.undotted))


def _decimals(u: np.ndarray) -> dict:
    """:attr:`ScannedProgram.decimals` from the scanner's counts (see :func:`scan_piece`)."""
    first = None
    if u[2] >= 0:
        v = float(u[3])
        first = (f"{chr(65 + int(u[2]))}{v:.0f}", int(u[4]), v, int(u[5]))
    return {"with": int(u[0]), "without": int(u[1]), "first": first}
