"""Seed-004-style plots of a turning path's axis motion (Figs. 8-9): X against C, the X
velocity and acceleration against time, one column per path."""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from ..io import atomic_write_bytes
from ..io._quickplot import panels_png
from ..toolpath import axis_derivatives

__all__ = ["plot_kinematics", "kinematics_png"]


def _envelope(x: np.ndarray, y: np.ndarray, bins: int = 1500):
    """Per-bin min/max of y (bins along x): plots of millions of points that keep spikes."""
    n = x.size
    if n <= 2 * bins:
        return x, y, y
    edges = np.linspace(0, n, bins + 1).astype(np.int64)
    starts = edges[:-1]
    xm = x[(starts + edges[1:]) // 2]
    return xm, np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)


def plot_kinematics(path, png_path, *, reference=None, labels=("RCSE", "conventional"),
                    title: str | None = None) -> Path:
    """Plot X against C and the X velocity and acceleration against time (seed 004
    Figs. 8-9), one column per path.

    Parameters
    ----------
    path : ToolPath
    png_path : str or Path
        Written atomically.
    reference : ToolPath, optional
        A second path (e.g. the conventional one) drawn in a second column.
    labels : (str, str)
        Column titles for ``path`` and ``reference``.
    title : str, optional

    Returns
    -------
    Path of the PNG.  Every curve is drawn as a per-bin min/max envelope, so spikes of
    single points stay visible on paths of millions of points.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    paths = [path] + ([reference] if reference is not None else [])
    fig, axes = plt.subplots(3, len(paths), figsize=(5.2 * len(paths), 8.4), squeeze=False,
                             sharey="row")
    for col, (p, lab) in enumerate(zip(paths, labels)):
        t = np.asarray(p.t, dtype=np.float64)
        vx, ax, _ = axis_derivatives(t, p.rho)
        c_rev = np.asarray(p.theta, dtype=np.float64) / (2 * math.pi)
        rows = [(c_rev, np.asarray(p.rho), "C (revolutions, cumulative)", "X = radius (mm)"),
                (t, vx, "time (s)", "X velocity (mm/s)"),
                (t, ax, "time (s)", "X acceleration (mm/s$^2$)")]
        for r, (xs, ys, xl, yl) in enumerate(rows):
            axx = axes[r, col]
            xm, lo, hi = _envelope(xs, ys)
            axx.plot(xm, lo, lw=0.7, color="C0")
            if xm.size != xs.size:
                axx.plot(xm, hi, lw=0.7, color="C0")
                axx.fill_between(xm, lo, hi, lw=0, color="C0", alpha=0.5)
            axx.set_xlabel(xl)
            axx.set_ylabel(yl)
            axx.grid(alpha=0.3)
        axes[0, col].set_title(f"{lab}\nmax |vX| {np.max(np.abs(vx)):.3g} mm/s, "
                               f"max |aX| {np.max(np.abs(ax)):.3g} mm/s$^2$", fontsize=9)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return atomic_write_bytes(png_path, buf.getvalue())


def kinematics_png(path, png_path, *, title: str = "") -> Path:
    """X against C and the X velocity and acceleration against time of one path, drawn
    with Pillow (``render_inspect.io._quickplot``: tens of milliseconds, where the
    matplotlib figure of :func:`plot_kinematics` takes about a second with its import).

    The derivatives are taken on the whole path (decimating first would smooth away the
    single-point spikes a machine limit cares about); only the drawing is decimated, to
    per-bin minimum / maximum envelopes (1500 bins)."""
    t = np.asarray(path.t, dtype=np.float64)
    vx, ax, _ = axis_derivatives(t, path.rho)
    c_rev = np.asarray(path.theta, dtype=np.float64) / (2 * math.pi)
    panels = []
    for xs, ys, xl, yl, tt in ((c_rev, np.asarray(path.rho), "C (revolutions, cumulative)", "X = radius (mm)", ""),
                               (t, vx, "time (s)", "X velocity (mm/s)", f"max |vX| {np.max(np.abs(vx)):.3g} mm/s"),
                               (t, ax, "time (s)", "X acceleration (mm/s^2)",
                                f"max |aX| {np.max(np.abs(ax)):.3g} mm/s^2")):
        xm, lo, hi = _envelope(xs, ys)
        panels.append({"x": xm, "lo": lo, "hi": hi, "xlabel": xl, "ylabel": yl, "title": tt})
    return panels_png(png_path, panels, title=title)
