"""Domain errors.  Every message names the parameter, the allowed range and the
value received, and says what to do."""

from __future__ import annotations

import math
from typing import Any, Callable

__all__ = ["RenderInspectError", "SceneError", "InputError", "MemoryBudgetError",
           "AccessibilityError", "check_range", "check_positive"]


class RenderInspectError(Exception):
    """Base class of the errors render_inspect raises on purpose."""


class SceneError(RenderInspectError, ValueError):
    """A scene file or override is invalid."""


class InputError(RenderInspectError, ValueError):
    """A function argument or an input file is invalid."""


class MemoryBudgetError(RenderInspectError, MemoryError):
    """A request would not fit into the memory budget."""


class AccessibilityError(RenderInspectError):
    """The tool cannot reach (part of) the design surface."""


def check_range(name: str, value: Any, lo: float | None = None, hi: float | None = None, *,
                lo_open: bool = False, hi_open: bool = False,
                exc: Callable[[str], Exception] = InputError) -> Any:
    """Raise ``exc`` naming ``name``, the allowed range and ``value`` if outside it."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise exc(f"{name} must be a number, got {value!r}") from None
    bad = not math.isfinite(v)
    if lo is not None:
        bad |= v <= lo if lo_open else v < lo
    if hi is not None:
        bad |= v >= hi if hi_open else v > hi
    if bad:
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        rng = f"{'(' if lo_open or lo is None else '['}{lo_s}, {hi_s}{')' if hi_open or hi is None else ']'}"
        raise exc(f"{name} must be in {rng}, got {value!r}")
    return value


def check_positive(name: str, value: Any, exc: Callable[[str], Exception] = InputError) -> Any:
    """Raise ``exc`` naming ``name`` and ``value`` unless ``value`` is a finite number > 0;
    return ``value``."""
    return check_range(name, value, 0.0, None, lo_open=True, exc=exc)
