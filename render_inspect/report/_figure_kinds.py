"""The registry of figure kinds beyond the built-in ones (:data:`FIGURE_KINDS` of
:mod:`._draw`): a figure spec's ``kind`` -> the function that draws it.

A module of this package registers ``draw(spec, png) -> Path`` with
:func:`register_figure`; the package imports every such module on start, so a new figure
kind is one new file, and a stage (a process's hooks, an instrument's ``write``) asks for
it by returning a spec of that kind.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable, TypeVar

__all__ = ["register_figure", "registered_figures"]

_DRAWERS: dict[str, Callable] = {}

#: a drawer ``draw(spec, png) -> Path`` (returned as it is)
_Draw = TypeVar("_Draw", bound=Callable[..., Path])


def register_figure(kind: str) -> Callable[[_Draw], _Draw]:
    """Decorator: register ``draw(spec, png) -> Path`` as the drawer of the figure specs
    whose ``kind`` is ``kind`` (registering a kind again replaces its drawer)."""
    if not isinstance(kind, str) or not kind.isidentifier():
        raise ValueError(f"figure kind must be an identifier, received {kind!r}")

    def deco(draw: _Draw) -> _Draw:
        _DRAWERS[kind] = draw
        return draw
    return deco


def registered_figures() -> dict[str, Callable]:
    """Registered figure kind -> its drawer (a copy)."""
    return dict(_DRAWERS)
