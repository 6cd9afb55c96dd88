"""Numbers without a decimal point in a machine program (``process.program_integers``).

A control with "calculator-type" decimal input (Fanuc's decimal point programming, a
Mitsubishi control set to decimal point input type II) reads ``X2000`` as 2000 mm; one
without it (Mitsubishi type I, Fanuc with the parameter off) counts least input
increments of its increment system: ``X2000`` is 2 mm on IS-B.  A number written with a
decimal point (``X2.``, ``X2.0``) is mm, inches or degrees on both.  The scanner
(:func:`~render_inspect.io._program_scan.scan_program`) reads the position and angle
words (X Y Z C, U V W H, I J K R) so and counts those written without a point; this
module says what was read, warns where a program at the default reading writes them, and
adds the hint to the refusal of a path beyond the part.  docs/programs.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ..core.errors import InputError
from ..core.lazy import njit  # numba, imported on first use

__all__ = ["PROGRAM_INTEGERS", "INCREMENT_PLACES", "POS_LETTERS", "check_integers",
           "increments_text", "integers_facts", "beyond_part_hint", "undotted_words"]

#: how a number without a decimal point is read: whole units, or least input increments
#: of an increment system
PROGRAM_INTEGERS = ("whole", "IS-A", "IS-B", "IS-C", "IS-D", "IS-E")
#: places after the point an increment system's least input increment has in mm and in
#: degrees (in inches one more): IS-B 0.001 mm, 0.0001 in, 0.001 deg
INCREMENT_PLACES = {"IS-A": 2, "IS-B": 3, "IS-C": 4, "IS-D": 5, "IS-E": 6}
_UNITS = ("mm", "in", "deg")
#: the words that are positions or angles (X Y Z C, U V W H, I J K R): letter indices (C
#: and H, 2 and 7, are degrees)
POS_LETTERS = np.array([23, 24, 25, 2, 20, 21, 22, 7, 8, 9, 10, 17], dtype=np.int64)
_POW10 = 10.0 ** np.arange(23)   # (exact powers of ten)
_KEY = "process.program_integers"


def check_integers(mode: str) -> int:
    """The places of ``mode`` (0 for ``"whole"``); a value not in
    :data:`PROGRAM_INTEGERS` is an :class:`~render_inspect.core.errors.InputError`."""
    if mode not in PROGRAM_INTEGERS:
        raise InputError(f"{_KEY} must be one of {list(PROGRAM_INTEGERS)}, received {mode!r}")
    return INCREMENT_PLACES.get(mode, 0)


def _places(system: str, unit: int) -> int:
    return INCREMENT_PLACES[system] + (1 if unit == 1 else 0)


def _fmt(value: float, places: int) -> str:
    """``value`` counted in increments of ``10**-places``, as a decimal (no float noise)."""
    text = f"{value / 10 ** places:.{places}f}"
    if places:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def increments_text(system: str) -> str:
    """``0.001 mm, 0.0001 in, 0.001 deg``: the least input increments of ``system``."""
    return ", ".join(f"{_fmt(1, _places(system, u))} {_UNITS[u]}" for u in range(3))


def integers_facts(sp: Any, mode: str) -> tuple[str | None, list[str]]:
    """(the sentence of ``inferred["integers"]``, the warnings) of the scanned program
    ``sp`` read with ``mode``: no sentence and no warning for a program at the default
    reading whose nonzero position words all have a decimal point (nothing to say)."""
    d = sp.decimals
    n = d["without"]
    if mode == "whole" and not n:
        return None, []
    counted = (f"{n:,} of the {n + d['with']:,} nonzero position and angle words have no "
               f"decimal point")
    if mode != "whole":
        return (f"integers as {mode} increments ({increments_text(mode)}; {_KEY}): "
                f"{counted}"), []
    word, line, value, unit = d["first"]
    warning = (f"{sp.path.name}:{line}: {word} has no decimal point: read as {_fmt(value, 0)} "
               f"{_UNITS[unit]}; a control that counts least input increments reads it as "
               f"{_fmt(value, _places('IS-B', unit))} {_UNITS[unit]} (IS-B): set {_KEY} "
               f"({counted})")
    return f"integers as whole mm, inches and degrees ({_KEY} = 'whole'): {counted}", [warning]


def beyond_part_hint(sp: Any, mode: str, big: float, limit: float, unit: int) -> str:
    """The hint added to the refusal of cutting moves reaching ``big`` mm beyond the
    part (``limit`` mm: the most X may reach): where the program is read as whole units
    and none of its nonzero position words has a decimal point, the increment systems
    (at most two, the coarsest first) that bring the moves within the part.  ``unit`` is
    the unit the furthest move's X was written in (:attr:`ScannedProgram.x_unit`: 0 mm,
    1 inch, each counted in its own increments; 2 both, incremental words of each: no
    single reading, none is given).  A program that writes X in both units says which
    the furthest move's X is in."""
    d = sp.decimals
    if mode != "whole" or d["with"] or not d["without"]:
        return ""
    both = {0, 1} <= set(np.unique(sp.x_unit).tolist())
    if unit not in (0, 1):
        return (f"; no position word of the program has a decimal point, and the furthest "
                f"move's X adds incremental words written in inches and in mm: read in "
                f"least input increments it may lie within the part (set {_KEY})")
    fits = [(s, big / 10 ** _places(s, unit)) for s in INCREMENT_PLACES
            if big / 10 ** _places(s, unit) <= limit][:2]
    if not fits:
        return ""
    reach = ", ".join(f"X = {v:.6g} mm as {s}" for s, v in fits)
    where = (f" (the furthest move's X is written in {('mm, G21 / G71', 'inches, G20 / G70')[unit]}; "
             f"the program switches units)" if both else "")
    return (f"; no position word of the program has a decimal point: read in least input "
            f"increments the moves reach {reach}{where}, within the part (set {_KEY})")


@njit(cache=True, nogil=True)
def undotted_words(have: npt.NDArray[np.bool_], val: npt.NDArray[np.float64],
                   dot: npt.NDArray[np.bool_], undotted: npt.NDArray[np.float64],
                   n_undot: int, line: int, places: int, inch: bool) -> None:
    """The ``n_undot`` nonzero position and angle words of a block written without a
    decimal point (``have``, ``val``, ``dot`` by letter): counted in ``undotted`` (see
    :func:`~render_inspect.io._program_kernel.scan_piece`), the first of the program
    kept, and read in least input increments of ``10**-places`` mm or deg (inches one
    place more) where ``places`` > 0: an exact integer over a power of ten, the same
    double as the number written with its point."""
    undotted[1] += n_undot
    for li in POS_LETTERS:
        if not have[li] or dot[li] or val[li] == 0:
            continue
        deg = li == 2 or li == 7
        if undotted[2] < 0:
            undotted[2] = li
            undotted[3] = val[li]
            undotted[4] = line
            undotted[5] = 2.0 if deg else (1.0 if inch else 0.0)
        if places:
            val[li] = val[li] / _POW10[places + (1 if inch and not deg else 0)]
