"""The spindle's direction and stops in a lathe program (M03, M04, M05; M00, M01 are
notes of the scanner): which way the spindle turns while the program cuts, which moves
it stands still in, and what is refused.

* M03 / M04 / M05 are modal; in a block with a move they act before the move (the order
  of execution of RS274NGC: the spindle is switched, then the axes move).
* Without C words (the spindle's angle taken from its turning) the spindle turns M03 or
  M04 while the program cuts; moves before the program's first M03 / M04 are read with
  the spindle already turning that way (a program that never says: M03, as the scene's
  spindle).  M04 cuts the mirror image of M03: the caller marks the path
  (:data:`~render_inspect.core.toolpath.SPINDLE_KEY`) and the simulation cuts the
  mirror image.  A cutting move (G01 .. G03) with the spindle stopped (M05) is
  refused; rapids while it stands take their time without turning it.  A program that
  cuts with the spindle turning both ways is refused (one run cuts one hand).
* With C words C is the spindle under position control: its words set the angle, the
  spindle's M codes do not move it (controls refuse them in C-axis mode; before it they
  start and stop the freely turning spindle): noted, not simulated.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import SPINDLE_KEY, ToolPath
from ._program_angles import c_backward, c_first_step
from ._program_scan import ScannedProgram

__all__ = ["Spindle", "spindle_of", "stopped_sentence", "c_mode_note", "c_way", "own_spindle",
           "HANDS", "MIRROR"]

#: the spindle's directions: M code -> the words the reader says
HANDS = {3: "M03", 4: "M04"}
#: what M04 does to the simulated part, said once (inferred and docs/programs.md)
MIRROR = ("the part is cut as the mirror image (y -> -y about the spindle axis) of the "
          "same program run M03 on the mirrored design; maps, figures, metrics and the "
          "program's files are in the part's own coordinates")
_COMMENT = re.compile(r"\([^)]*\)|;.*")


@dataclass
class Spindle:
    """``direction``: 3 (M03) or 4 (M04) while the program cuts; ``stopped``: per point,
    whether the move ending there runs with the spindle stopped (None: never);
    ``said``: what to add to the sentence on the spindle ("" where nothing)."""

    direction: int
    stopped: np.ndarray | None
    said: str


def _line(sp: ScannedProgram, pts: slice | np.ndarray, k: int) -> int:
    return int(sp.line[pts][k]) if isinstance(pts, slice) else int(sp.line[pts[k]])


def _m_line(path: Path, line: int, m: int) -> int:
    """The file line of the last ``M<m>`` up to ``line`` (comments skipped; ``line``
    where none is found): where the spindle was last switched so."""
    word = re.compile(rf"M0*{m}(?![0-9.])")
    last = line
    with Path(path).open("rb") as fh:
        for no, raw in enumerate(fh, start=1):
            if no > line:
                break
            text = _COMMENT.sub("", raw.decode("ascii", "replace").upper().replace(" ", ""))
            if word.search(text):
                last = no
    return last


def spindle_of(sp: ScannedProgram, pts: slice | np.ndarray, motion: np.ndarray) -> Spindle:
    """The spindle of the X-Z lathe program ``sp`` (a ScannedProgram) at its points
    ``pts`` (a slice or the rows of its points) whose blocks move as ``motion``; raises
    :class:`InputError` naming the line of a cutting move with the spindle stopped, or of
    one that turns it the other way than the cutting moves before it."""
    d = sp.spindle_dir[pts]
    if d.size == 0 or int(d.max()) <= 3:  # M03 or nothing: the project's turning
        return Spindle(3, None, "")
    # (masks and first indices: a few bytes a block, whatever the program's length)
    stated = (d == 3) | (d == 4)
    k0 = int(np.argmax(stated))
    first = int(d[k0]) if stated[k0] else 3
    stopped = d == 5
    cutting = motion >= 1
    bad = stopped & cutting
    if bad.any():
        k = int(np.argmax(bad))
        line = _line(sp, pts, k)
        raise InputError(f"{sp.path}:{line}: a cutting move (G0{int(motion[k])}) with the "
                         f"spindle stopped (M05 at line {_m_line(sp.path, line, 5)}): a "
                         f"control would feed the tool into the standing part or stop with an "
                         f"alarm; start the spindle (M03 / M04) before the cutting moves "
                         f"(rapids, G00, may run while it stands)")
    turning = np.where(d == 0, np.int8(first), d)
    cut = cutting & ~stopped
    direction = int(turning[int(np.argmax(cut))]) if cut.any() else first
    other = cut & (turning != direction)
    if other.any():
        k = int(np.argmax(other))
        raise InputError(f"{sp.path}:{_line(sp, pts, k)}: this cutting move turns the spindle "
                         f"{HANDS[int(turning[k])]}, the cutting moves before it "
                         f"{HANDS[direction]}: a program that cuts with the spindle turning "
                         f"both ways is not simulated in one run (each way cuts the mirror "
                         f"image of the other); split the program where the spindle turns round")
    said = []
    at = _m_line(sp.path, _line(sp, pts, k0), first) if stated[k0] else 0
    if direction == 4:
        said.append(f"the spindle turns counter-clockwise (M04, line {at}): " + MIRROR)
    if stated[k0] and cutting[:k0].any():
        said.append(f"the moves before the first {HANDS[first]} (line {at}) are read with "
                    f"the spindle already turning {HANDS[first]}")
    return Spindle(direction, stopped if stopped.any() else None,
                   "".join(f" ; {s}" for s in said))


def stopped_sentence(stopped: np.ndarray, dt: np.ndarray, ln: np.ndarray) -> str:
    """`` ; the spindle stands (M05) in 3 rapid moves (lines 12 .. 14), 0.06 s ...``: the
    moves (``stopped``, per move, of times ``dt`` s; ``ln`` the file lines of those
    moves) run with the spindle stopped, and how their time is counted."""
    n = int(stopped.sum())
    span = f"line {int(ln[0])}" if ln.min() == ln.max() else \
        f"lines {int(ln.min())} .. {int(ln.max())}"
    return (f" ; the spindle stands (M05) in {n} rapid move{'s' if n != 1 else ''} ({span}), "
            f"{float(np.sum(dt[stopped])):.6g} s at the rapid rate, counted in the program's "
            f"time, with the spindle's angle standing still; the spindle stops and starts at "
            f"once (its run-down and run-up take no time)")


def c_mode_note(m_codes: set, down: bool) -> str | None:
    """The note on M03 / M04 / M05 in a program with C words (None where none is due):
    the C words turn the spindle (``down``: C decreases, the other way than M03)."""
    said = sorted({4, 5} & m_codes | ({3} & m_codes if down else set()))
    if not said:
        return None
    way = ("decreasing: the spindle turns the other way, as with M04" if down
           else "increasing: the spindle turns as with M03")
    return (f"{' / '.join(f'M{m:02d}' for m in said)} in a program with C words: C is the "
            f"spindle under position control and its words set the angle (here C is {way}); "
            f"the spindle's M03 / M04 / M05 do not move C and are not simulated (controls "
            f"refuse them in C-axis mode; before it they start or stop the spindle turning "
            f"freely)")


def c_way(c: np.ndarray, sp: ScannedProgram, blk: np.ndarray, wrap: float) -> bool:
    """Which way the C words ``c`` (deg as written, the reader's own copy; ``blk``: the
    program's row of each) turn the spindle: that of their first step shorter than a
    wrap (``wrap`` deg or more the other way starts a new revolution).  True where C
    decreases (the spindle turning the other way, as M04): ``c`` is then negated in
    place.  Raises :class:`InputError` naming the line of a later step the other way."""
    k = int(c_first_step(c, wrap))
    down = bool(k >= 0 and c[k + 1] < c[k])
    if down:
        np.negative(c, out=c)
    back = int(c_backward(c, wrap))
    if back >= 0:
        line = int(sp.line[blk[1:][back]])
        sign = -1.0 if down else 1.0
        c0, c1 = sign * float(c[back]), sign * float(c[back + 1])
        way, turn, eg = (("increases", "decreases", "C0 to C359.5") if down else
                         ("decreases", "increases", "C359.5 to C0"))
        raise InputError(f"{sp.path}:{line}: C {way} by {abs(c0 - c1):.6g} deg (C{c0:g} to "
                         f"C{c1:g}) in a program whose C {turn}: the spindle would turn round; "
                         f"C may step the other way only to start a new revolution, by "
                         f"{wrap:g} deg or more ({eg})")
    return down


def own_spindle(path: ToolPath) -> dict:
    """What :func:`read_program` infers of the spindle of a program in the project's own
    turning dialect (``path``, the ToolPath read): C decreasing is the spindle turning
    M04."""
    if getattr(path, "meta", {}).get(SPINDLE_KEY) != "M04":
        return {}
    return {"spindle": "C decreases: the spindle turns counter-clockwise (M04); " + MIRROR}
