"""Following-error figures: the error of each axis against time, and the X and Z errors
mapped onto the part (the error of the pass that cut each point), drawn with Pillow
(:mod:`._quickplot`: a few tens of milliseconds each, where matplotlib took about 0.25 s a
figure and its import about 0.35 s)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ._kinematics import _envelope
from ._quickplot import maps_png, panels_png

__all__ = ["plot_following_error", "plot_following_error_map"]


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
        :func:`~render_inspect.machining.following_error_stats`, written into the panels'
        titles.

    Returns
    -------
    Path.  Curves are per-bin min/max envelopes (1500 bins), so single-tick spikes stay
    visible.
    """
    return panels_png(png_path, following_error_panels(t, errors, stats),
                      title=title or FOLLOWING_ERROR_TITLE, height=FOLLOWING_ERROR_PANEL_HEIGHT)


#: the title of :func:`plot_following_error` when none is given, and its panels' height (px)
FOLLOWING_ERROR_TITLE = "following error (command - followed)"
FOLLOWING_ERROR_PANEL_HEIGHT = 150


def following_error_panels(t: np.ndarray, errors: dict, stats: dict | None = None) -> list[dict]:
    """The panels :func:`plot_following_error` draws: per axis, its error against time as
    per-bin envelopes (1500 bins), with its labels."""
    t = np.asarray(t, dtype=np.float64)
    rows = [(k, lab, scale) for k, lab, scale in
            (("x", "X (nm)", 1e6), ("z", "Z slide (nm)", 1e6), ("fts", "FTS (nm)", 1e6),
             ("c", "C (urad)", 1e6))
            if k in errors and np.any(np.asarray(errors[k]) != 0)]
    if not rows:
        rows = [("x", "X (nm)", 1e6)]
    panels = []
    for k, lab, scale in rows:
        y = np.asarray(errors.get(k, np.zeros_like(t)), dtype=np.float64) * scale
        xm, lo, hi = _envelope(t, y)
        note = ""
        if stats:
            unit = "urad" if k == "c" else "nm"
            r, m = stats.get(f"{k}_rms_{unit}"), stats.get(f"{k}_max_{unit}")
            if r is not None:
                note = f"rms {r:.3g} {unit}, max {m:.3g} {unit}"
        panels.append({"x": xm, "lo": lo, "hi": hi, "xlabel": "time (s)", "ylabel": lab, "title": note})
    return panels


def plot_following_error_map(x_nm: np.ndarray, z_nm: np.ndarray, extent: Sequence[float],
                             png_path: str | Path, *, title: str | None = None) -> Path:
    """The X and Z following errors (nm) of the pass that cut each point of the part, side
    by side, each on its own colour scale symmetric about zero (grey: not cut).

    Parameters
    ----------
    x_nm, z_nm : (ny, nx) arrays, nm (NaN = not cut)
    extent : (x0, x1, y0, y1), mm
    png_path : str or Path
    """
    return maps_png(png_path, [{"data": x_nm, "title": "X following error (nm)", "label": "nm",
                                "symmetric": True},
                               {"data": z_nm, "title": "Z following error (nm)", "label": "nm",
                                "symmetric": True}],
                    extent=extent, title=title or "")
