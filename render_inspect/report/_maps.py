"""Single maps as PNG files: a height or difference map with axes in mm and a colour bar
(:func:`save_map_png`, one panel of :func:`~render_inspect.report.map_panels`), a height
map drawn to scale with a scale bar (:func:`save_height_png`), the quick residual preview
of a simulation (:func:`residual_png`, drawn with Pillow: :mod:`render_inspect.report._quickplot`),
and a map as a bare false-colour image, one pixel per value (:func:`image_png`, the
regression summary's)."""

from __future__ import annotations

from collections.abc import Sequence
import io
from pathlib import Path

import numpy as np

from ..core.units import MM_TO_NM, NM_TO_MM
from ..io import atomic_write_bytes, coarsen, means
from ..io import preview as area_preview
from ._figures import length_label, map_panels
from ._format import scale_bar_length
from ._quickplot import map_png
from ._savefig import figure_png

__all__ = ["save_map_png", "save_height_png", "residual_png", "residual_preview_png",
           "image_png", "rgb_png"]


def save_map_png(path: str | Path, data: np.ndarray, *, extent: Sequence[float] | None = None,
                 title: str = "",
                 label: str = "", cmap: str = "viridis", symmetric: bool = False) -> Path:
    """False-colour map with a colour bar and a scale bar, written atomically: one panel
    of :func:`~render_inspect.report.map_panels` over the whole range of the values.
    ``data`` row 0 is the smallest y (drawn at the bottom); ``extent`` = (x0, x1, y0, y1)
    in mm."""
    png = map_panels([(title, np.asarray(data, dtype=np.float64))], extent=extent, label=label,
                     cmap=cmap, symmetric=symmetric, percentile=None)
    return atomic_write_bytes(path, png)


def _nice_length(width_mm: float) -> tuple[float, str]:
    """The scale bar of a map ``width_mm`` wide (:func:`~render_inspect.report.scale_bar_length`)
    and its label (nm / um / mm)."""
    if not width_mm > 0:
        return 0.0, ""
    v = scale_bar_length(width_mm)
    return v, length_label(v)


def save_height_png(path: str | Path, height_nm: np.ndarray, *,
                    extent: tuple[float, float, float, float], title: str = "",
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
    length, text = _nice_length(w)
    if length:
        bar = AnchoredSizeBar(ax.transData, length, text, "lower right", pad=0.4, color="white",
                              frameon=True, size_vertical=h / 150, label_top=True)
        bar.patch.set_facecolor("black")
        bar.patch.set_alpha(0.55)
        ax.add_artist(bar)
    cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
    cb.set_label(label)
    return atomic_write_bytes(path, figure_png(fig, tight_layout=True))


def residual_preview_png(png: str | Path, machined: np.ndarray, design: np.ndarray, *,
                         extent: Sequence[float], mean_nm: float, title: str,
                         overview: dict | None = None, side: int = 512) -> Path:
    """residual.png: machined - design less its mean (nm) as area averages of at most
    ``side`` pixels a side (no aliasing of the feed marks; :func:`render_inspect.io.preview`),
    from the EXR overview's block sums when given (no second pass over the map)."""
    img, factor = residual_preview_image(machined, design, overview=overview, side=side)
    return residual_png(png, img, factor, extent=extent, mean_nm=mean_nm, title=title)


def residual_preview_image(machined: np.ndarray, design: np.ndarray, *,
                           overview: dict | None = None,
                           side: int = 512) -> tuple[np.ndarray, int]:
    """The image :func:`residual_preview_png` draws: machined - design (mm) as means of
    ``factor`` x ``factor`` pixels, at most ``side`` a side; returns (image, factor)."""
    if overview is not None and overview["residual"] is not None:
        factor, (s, c) = overview["factor"], overview["residual"]
        while max(s.shape) > side:
            s, c = coarsen(s, c, 2)
            factor *= 2
        return means(s, c), factor
    return area_preview(machined, side, minus=design)


def residual_png(png: str | Path, img: np.ndarray, factor: int, *, extent: Sequence[float],
                 mean_nm: float, title: str) -> Path:
    """residual.png from an area-averaged residual image (mm) of ``factor`` x ``factor``
    pixel means."""
    img = (np.asarray(img, dtype=np.float32) - np.float32(mean_nm * NM_TO_MM)) * np.float32(MM_TO_NM)
    avg = f", {factor} x {factor}-pixel means" if factor > 1 else ""
    return map_png(png, img, extent=extent, cmap="RdBu_r", symmetric=True,
                   label=f"machined - design (nm{avg})", title=title)


#: Images in the summary are enlarged (nearest neighbour) to at least this many pixels.
MIN_SIDE = 192


def _encode(rgb8: np.ndarray) -> bytes:
    from PIL import Image

    h, w = rgb8.shape[:2]
    k = max(1, int(np.ceil(MIN_SIDE / max(min(h, w), 1))))
    img = Image.fromarray(rgb8)
    if k > 1:
        img = img.resize((w * k, h * k), Image.Resampling.NEAREST)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    return buf.getvalue()


def image_png(data: np.ndarray, *, cmap: str = "viridis", vmin: float | None = None,
              vmax: float | None = None, symmetric: bool = False,
              flip_rows: bool = True) -> tuple[bytes, float, float]:
    """A 2-D array as a false-colour PNG, one pixel per value (NaN grey; no axes: an image
    to hold next to its reference); returns (png, vmin, vmax).
    ``flip_rows``: row 0 is the smallest y and is drawn at the bottom."""
    from matplotlib import colormaps

    d = np.asarray(data, dtype=np.float64)
    fin = np.isfinite(d)
    if vmin is None or vmax is None:
        if fin.any():
            lo, hi = float(d[fin].min()), float(d[fin].max())
        else:
            lo, hi = 0.0, 1.0
        if symmetric:
            m = max(abs(lo), abs(hi)) or 1.0
            lo, hi = -m, m
        vmin = lo if vmin is None else vmin
        vmax = hi if vmax is None else vmax
    span = (vmax - vmin) or 1.0
    rgba = colormaps[cmap](np.clip((np.nan_to_num(d) - vmin) / span, 0, 1))
    rgba[~fin] = (0.55, 0.55, 0.55, 1.0)
    rgb8 = (rgba[..., :3] * 255 + 0.5).astype(np.uint8)
    if flip_rows:
        rgb8 = rgb8[::-1]
    return _encode(rgb8), float(vmin), float(vmax)


def rgb_png(rgb: np.ndarray) -> bytes:
    """Linear RGB (H, W, 3), row 0 at the top, as an sRGB PNG."""
    a = np.clip(np.nan_to_num(np.asarray(rgb, dtype=np.float64)), 0, 1)
    a = np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)
    return _encode((a * 255 + 0.5).astype(np.uint8))
