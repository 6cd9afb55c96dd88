"""PNG previews (8-bit) and false-colour maps with a colour bar."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

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
