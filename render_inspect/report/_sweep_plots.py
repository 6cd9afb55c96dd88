"""Sweep figures: a metric against one key with a curve per value of another (Li et al.
2018, Fig. 15 a-c, as curves), and a metric over two keys as a heat map."""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence

import numpy as np

from ._keys import key_label as _label, key_unit
from ._savefig import figure_png

__all__ = ["curves_png", "heatmap_png", "sweep_plot_png"]


def _words(key: str | None) -> str:
    """A key's words without its unit (``process.spindle_rpm`` -> "process spindle speed")."""
    label = _label(str(key))
    return label[:label.rindex(" (")] if label.endswith(")") else label


def _unit(key: str | None) -> str:
    u = key_unit(str(key))
    return f" {u}" if u else ""


def _figure(figsize=(6.0, 4.4)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _png(fig, *, tight_layout: bool = False) -> bytes:
    return figure_png(fig, tight_layout=tight_layout, close=False)


def curves_png(rows: Sequence[Sequence[Any]], *, x: str, y: str = "residual.Sq_nm",
               series: str | None = None,
               study: str | None = None, title: str = "", log: bool = False) -> bytes:
    """``y`` (a metric, dotted path into metrics.json) against the sweep key ``x``, one curve
    per value of the key ``series``, from ``rows`` of (x, [series,] y)
    (:func:`render_inspect.batch.plot_rows`).  Returns PNG bytes."""
    fig = _figure()
    ax = fig.add_subplot(111)
    groups: dict = {}
    for row in rows:
        groups.setdefault(row[1] if series else None, []).append((row[0], row[-1]))
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    for i, (s, pts) in enumerate(sorted(groups.items(), key=lambda t: (t[0] is None, t[0]))):
        pts = sorted(pts)
        col = cmap(i / max(len(groups) - 1, 1))
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", color=col, ms=4,
                label=None if s is None else f"{_words(series)} = {s:g}{_unit(series)}")
    ax.set_xlabel(_label(x))
    ax.set_ylabel(_label(y))
    if log:
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    if series and groups:
        ax.legend(fontsize=8)
    ax.set_title(title or f"{_words(y)} vs {_words(x)}" + (f" (study {study})" if study else ""),
                 fontsize=10)
    if not rows:
        ax.text(0.5, 0.5, f"no finished point has {y}", ha="center", va="center",
                transform=ax.transAxes)
    return _png(fig, tight_layout=True)


def heatmap_png(rows: Sequence[Sequence[Any]], *, x: str, y: str, value: str = "residual.Sq_nm",
                study: str | None = None, title: str = "", log: bool = False) -> bytes:
    """``value`` (a metric) over the plane of the sweep keys ``x`` and ``y``, from ``rows``
    of (x, y, value): cells on the grid of the values met, each annotated with its value
    (the mean where several points share a cell).  Returns PNG bytes."""
    from matplotlib.colors import LogNorm

    fig = _figure((6.2, 4.8))
    ax = fig.add_subplot(111)
    if rows:
        xs = sorted({r[0] for r in rows})
        ys = sorted({r[1] for r in rows})
        grid = np.full((len(ys), len(xs)), np.nan)
        acc: dict = {}
        for a, b, v in rows:
            acc.setdefault((ys.index(b), xs.index(a)), []).append(v)
        for (i, j), vs in acc.items():
            grid[i, j] = float(np.mean(vs))
        finite = grid[np.isfinite(grid)]
        norm = LogNorm(vmin=finite[finite > 0].min(), vmax=finite.max()) \
            if log and (finite > 0).any() else None
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis", norm=norm,
                       interpolation="nearest")
        ax.set_xticks(range(len(xs)), [f"{v:g}" for v in xs])
        ax.set_yticks(range(len(ys)), [f"{v:g}" for v in ys])
        if grid.size <= 400:
            for (i, j), vs in acc.items():
                shade = im.norm(np.mean(vs))  # light text on the dark end of viridis
                ax.text(j, i, f"{np.mean(vs):.3g}", ha="center", va="center", fontsize=7,
                        color="w" if np.ma.filled(shade, 0.0) < 0.6 else "k")
        cb = fig.colorbar(im, ax=ax)
        cb.set_label(_label(value))
    else:
        ax.text(0.5, 0.5, f"no finished point has {value}", ha="center", va="center",
                transform=ax.transAxes)
    ax.set_xlabel(_label(x))
    ax.set_ylabel(_label(y))
    ax.set_title(title or f"{_words(value)} over {_words(x)} and {_words(y)}"
                 + (f" (study {study})" if study else ""), fontsize=10)
    return _png(fig, tight_layout=True)


def sweep_plot_png(plot: Any, rows: Sequence[Sequence[Any]]) -> bytes:
    """The PNG of one ``[[plot]]`` entry of a sweep file (``plot``: its ``kind``, ``x``,
    ``y``, ``series``, ``value``, ``study``, ``title``, ``log``) from its ``rows``."""
    if plot.kind == "curves":
        return curves_png(rows, x=plot.x, y=plot.y, series=plot.series, study=plot.study,
                          title=plot.title, log=plot.log)
    return heatmap_png(rows, x=plot.x, y=plot.y, value=plot.value, study=plot.study,
                       title=plot.title, log=plot.log)
