"""Saving a matplotlib figure as PNG bytes with less work, the bytes ``savefig`` writes.

Two things make a save of the report's figures slow, and both are repeated work:

* a figure with a layout engine (constrained layout, or the engine that does nothing
  which ``tight_layout`` leaves behind) is drawn twice by ``savefig``: once with nothing
  rendered, only to run the layout, then for real.  :func:`lay_out_once` runs the
  layout itself and fixes its result, so the figure is drawn once;
* laying a figure out measures every axes' tick labels, and each measurement asks the
  axis for its ticks again (the tick labels, the axis label, each spine: about five
  times per axis per pass), running its tick locator and formatter each time.
  :func:`figure_png` remembers an axis' last ticks while nothing they depend on has
  changed (the view limits, the axes' place on the figure, the locators and
  formatters), on the figure's own axes only and only while it is being saved.

The PNG is compressed at zlib level :data:`PNG_COMPRESS_LEVEL` (3), which costs about half
of savefig's default level 6 for files a few per cent larger: the same pixels.
"""

from __future__ import annotations

import contextlib
import functools
import io
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..io import atomic_write_bytes

__all__ = ["figure_png", "save_png", "lay_out_once", "quick_ticks", "PNG_COMPRESS_LEVEL"]


@functools.cache
def _root_arg() -> bool:
    """Whether this matplotlib's ``get_figure`` takes ``root`` (3.10 on)."""
    import inspect

    from matplotlib.artist import Artist

    return "root" in inspect.signature(Artist.get_figure).parameters


def lay_out_once(fig: Any) -> None:
    """Run ``fig``'s layout engine (constrained layout) now and then fix the result: the
    figure is saved as it would have been, but ``savefig`` no longer draws it a first
    time (every artist, with nothing rendered) only to lay it out."""
    import matplotlib

    engine = fig.get_layout_engine()
    if engine is None or not fig.axes:
        return
    if matplotlib.rcParams["figure.autolayout"] or matplotlib.rcParams["figure.constrained_layout.use"]:
        return  # a figure without an engine gets one again: savefig lays it out as before
    try:
        engine.execute(fig)
    except ValueError:  # as a draw does: the layout is left as it is
        pass
    fig.set_layout_engine(None)


def _axis_state(axis: Any) -> tuple:
    """What an axis' ticks depend on while a figure is drawn: its view limits, its axes'
    place in the figure (pixels), the figure's dpi, and its tickers (with the view and
    place of the axis each locator and formatter reads, which for a shared axis may be
    another one)."""
    fig = axis.axes.get_figure(root=True) if _root_arg() else axis.axes.figure
    parts: list = [tuple(axis.get_view_interval()), axis.axes.transAxes.get_matrix().tobytes(),
                   fig.dpi]
    for ticker in (axis.major, axis.minor):
        parts += [id(ticker.locator), id(ticker.formatter)]
        for user in (ticker.locator, ticker.formatter):
            other = getattr(user, "axis", None)
            if other is not None and other is not axis:
                parts += [id(other), tuple(other.get_view_interval()),
                          other.axes.transAxes.get_matrix().tobytes()]
    return tuple(parts)


def _remember_ticks(axis: Any, owners: dict) -> None:
    """Give ``axis`` (this instance only) an ``_update_ticks`` that returns its last
    ticks when nothing they depend on changed since they were set, and the formatters
    (which keep the last ticks' offset and order of magnitude, and which shared axes
    share) were last used by this axis with the same state; and a
    ``_get_ticklabel_bboxes`` that returns the last boxes of the same ticks' labels,
    measured with the same renderer."""
    update, boxes = axis._update_ticks, axis._get_ticklabel_bboxes
    last: list = [None, None]
    last_boxes: list = [None, None]

    def _update_ticks() -> list:
        try:
            key = _axis_state(axis)
        except Exception:  # an axis of an unusual kind: no shortcut
            key = None
        fmts = (id(axis.major.formatter), id(axis.minor.formatter))
        if (key is not None and key == last[0]
                and all(owners.get(f) == (id(axis), key) for f in fmts)):
            return list(last[1])
        ticks = update()
        last[0], last[1] = key, list(ticks)
        last_boxes[0] = None
        for f in fmts:
            owners[f] = (id(axis), key)
        return ticks

    def _get_ticklabel_bboxes(ticks: list, renderer: Any = None) -> tuple:
        key = (last[0], id(renderer), [id(t) for t in ticks])
        if last[0] is None or key != last_boxes[0]:
            last_boxes[0], last_boxes[1] = key, boxes(ticks, renderer)
        b1, b2 = last_boxes[1]
        return list(b1), list(b2)

    axis._update_ticks = _update_ticks
    axis._get_ticklabel_bboxes = _get_ticklabel_bboxes


@contextlib.contextmanager
def quick_ticks(fig: Any) -> Iterator[None]:
    """While inside: the axes of ``fig`` compute their ticks once per state
    (see the module notes); on leaving they are as before."""
    axes = [axis for ax in fig.get_axes() for axis in getattr(ax, "_axis_map", {}).values()]
    if not all(hasattr(axis, "_update_ticks") and hasattr(axis, "_get_ticklabel_bboxes")
               for axis in axes):
        axes = []  # a matplotlib without these methods: a plain save
    owners: dict = {}
    for axis in axes:
        _remember_ticks(axis, owners)
    try:
        yield
    finally:
        for axis in axes:
            axis.__dict__.pop("_update_ticks", None)
            axis.__dict__.pop("_get_ticklabel_bboxes", None)


#: zlib level of the figures' PNG files: the quick plots' level; about half the time of
#: savefig's default (6) for files 1-8 % larger, the same pixels
PNG_COMPRESS_LEVEL = 3


def figure_png(fig: Any, *, dpi: float | None = None, tight_layout: bool = False,
               close: bool = True) -> bytes:
    """PNG bytes of ``fig`` as ``fig.savefig(buf, format="png", dpi=dpi,
    pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})`` writes them (``dpi=None``:
    savefig's default), after ``fig.tight_layout()`` when ``tight_layout``; the figure
    is closed (``plt.close``) when ``close``."""
    buf = io.BytesIO()
    try:
        with quick_ticks(fig):
            if tight_layout:
                fig.tight_layout()
            lay_out_once(fig)
            kw = {} if dpi is None else {"dpi": dpi}
            fig.savefig(buf, format="png", pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL}, **kw)
    finally:
        if close:
            import matplotlib.pyplot as plt

            plt.close(fig)
    return buf.getvalue()


def save_png(fig: Any, png_path: str | Path, *, tight_layout: bool = False) -> Path:
    """Write ``fig`` at 110 dpi into ``png_path`` atomically (:func:`figure_png`; after
    ``fig.tight_layout()`` when ``tight_layout``); the figure is closed."""
    return atomic_write_bytes(png_path, figure_png(fig, dpi=110, tight_layout=tight_layout))
