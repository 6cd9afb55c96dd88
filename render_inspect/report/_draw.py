"""Figures described by data: the stages (a process's plan and cut, an instrument's
outputs) say what to draw as a *figure spec*, a dict whose ``kind`` names the figure,
and :func:`draw_figure` draws it into a PNG file.

Kinds: ``"axes"`` (the axes of machine programs that move, ``columns`` of (label,
program, data); :func:`~render_inspect.report.kinematics_png`), ``"kinematics"`` (X of a
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
from ._following import plot_following_error, plot_following_error_map
from ._kinematics import kinematics_png, plot_kinematics
from ._maps import save_map_png
from ._program import plot_feed_per_rev

__all__ = ["draw_figure", "FIGURE_KINDS", "figure_kinds", "preload_drawing", "uses_matplotlib"]

#: the figure kinds :func:`draw_figure` draws itself (more are registered:
#: :func:`figure_kinds`)
FIGURE_KINDS = ("axes", "kinematics", "following_error", "following_error_map", "map",
                "feed_per_rev")


def figure_kinds() -> tuple[str, ...]:
    """Every figure kind :func:`draw_figure` draws: the built-in ones and those registered
    with :func:`~render_inspect.report.register_figure`."""
    return FIGURE_KINDS + tuple(k for k in registered_figures() if k not in FIGURE_KINDS)


#: the figure kinds :func:`draw_figure` draws with Pillow alone (no matplotlib to import)
PILLOW_KINDS = ("axes", "following_error", "following_error_map")


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


def draw_figure(spec: dict, png: str | Path) -> Path:
    """Draw the figure ``spec`` into the PNG file ``png`` (written atomically)."""
    kind: Any = spec.get("kind")
    if kind == "axes":
        return kinematics_png(spec["columns"], png, axes=spec.get("axes"),
                              title=spec.get("title", ""))
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
