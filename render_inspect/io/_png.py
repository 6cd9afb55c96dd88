"""PNG previews (8-bit) and false-colour maps with a colour bar."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from ..core.units import MM_TO_NM, MM_TO_UM
from ._atomic import atomic_write_bytes


def save_png(path: str | Path, image: np.ndarray) -> Path:
    """Save a float image in [0, 1] (H x W or H x W x 3) as 8-bit PNG, row 0 at the top."""
    from PIL import Image

    a = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float64)), 0, 1)
    a = (a * 255 + 0.5).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(a).save(buf, format="PNG")
    return atomic_write_bytes(path, buf.getvalue())


def save_map_png(path: str | Path, data: np.ndarray, *, extent=None, title: str = "",
                 label: str = "", cmap: str = "viridis", symmetric: bool = False,
                 vmin=None, vmax=None) -> Path:
    """False-colour map with a colour bar.  ``data`` row 0 is the smallest y (drawn at the
    bottom); ``extent`` = (x0, x1, y0, y1) in mm."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    d = np.asarray(data, dtype=np.float64)
    if symmetric and vmin is None and vmax is None:
        m = np.nanmax(np.abs(d)) if np.isfinite(d).any() else 1.0
        vmin, vmax = -m, m
    fig, ax = plt.subplots(figsize=(5.2, 4.2), dpi=100)
    im = ax.imshow(d, origin="lower", extent=extent, cmap=cmap, vmin=vmin, vmax=vmax,
                   interpolation="nearest")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    if title:
        ax.set_title(title, fontsize=10)
    cb = fig.colorbar(im, ax=ax)
    if label:
        cb.set_label(label)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())


def _nice_length(mm: float) -> tuple[float, str]:
    """A round scale-bar length near ``mm`` and its label (nm / um / mm)."""
    if not mm > 0:
        return 0.0, ""
    exp = np.floor(np.log10(mm))
    for m in (5, 2, 1):
        v = m * 10 ** exp
        if v <= mm:
            break
    if v >= 1:
        return v, f"{v:g} mm"
    if v >= 1e-3:
        return v, f"{v * MM_TO_UM:g} um"
    return v, f"{v * MM_TO_NM:g} nm"


def save_height_png(path: str | Path, height_nm: np.ndarray, *, extent, title: str = "",
                    label: str = "height (nm)", cmap: str = "viridis",
                    percentile: float = 0.1) -> Path:
    """Height map with a colour bar, a scale bar and axes in mm.

    Parameters
    ----------
    path : str or Path
        PNG written atomically.
    height_nm : (ny, nx) array
        Heights in nm (NaN = not measured, drawn grey); row 0 = smallest y, drawn at the
        bottom.
    extent : (x0, x1, y0, y1)
        Pixel edges, mm (non-square pixels are drawn to scale).
    label : str
        Colour-bar label (say the unit).
    percentile : float
        The colour range spans the ``percentile`` .. ``100 - percentile`` percentiles of
        the valid heights, so a few spikes do not wash out the map.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    d = np.asarray(height_nm, dtype=np.float64)
    ok = np.isfinite(d)
    lo, hi = (np.percentile(d[ok], [percentile, 100 - percentile]) if ok.any() else (0.0, 1.0))
    if not hi > lo:
        lo, hi = lo - 0.5, hi + 0.5
    x0, x1, y0, y1 = extent
    w, h = x1 - x0, y1 - y0
    fig_w = 6.4
    fig_h = float(np.clip(fig_w * 0.8 * h / w + 0.9, 2.6, 7.5))
    fig, ax = plt.subplots(figsize=(fig_w, fig_h), dpi=110)
    cm = matplotlib.colormaps[cmap].copy()
    cm.set_bad("0.75")
    im = ax.imshow(d, origin="lower", extent=extent, cmap=cm, vmin=lo, vmax=hi,
                   interpolation="nearest", aspect="equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    if title:
        ax.set_title(title, fontsize=9)
    length, text = _nice_length(0.25 * w)
    if length:
        bar = AnchoredSizeBar(ax.transData, length, text, "lower right", pad=0.4, color="white",
                              frameon=True, size_vertical=h / 150, label_top=True)
        bar.patch.set_facecolor("black")
        bar.patch.set_alpha(0.55)
        ax.add_artist(bar)
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    cb.set_label(label)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return atomic_write_bytes(path, buf.getvalue())
