"""The figure of a machine program read from a file: its feed per revolution against the
radius (``feed_per_rev.png``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._savefig import save_png

__all__ = ["plot_feed_per_rev"]


def plot_feed_per_rev(radius_mm: np.ndarray, feed_um: np.ndarray, png_path: str | Path, *,
                      title: str = "") -> Path:
    """The feed per revolution (um: how far the radius moves over the revolution that
    starts at each point) against the radius (mm), one dot per point."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    r = np.asarray(radius_mm, dtype=np.float64)
    f = np.asarray(feed_um, dtype=np.float64)
    fig, ax = plt.subplots(figsize=(8.0, 3.6))
    ax.plot(r, f, ".", ms=1.5, color="C0")
    ax.set_xlabel("radius (mm)")
    ax.set_ylabel("feed per revolution (um)")
    ax.grid(alpha=0.3)
    if f.size:
        lo, hi = float(np.min(f)), float(np.max(f))
        pad = 0.05 * (hi - lo) if hi > lo else max(abs(hi) * 0.05, 1e-3)
        ax.set_ylim(lo - pad, hi + pad)
    ax.set_title(title or "feed per revolution against the radius")
    return save_png(fig, png_path, tight_layout=True)
