"""Numbers for people: units, sensible significant figures, no false precision."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["fmt_number", "fmt_quantity", "nice_length", "scale_bar_length", "SCALE_BAR_FRACTION"]


def fmt_number(v: Any, *, sig: int = 3, resolution: float | None = None) -> str:
    """A number with ``sig`` significant figures (at most), without exponent notation
    between 1e-4 and 1e6; magnitudes below ``resolution`` are written ``0`` (a value
    of -2.7e-4 nm where the computation resolves 0.01 nm is zero, not a measurement).

    Integers are written in full; booleans as yes/no; None and NaN as ``n/a``.
    """
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}" if abs(v) >= 10000 else str(v)
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    if math.isnan(x):
        return "n/a"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    if x == 0 or (resolution is not None and abs(x) < resolution):
        return "0"
    a = abs(x)
    if a >= 1e6 or a < 1e-4:
        return f"{x:.{sig - 1}e}"
    digits = sig - 1 - int(math.floor(math.log10(a)))
    if resolution is not None:
        digits = min(digits, max(0, -int(math.floor(math.log10(resolution)))))
    digits = max(digits, 0)
    s = f"{x:.{digits}f}"
    if s.lstrip("-") in ("0", "0." + "0" * digits):
        return "0"
    return s


#: display resolution per unit: finer digits are noise of the computation
_RESOLUTION = {"nm": 0.01, "um": 1e-4, "mm": 1e-7, "urad": 0.01, "mrad": 1e-5, "rad": 1e-8,
               "deg": 1e-6, "%": 1e-3, "s": 1e-4, "Hz": 1e-3, "mm/s": 1e-9,
               "mm/s^2": 1e-6}


#: a length this large is written in the next unit (12445 nm -> 12.4 um)
_PROMOTE = {"nm": ("um", 1e-3), "um": ("mm", 1e-3)}


def fmt_quantity(v: Any, unit: str = "", *, sig: int = 3) -> str:
    """``fmt_number`` with the unit appended and the unit's display resolution (0.01 nm,
    0.1 nm-equivalent in um, ...); lengths of 10,000 nm or um and more are written in the
    next unit."""
    if unit in _PROMOTE and isinstance(v, (int, float)) and not isinstance(v, bool) \
            and abs(v) >= 1e4:
        unit, scale = _PROMOTE[unit]
        return fmt_quantity(v * scale, unit, sig=sig)
    s = fmt_number(v, sig=sig, resolution=_RESOLUTION.get(unit))
    if not unit or s == "n/a":
        return s
    return f"{s} {unit}"


def nice_length(target: float) -> float:
    """The 1-2-5 step at or below ``target`` (> 0)."""
    if not target > 0:
        return 1.0
    e = 10 ** math.floor(math.log10(target))
    for m in (5, 2, 1):
        if m * e <= target * (1 + 1e-9):
            return m * e
    return e


#: a scale bar is the 1-2-5 length at or below this fraction of the width it stands in
SCALE_BAR_FRACTION = 0.25


def scale_bar_length(width: float) -> float:
    """The scale bar of a picture ``width`` wide (any length unit): the 1-2-5 step at or
    below :data:`SCALE_BAR_FRACTION` of the width rounded to two significant figures, so
    that pictures of nearly the same width (a window and its pixel-edge extent, 0.225
    and 0.2275 mm) carry the same bar."""
    if not width > 0:
        return 1.0
    e = 10 ** (math.floor(math.log10(width)) - 1)
    return nice_length(SCALE_BAR_FRACTION * round(width / e) * e)
