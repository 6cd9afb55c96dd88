"""Following-error figures: the error of each axis against time, and the X and Z errors
mapped onto the part (the error of the pass that cut each point)."""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..io import atomic_write_bytes
from ._kinematics import _envelope
from ._savefig import figure_png

__all__ = ["plot_following_error", "plot_following_error_map"]


#: inches: the figure's edge, a tick and its pad, an axis label's pad
_EDGE, _TICK, _PAD = 0.08, 7.5 / 72, 5.0 / 72


def _text_size(fig: Any, text: str, size: float | str) -> tuple[float, float]:
    """Width and height (inches) of ``text`` at font ``size`` as Agg draws it."""
    from matplotlib.font_manager import FontProperties

    if not text:
        return 0.0, 0.0
    r = fig.canvas.get_renderer()
    w, h, _ = r.get_text_width_height_descent(text, FontProperties(size=size),
                                              ismath="$" in text)
    return w / fig.dpi, h / fig.dpi


def _tick_labels(axis: Any) -> list[str]:
    """The labels of the major ticks ``axis`` will draw in its current view."""
    lo, hi = sorted(axis.get_view_interval())
    slack = 1e-9 * (hi - lo)  # not a unit conversion: a relative slack
    locs = [v for v in axis.get_major_locator()() if lo - slack <= v <= hi + slack]
    return list(axis.get_major_formatter().format_ticks(locs))


def _widest(fig: Any, axis: Any, size: float | str) -> tuple[float, float]:
    """The largest width and height (inches) of ``axis``'s tick labels."""
    sizes = [_text_size(fig, t, size) for t in _tick_labels(axis)] or [(0.0, 0.0)]
    return max(w for w, _ in sizes), max(h for _, h in sizes)


def _fixed_layout(fig: Any, *, left: float, right: float, top: float, bottom: float, rows: int = 1,
                  row_gap: float = 0.0, wspace: float | None = None) -> None:
    """Margins and the gap between rows in inches, set directly (``tight_layout`` measures
    every tick label of every axes again, about half of these figures' drawing time)."""
    w, h = fig.get_size_inches()
    axes_h = (h - top - bottom - (rows - 1) * row_gap) / rows
    fig.subplots_adjust(left=left / w, right=1.0 - right / w, top=1.0 - top / h, bottom=bottom / h,
                        hspace=row_gap / axes_h if rows > 1 else None, wspace=wspace)


def _save(fig: Any, png_path: str | Path, *, tight_layout: bool = False) -> Path:
    """Write ``fig`` at 110 dpi (after ``fig.tight_layout()`` when ``tight_layout``)."""
    return atomic_write_bytes(png_path, figure_png(fig, dpi=110, tight_layout=tight_layout))


def plot_following_error(t: np.ndarray, errors: dict, png_path: str | Path, *,
                         title: str | None = None,
                         stats: dict | None = None) -> Path:
    """Following error (command - followed) of each axis against time.

    Parameters
    ----------
    t : (m,) array, s
    errors : dict
        ``x``, ``z``, ``fts`` (mm) and ``c`` (rad) arrays at ``t``; all-zero axes are left
        out.
    png_path : str or Path
        Written atomically.
    title : str, optional
    stats : dict, optional
        :func:`~render_inspect.machining.following_error_stats`, written into the titles.

    Returns
    -------
    Path.  Curves are per-bin min/max envelopes, so single-tick spikes stay visible.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    t = np.asarray(t, dtype=np.float64)
    rows = [(k, lab, scale) for k, lab, scale in
            (("x", "X (nm)", 1e6), ("z", "Z slide (nm)", 1e6), ("fts", "FTS (nm)", 1e6),
             ("c", "C (urad)", 1e6))
            if k in errors and np.any(np.asarray(errors[k]) != 0)]
    if not rows:
        rows = [("x", "X (nm)", 1e6)]
    fig, axes = plt.subplots(len(rows), 1, figsize=(8.0, 2.1 * len(rows) + 0.8), sharex=True,
                             squeeze=False)
    for ax, (k, lab, scale) in zip(axes[:, 0], rows):
        y = np.asarray(errors.get(k, np.zeros_like(t)), dtype=np.float64) * scale
        xm, lo, hi = _envelope(t, y)
        ax.plot(xm, lo, lw=0.6, color="C0")
        if xm.size != t.size:
            ax.plot(xm, hi, lw=0.6, color="C0")
            ax.fill_between(xm, lo, hi, lw=0, color="C0", alpha=0.5)
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
        if stats:
            unit = "urad" if k == "c" else "nm"
            r, m = stats.get(f"{k}_rms_{unit}"), stats.get(f"{k}_max_{unit}")
            if r is not None:
                ax.set_title(f"rms {r:.3g} {unit}, max {m:.3g} {unit}", fontsize=8, loc="right")
    axes[-1, 0].set_xlabel("time (s)")
    suptitle = title or "following error (command - followed)"
    fig.suptitle(suptitle)
    # the margins from the labels' own sizes (fonts 10, titles 8, suptitle 12 points)
    lab_h = _text_size(fig, "X (nm)", 10)[1]
    y_w = max(_widest(fig, ax.yaxis, 10)[0] for ax in axes[:, 0])
    x_w, x_h = _widest(fig, axes[-1, 0].xaxis, 10)
    sup_h = _text_size(fig, suptitle, 12)[1]
    ttl_h = _text_size(fig, "rms 1 nm", 8)[1] + _PAD if stats else 0.0
    _fixed_layout(fig, left=_EDGE + lab_h + _PAD + y_w + _TICK,
                  right=_EDGE + x_w / 2, top=2 * _EDGE + sup_h + _PAD + ttl_h,
                  bottom=_EDGE + lab_h + _PAD + x_h + _TICK, rows=len(rows),
                  row_gap=_TICK + 2 * _PAD + ttl_h)
    return _save(fig, png_path)


def plot_following_error_map(x_nm: np.ndarray, z_nm: np.ndarray, extent: Sequence[float],
                             png_path: str | Path, *, title: str | None = None) -> Path:
    """The X and Z following errors (nm) of the pass that cut each point of the part.

    Parameters
    ----------
    x_nm, z_nm : (ny, nx) arrays, nm (NaN = not cut)
    extent : (x0, x1, y0, y1), mm
    png_path : str or Path
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.4), squeeze=False)
    bars = []
    for ax, (m, lab) in zip(axes[0], ((x_nm, "X following error (nm)"),
                                      (z_nm, "Z following error (nm)"))):
        m = np.asarray(m, dtype=np.float64)
        lim = float(np.nanmax(np.abs(m))) if np.isfinite(m).any() else 1.0
        im = ax.imshow(m, origin="lower", extent=extent, cmap="RdBu_r", vmin=-lim or -1,
                       vmax=lim or 1)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_title(lab, fontsize=9)
        bars.append(fig.colorbar(im, ax=ax, shrink=0.85))
    if title:
        fig.suptitle(title)
    # the margins from the labels' own sizes (fonts 10, titles 9, suptitle 12 points)
    lab_h = _text_size(fig, "y (mm)", 10)[1]
    y_w = [_widest(fig, ax.yaxis, 10)[0] for ax in axes[0]]
    c_w = [_widest(fig, cb.ax.yaxis, 10)[0] for cb in bars]
    x_w, x_h = _widest(fig, axes[0, 0].xaxis, 10)
    top = _EDGE + _text_size(fig, "X following error (nm)", 9)[1] + _PAD
    if title:
        top += _text_size(fig, title, 12)[1] + _EDGE
    cell = (fig.get_size_inches()[0] - 2 * _EDGE - lab_h - _PAD - y_w[0] - _TICK - c_w[1] - _TICK) / 2
    gap = c_w[0] + _TICK + _EDGE + lab_h + _PAD + y_w[1] + _TICK
    _fixed_layout(fig, left=_EDGE + lab_h + _PAD + y_w[0] + _TICK, right=_EDGE + c_w[1] + _TICK,
                  top=top, bottom=_EDGE + lab_h + _PAD + x_h + _TICK,
                  wspace=gap / max(cell - gap / 2, 0.1))
    return _save(fig, png_path)
