"""Figures described by data: the stages (a process's plan and cut, an instrument's
outputs) say what to draw as a *figure spec*, a dict whose ``kind`` names the figure,
and :func:`draw_figure` draws it into a PNG file.

Kinds: ``"axes"`` (the axes of machine programs that move, ``columns`` of (label,
program, data); :func:`~render_inspect.report.kinematics_png`), ``"panels"`` (that
figure's or the following error's panels, reduced to what is drawn: :func:`drawn_data`), ``"kinematics"`` (X of a
path against a reference; :func:`~render_inspect.report.plot_kinematics`),
``"following_error"`` and ``"following_error_map"`` (a machine's following error;
:mod:`render_inspect.report._following`) and ``"map"`` (one false-colour map;
:func:`~render_inspect.report.save_map_png`) and ``"feed_per_rev"`` (the feed per
revolution of a program against the radius).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ._figure_kinds import registered_figures
from ._following import (FOLLOWING_ERROR_PANEL_HEIGHT, FOLLOWING_ERROR_TITLE, following_error_panels,
                         plot_following_error, plot_following_error_map)
from ._kinematics import kinematics_panels, kinematics_png, plot_kinematics
from ._maps import save_map_png
from ._program import plot_feed_per_rev
from ._quickplot import panels_png

__all__ = ["draw_figure", "drawn_data", "FIGURE_KINDS", "figure_kinds", "preload_drawing", "uses_matplotlib"]

#: the figure kinds :func:`draw_figure` draws itself (more are registered:
#: :func:`figure_kinds`)
FIGURE_KINDS = ("axes", "panels", "kinematics", "following_error", "following_error_map", "map",
                "feed_per_rev")


def figure_kinds() -> tuple[str, ...]:
    """Every figure kind :func:`draw_figure` draws: the built-in ones and those registered
    with :func:`~render_inspect.report.register_figure`."""
    return FIGURE_KINDS + tuple(k for k in registered_figures() if k not in FIGURE_KINDS)


#: the figure kinds :func:`draw_figure` draws with Pillow alone (no matplotlib to import)
PILLOW_KINDS = ("axes", "panels", "following_error", "following_error_map")


def uses_matplotlib(spec: dict) -> bool:
    """Whether drawing the figure ``spec`` imports matplotlib (a registered kind is taken
    to: it may)."""
    return spec.get("kind") not in PILLOW_KINDS


def preload_drawing() -> None:
    """Import what drawing a figure needs (matplotlib with its Agg backend, pyplot and the
    font list: about 0.35 s), so that a command can do it in a thread while it computes
    what the figures show.  Drawing does the same imports itself when they are not done."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot  # noqa: F401
    from matplotlib.font_manager import fontManager  # noqa: F401  (reads the font list)


def drawn_data(spec: dict) -> dict:
    """``spec`` with its data reduced to what the drawing reads, for a figure drawn by
    another process (the same PNG, fewer bytes to copy there): an ``"axes"`` figure becomes
    its ``"panels"`` (per-bin envelopes of the axes' motion: a hundred kilobytes instead of
    the programs and their derivatives, 45 MB for a 2 x 2 mm window of the shipped grid
    scene), and so does a ``"following_error"`` figure (17 MB there); other kinds are
    returned as they are."""
    if spec.get("kind") == "axes":
        return {"kind": "panels", "panels": kinematics_panels(spec["columns"], spec.get("axes")),
                "title": spec.get("title", "")}
    if spec.get("kind") == "following_error":
        return {"kind": "panels", "panels": following_error_panels(spec["t"], spec["errors"], spec.get("stats")),
                "title": spec.get("title") or FOLLOWING_ERROR_TITLE, "height": FOLLOWING_ERROR_PANEL_HEIGHT}
    return spec


def draw_figure(spec: dict, png: str | Path) -> Path:
    """Draw the figure ``spec`` into the PNG file ``png`` (written atomically)."""
    kind: Any = spec.get("kind")
    if kind == "axes":
        return kinematics_png(spec["columns"], png, axes=spec.get("axes"),
                              title=spec.get("title", ""))
    if kind == "panels":
        return panels_png(png, spec["panels"], title=spec.get("title", ""), **(
            {"height": spec["height"]} if "height" in spec else {}))
    if kind == "kinematics":
        return plot_kinematics(spec["path"], png, reference=spec.get("reference"),
                               labels=spec.get("labels", ("", "")), title=spec.get("title"))
    if kind == "following_error":
        return plot_following_error(spec["t"], spec["errors"], png, title=spec.get("title"),
                                    stats=spec.get("stats"))
    if kind == "following_error_map":
        return plot_following_error_map(spec["x_nm"], spec["z_nm"], spec["extent"], png,
                                        title=spec.get("title"))
    if kind == "map":
        return save_map_png(png, spec["data"], extent=spec.get("extent"),
                            title=spec.get("title", ""), label=spec.get("label", ""),
                            cmap=spec.get("cmap", "viridis"),
                            symmetric=spec.get("symmetric", False))
    if kind == "feed_per_rev":
        return plot_feed_per_rev(spec["radius_mm"], spec["feed_um"], png,
                                 title=spec.get("title", ""))
    draw = registered_figures().get(kind)
    if draw is not None:
        return draw(spec, png)
    raise ValueError(f"unknown figure kind {kind!r}; known: {', '.join(figure_kinds())}")
