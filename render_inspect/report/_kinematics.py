"""Plots of a turning path's axis motion: the axes that move (Z and the FTS for slow
and fast tool servo turning, X for RCSE against the conventional path, the RCSE
study's Figs. 8-9), position, velocity and acceleration against time, one column per path."""

from __future__ import annotations

from collections.abc import Sequence
import math
from pathlib import Path

import numpy as np

from ..core.units import MM_TO_UM
from ..io import atomic_write_bytes
from ._quickplot import panels_png
from ._savefig import figure_png
from ..toolpath import axes_derivatives, axis_derivatives, turning_axes
from ..core.toolpath import ToolPath, part_angle

__all__ = ["plot_kinematics", "axis_motion_figure", "kinematics_png", "kinematics_panels", "moving_axes",
           "turning_axes"]

#: an axis whose velocity varies by less than this fraction of its largest speed moves
#: at constant speed (its acceleration is rounding noise): its position is not plotted
#: against velocity and acceleration
CONSTANT_SPEED_TOL = 1e-4


def _envelope(x: np.ndarray, y: np.ndarray, bins: int = 1500):
    """Per-bin min/max of y (bins along x): plots of millions of points that keep spikes."""
    n = x.size
    if n <= 2 * bins:
        return x, y, y
    edges = np.linspace(0, n, bins + 1).astype(np.int64)
    starts = edges[:-1]
    xm = x[(starts + edges[1:]) // 2]
    return xm, np.minimum.reduceat(y, starts), np.maximum.reduceat(y, starts)


def moving_axes(t: np.ndarray, axes: dict, derivatives: dict | None = None) -> list[str]:
    """The axes whose speed changes (more than :data:`CONSTANT_SPEED_TOL` of their top
    speed): an axis at rest or at constant speed (X of a constant-feed spiral) has
    nothing to show but rounding noise in its acceleration.  ``derivatives``, a dict,
    receives the :func:`~render_inspect.toolpath.axis_derivatives` taken (axis -> (v, a, j));
    an axis' derivatives already in it are used as they are."""
    taken = derivatives if derivatives is not None else {}
    # (the axes that move at all: at least 3 points, not all equal)
    taken.update(axes_derivatives(t, {n: q for n, q in axes.items() if n not in taken}))
    out = []
    for name in axes:
        if name not in taken:
            continue
        v = taken[name][0]
        top = float(np.max(np.abs(v)))
        if top > 0 and float(np.ptp(v)) > CONSTANT_SPEED_TOL * top:
            out.append(name)
    return out


_UNITS = {"X": ("mm", 1.0), "Z": ("um", MM_TO_UM), "FTS": ("um", MM_TO_UM)}


def _motion_series(columns, axes=None):
    """``[(label, t, {axis: position}, {axis: derivatives taken})]`` of ``columns`` and the
    axes to plot: ``axes``, or every axis that moves in any column (Z when none does)."""
    series = []
    for label, path, data in columns:
        t = np.asarray(path.t, dtype=np.float64)
        # (the derivatives the plan took already, when its data holds them)
        series.append((label, t, turning_axes(path, data), dict((data or {}).get("derivatives") or {})))
    if axes is None:
        names = []
        for _, t, ax, taken in series:
            for n in moving_axes(t, ax, taken):
                if n not in names:
                    names.append(n)
        if not names:
            names = ["Z"]
    else:
        names = list(axes)
    return series, names


def axis_motion_figure(columns: Sequence[tuple[str, ToolPath, dict]], *,
                       axes: Sequence[str] | None = None, title: str | None = None,
                       dpi: int = 100) -> bytes:
    """PNG bytes: position, velocity and acceleration against time of the axes that move
    (:func:`moving_axes`), one column per path.

    Parameters
    ----------
    columns : list of (label, ToolPath, data)
        ``data``: the plan's data (``z_slow`` / ``z_fts`` of a tool-servo program), or {}.
    axes : sequence of str, optional
        Only these axes (e.g. ``("X",)``); default every axis that moves in any column.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    series, names = _motion_series(columns, axes)
    rows = [(n, q) for n in names for q in ("position", "velocity", "acceleration")]
    fig, grid = plt.subplots(len(rows), len(series), figsize=(5.4 * len(series), 1.9 * len(rows)),
                             dpi=dpi, squeeze=False, sharey="row")
    for col, (label, t, ax_data, taken) in enumerate(series):
        still = [n for n in ax_data if n not in names] if axes is None else []
        for r, (name, qty) in enumerate(rows):
            axx = grid[r, col]
            unit, scale = _UNITS.get(name, ("mm", 1.0))
            q = ax_data.get(name)
            if q is None:
                axx.set_axis_off()
                continue
            v, a, _ = taken[name] if name in taken else axis_derivatives(t, q)
            y = {"position": q, "velocity": v, "acceleration": a}[qty] * scale
            ylab = {"position": f"{name} ({unit})", "velocity": f"{name} velocity ({unit}/s)",
                    "acceleration": f"{name} acceleration ({unit}/s$^2$)"}[qty]
            xm, lo, hi = _envelope(t, y)
            axx.plot(xm, lo, lw=0.7, color="C0")
            if xm.size != t.size:
                axx.plot(xm, hi, lw=0.7, color="C0")
                axx.fill_between(xm, lo, hi, lw=0, color="C0", alpha=0.5)
            axx.set_ylabel(ylab, fontsize=8)
            axx.grid(alpha=0.3)
            if r == len(rows) - 1:
                axx.set_xlabel("time (s)")
            if qty == "acceleration":
                axx.set_title(f"max |{name} accel.| {np.max(np.abs(a)) * scale:.3g} {unit}/s$^2$",
                              fontsize=8)
        head = label
        if still:
            head += "\n(" + ", ".join(still) + " at constant speed: not plotted)"
        grid[0, col].set_title(head, fontsize=9)
    if title:
        fig.suptitle(title)
    return figure_png(fig, dpi=dpi, tight_layout=True)


def plot_kinematics(path: ToolPath, png_path: str | Path, *, reference: ToolPath | None = None,
                    labels: Sequence[str] = ("RCSE", "conventional"),
                    title: str | None = None) -> Path:
    """Plot X against C and the X velocity and acceleration against time (the RCSE
    study's Figs. 8-9), one column per path.

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
        c_rev = part_angle(p) / (2 * math.pi)  # (the part's C: decreasing turning M04)
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
    return atomic_write_bytes(png_path, figure_png(fig, dpi=110, tight_layout=True))


def kinematics_png(columns: Sequence[tuple[str, ToolPath, dict]], png_path: str | Path, *,
                   axes: Sequence[str] | None = None, title: str = "") -> Path:
    """kinematics.png: the content of :func:`axis_motion_figure` (position, velocity and
    acceleration against time of the axes that move, per path) drawn with Pillow as
    stacked panels (``render_inspect.report._quickplot``: tens of milliseconds, where a
    matplotlib figure takes about a second with its import).

    The derivatives are taken on the whole path (decimating first would smooth away the
    single-point spikes a machine limit cares about); only the drawing is decimated, to
    per-bin minimum / maximum envelopes (1500 bins).

    Parameters
    ----------
    columns : list of (label, ToolPath, data)
        As for :func:`axis_motion_figure`.
    png_path : str or Path
        Written atomically.
    axes : sequence of str, optional
        Only these axes; default every axis that moves in any path.
    """
    return panels_png(png_path, kinematics_panels(columns, axes), title=title)


def kinematics_panels(columns: Sequence[tuple[str, ToolPath, dict]],
                      axes: Sequence[str] | None = None) -> list[dict]:
    """The panels :func:`kinematics_png` draws (as the Pillow drawing's ``panels_png`` takes
    them): per axis that moves and per path, its position, velocity
    and acceleration as per-bin envelopes over time, with their labels.  A few hundred
    kilobytes, where the paths and their derivatives are tens of megabytes: what is sent to
    a process that draws the figure."""
    series, names = _motion_series(columns, axes)
    panels = []
    for label, t, ax_data, taken in series:
        still = [n for n in ax_data if n not in names] if axes is None else []
        head = label + (" (" + ", ".join(still) + " at constant speed: not plotted)" if still else "")
        first = True
        for name in names:
            q = ax_data.get(name)
            if q is None:
                continue
            unit, scale = _UNITS.get(name, ("mm", 1.0))
            v, a, _ = taken[name] if name in taken else axis_derivatives(t, q)
            for qty, y, u in (("position", q, unit), ("velocity", v, f"{unit}/s"),
                              ("acceleration", a, f"{unit}/s^2")):
                y = np.asarray(y, dtype=np.float64) * scale
                xm, lo, hi = _envelope(t, y)
                ylab = f"{name} ({u})" if qty == "position" else f"{name} {qty} ({u})"
                note = "" if qty == "position" else f"max |{name} {qty}| {np.max(np.abs(y)):.3g} {u}"
                panels.append({"x": xm, "lo": lo, "hi": hi, "xlabel": "time (s)", "ylabel": ylab,
                               "title": "; ".join(x for x in ((head if first else ""), note) if x)})
                first = False
    return panels
