"""The part and the machine a written program is checked against (the verifier's
:class:`~render_inspect.toolpath.PartModel` and
:class:`~render_inspect.toolpath.MachineLimits`), built from the design and the
``machine.preset``, never from the program: the design's true highest point (an
interval bound where the design has one, a dense evaluation with a slope bound
otherwise: :func:`~render_inspect.design.max_height`), the machine's largest feed and
travel (:func:`~render_inspect.machining.program_limits_of`)."""

from __future__ import annotations

from typing import Any

from ..design import Surface, height_interval, max_height
from ..machining import program_limits_of
from ..toolpath import MachineLimits, PartModel

__all__ = ["design_part", "machine_limits"]


def design_part(surface: Surface, outline: tuple, **kw: Any) -> PartModel:
    """A :class:`PartModel` of ``surface`` over ``outline`` with the design's true
    highest point (``top``) and, where the design has one, its interval bound."""
    b = max_height(surface, outline)
    bound = None
    if height_interval(surface, 0.0, 0.0, 0.0, 0.0) is not None:
        def bound(x0, y0, x1, y1):
            return height_interval(surface, x0, y0, x1, y1)[1]
    return PartModel(surface.height, outline, top=None if b is None else b.high, bound=bound,
                     **kw)


def machine_limits(preset: str, *, also: str = "", **kw: Any) -> MachineLimits:
    """The :class:`MachineLimits` of ``machine.preset`` (its largest feed and travel)
    with ``kw`` (velocities, spindle speed, the plunge feed the physics allows); ``also``
    names further sources for messages."""
    m = program_limits_of(preset)
    kw.setdefault("feed_mm_per_min", m.feed_mm_per_min)
    return MachineLimits(source=f"machine.preset {preset!r} ({m.source}){also}",
                         travel=m.travel(), **kw)
