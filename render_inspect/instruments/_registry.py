"""The registry of virtual instruments: each is one module of this package with its scene
schema class, found under ``[render.<name>]`` in a scene file (e.g.
``[render.interferometer]``), and the hooks the pipeline calls to image a height map
with it (``render --kind <name>`` and ``compare``).

An instrument is registered with :func:`register_instrument`:

``render(heightmap, cfg, *, surface, seed) -> result``
    Image the ``surface`` layer (``"machined"`` / ``"design"``) of a
    :class:`~render_inspect.core.HeightMap` with the settings ``cfg`` (its section).
``write(out, result, *, scene) -> (summary, figures)``
    Write the result's files into the folder ``out`` and return its summary (for
    ``render_metrics.json``) and the figures to draw (file name -> figure spec,
    :func:`render_inspect.report.draw_figure`).
``field(grid, cfg) -> dict``
    The part of the map it looks at (``window`` = (x0, y0, x1, y1), mm) and the
    ``settings`` that image that same field from a crop of the map, so that a map too
    large for memory is read only there.
``memory(grid, cfg, *, slope) -> (bytes, what, drivers)``
    Bytes it needs at its peak, checked against the budget before anything runs.
``frames``
    True for an instrument whose result is a stack of interferometer frames
    (:class:`~render_inspect.core.Frames`) that :func:`render_inspect.metrology.measure_frames`
    turns into a measured height: ``compare`` measures through it.

An instrument without ``render`` is a settings section only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    from ..core.section import Section

__all__ = ["InstrumentType", "instrument_types", "register_instrument", "renderable_instruments",
           "height_instrument"]


@dataclass(frozen=True)
class InstrumentType:
    """A registered instrument: its ``[render.<name>]`` section name, schema class and
    hooks (see the module docstring)."""

    name: str
    config: type[Section]
    render: Callable | None = None
    write: Callable | None = None
    field: Callable | None = None
    memory: Callable | None = None
    frames: bool = False


_INSTRUMENTS: dict[str, InstrumentType] = {}


def register_instrument(name: str, config: type[Section], *, render: Callable | None = None,
                        write: Callable | None = None, field: Callable | None = None,
                        memory: Callable | None = None, frames: bool = False) -> InstrumentType:
    """Register an instrument whose settings are the scene section ``[render.<name>]``
    (registering a name again replaces its entry)."""
    if not name.isidentifier():
        raise ValueError(f"instrument name must be an identifier, received {name!r}")
    if (render is None) != (write is None):
        raise ValueError(f"instrument {name!r}: give both render and write, or neither")
    entry = InstrumentType(name, config, render, write, field, memory, frames)
    _INSTRUMENTS[name] = entry
    return entry


def instrument_types() -> dict[str, InstrumentType]:
    """Section name -> :class:`InstrumentType`."""
    return dict(_INSTRUMENTS)


def renderable_instruments() -> dict[str, InstrumentType]:
    """The instruments ``render --kind`` can image with (those with a ``render`` hook)."""
    return {k: v for k, v in sorted(_INSTRUMENTS.items()) if v.render is not None}


def height_instrument() -> InstrumentType:
    """The instrument ``compare`` measures heights through: the registered one whose
    result is interferometer frames."""
    for entry in _INSTRUMENTS.values():
        if entry.frames and entry.render is not None:
            return entry
    raise LookupError("no registered instrument records interferometer frames")
