"""Following-error figures: the error of each axis against time, and the X and Z errors
mapped onto the part (the error of the pass that cut each point)."""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import io
from pathlib import Path

import numpy as np

from ..io import atomic_write_bytes
from ._kinematics import _envelope

__all__ = ["plot_following_error", "plot_following_error_map"]


def _save(fig: Any, png_path: str | Path) -> Path:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return atomic_write_bytes(png_path, buf.getvalue())


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
    fig.suptitle(title or "following error (command - followed)")
    fig.tight_layout()
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
    for ax, (m, lab) in zip(axes[0], ((x_nm, "X following error (nm)"),
                                      (z_nm, "Z following error (nm)"))):
        m = np.asarray(m, dtype=np.float64)
        lim = float(np.nanmax(np.abs(m))) if np.isfinite(m).any() else 1.0
        im = ax.imshow(m, origin="lower", extent=extent, cmap="RdBu_r", vmin=-lim or -1,
                       vmax=lim or 1)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_title(lab, fontsize=9)
        fig.colorbar(im, ax=ax, shrink=0.85)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, png_path)
