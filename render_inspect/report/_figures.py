"""Figures of the comparison report, as PNG bytes (matplotlib, Agg backend).

Conventions of every figure:

* maps are drawn with row 0 (the smallest y) at the bottom, x and y in mm, and a scale
  bar; maps larger than the panel are area-averaged (NaN-aware block means) down to about
  the panel's pixel count first, so fine periodic marks are averaged, not aliased into
  moire;
* panels that are compared share one colour scale (symmetric about zero for differences),
  clipped to the 0.5 / 99.5 percentiles so that a few edge pixels cannot flatten the
  rest; a clipped scale shows arrows on its colour bar;
* rendered images carry their scale bar and, for diffuse images, the vertical
  exaggeration written into the picture.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import io
import math

import numpy as np

from ..core.units import MM_TO_NM, MM_TO_UM
from ._format import fmt_quantity, scale_bar_length
from ._savefig import figure_png

__all__ = ["map_panels", "image_panels", "radial_profile_figure", "png_bytes", "line_panels",
           "block_mean", "display_map", "annotate_rgb", "length_label", "lowpass_map",
           "DISPLAY_PIXELS"]

#: maps are area-averaged to at most this many samples across before drawing
DISPLAY_PIXELS = 400
#: alpha of the ISO 16610-61 Gaussian weighting function, sqrt(ln 2 / pi)
ISO_GAUSSIAN_ALPHA = math.sqrt(math.log(2) / math.pi)


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _to_png(fig, *, tight_layout: bool = False) -> bytes:
    _plt()
    return figure_png(fig, dpi=fig.dpi, tight_layout=tight_layout)


def png_bytes(image: np.ndarray) -> bytes:
    """8-bit PNG of a float image in [0, 1] (H x W or H x W x 3), row 0 at the top."""
    from PIL import Image

    a = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float64)), 0, 1)
    buf = io.BytesIO()
    Image.fromarray((a * 255 + 0.5).astype(np.uint8)).save(buf, format="PNG")
    return buf.getvalue()


def block_mean(z: np.ndarray, factor: int) -> np.ndarray:
    """NaN-aware area average over ``factor x factor`` blocks (the last partial blocks
    averaged over what they hold).

    Parameters
    ----------
    z : (ny, nx) or (ny, nx, c) array
    factor : int >= 1

    Returns
    -------
    (ceil(ny / factor), ceil(nx / factor)[, c]) float64; NaN where a block holds no
    finite value.
    """
    z = np.asarray(z, dtype=np.float64)
    f = int(factor)
    if f <= 1:
        return z
    ny, nx = z.shape[:2]
    py, px = (-ny) % f, (-nx) % f
    pad = [(0, py), (0, px)] + [(0, 0)] * (z.ndim - 2)
    zp = np.pad(z, pad, constant_values=np.nan)
    shp = (zp.shape[0] // f, f, zp.shape[1] // f, f) + zp.shape[2:]
    blocks = zp.reshape(shp)
    ok = np.isfinite(blocks)
    s = np.where(ok, blocks, 0.0).sum(axis=(1, 3))
    n = ok.sum(axis=(1, 3))
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(n > 0, s / np.maximum(n, 1), np.nan)


def display_map(z: np.ndarray, max_px: int = DISPLAY_PIXELS) -> np.ndarray:
    """``z`` area-averaged (:func:`block_mean`) so that its longer side is at most
    ``max_px`` samples (unchanged when it already is)."""
    z = np.asarray(z, dtype=np.float64)
    n = max(z.shape[:2])
    return block_mean(z, int(math.ceil(n / max_px))) if n > max_px else z


def length_label(mm: float) -> str:
    """A length for a scale bar: ``"50 um"``, ``"1 mm"``."""
    if mm >= 1.0:
        return f"{mm:g} mm"
    if mm >= 1e-3:
        return f"{mm * MM_TO_UM:g} um"
    return f"{mm * MM_TO_NM:g} nm"


def _scale_bar(ax, width_mm: float, *, color: str = "black", length: float | None = None,
               loc: str = "lower right") -> None:
    """A scale bar, in data units (mm): ``length``, or :func:`scale_bar_length` of
    ``width_mm`` (panels of one figure pass the figure's one length)."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    if not width_mm > 0:
        return
    L = length if length is not None else scale_bar_length(width_mm)
    bar = AnchoredSizeBar(ax.transData, L, length_label(L), loc, pad=0.3, borderpad=0.4,
                          sep=3, color=color, frameon=True, size_vertical=0,
                          fontproperties={"size": 8})
    bar.patch.set_alpha(0.75)
    bar.patch.set_edgecolor("none")
    ax.add_artist(bar)


def _shared_bar(extents) -> float | None:
    """One scale bar for the panels of a figure: that of the narrowest panel."""
    widths = [e[1] - e[0] for e in extents if e is not None and e[1] - e[0] > 0]
    return scale_bar_length(min(widths)) if widths else None


def _limits(arrays, symmetric, percentile=None):
    vals = [np.asarray(a, dtype=np.float64) for a in arrays if a is not None]
    vals = [v[np.isfinite(v)] for v in vals]
    vals = [v for v in vals if v.size]
    if not vals:
        return -1.0, 1.0, False
    allv = np.concatenate(vals)
    full = float(allv.min()), float(allv.max())
    if percentile:
        lo, hi = (float(x) for x in np.percentile(allv, [percentile, 100 - percentile]))
    else:
        lo, hi = full
    if symmetric:
        m = max(abs(lo), abs(hi))
        if m == 0:
            m = max(abs(full[0]), abs(full[1])) or 1.0
        return -m, m, max(abs(full[0]), abs(full[1])) > m * (1 + 1e-9)
    if hi <= lo:
        hi = lo + (abs(lo) * 1e-3 or 1.0)  # not a unit conversion
    return lo, hi, full[0] < lo or full[1] > hi


def _extend(data, vmin, vmax) -> str:
    d = np.asarray(data, dtype=np.float64)
    d = d[np.isfinite(d)]
    if not d.size:
        return "neither"
    lo, hi = d.min() < vmin - 1e-12 * abs(vmin), d.max() > vmax + 1e-12 * abs(vmax)  # not a unit conversion
    return {(True, True): "both", (True, False): "min", (False, True): "max"}.get((lo, hi), "neither")


def map_panels(panels: Sequence[tuple[str, np.ndarray | None]], *,
               extent: Any = None, label: str = "",
               cmap: str = "viridis",
               symmetric: bool = False, shared: bool = True, suptitle: str = "",
               percentile: float | None = 0.5, panel_size: tuple[float, float] = (4.6, 3.9),
               dpi: int = 100,
               max_px: int = DISPLAY_PIXELS, lines: Any = None) -> bytes:
    """Side-by-side false-colour maps, each with a colour bar and a scale bar.

    Parameters
    ----------
    panels : list of (title, (ny, nx) array)
        Maps with row 0 = smallest y; NaN is drawn blank; None draws "not available".
    extent : (x0, x1, y0, y1) or list of them, mm
        Pixel-edge extent (one for all panels or one per panel).
    label : str
        Colour-bar label (say the unit).
    symmetric : bool
        Colour scale symmetric about 0 (differences, residuals).
    shared : bool
        One colour scale for all panels (compare like with like).
    percentile : float or None
        Clip the scale to this lower/upper percentile (0.5: robust to a few spikes;
        arrows on the colour bar show that values go beyond).
    max_px : int
        Maps are area-averaged to at most this many samples across.
    lines : list of ((x0, y0), (x1, y1)), optional
        A line (mm) drawn on every panel (e.g. where a profile is taken).
    """
    plt = _plt()
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(panel_size[0] * n, panel_size[1]), dpi=dpi,
                             squeeze=False, layout="constrained")
    shown = [(t, None if d is None else display_map(d, max_px)) for t, d in panels]
    lim = _limits([p[1] for p in panels], symmetric, percentile) if shared else None
    bar = _shared_bar([extent[i] if isinstance(extent, list) else extent
                       for i in range(n) if shown[i][1] is not None])
    for i, (title, data) in enumerate(shown):
        ax = axes[0, i]
        ext = extent[i] if isinstance(extent, list) else extent
        ax.set_title(title, fontsize=10)
        if data is None:
            ax.text(0.5, 0.5, "not available", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
            continue
        vmin, vmax, _ = lim if lim is not None else _limits([panels[i][1]], symmetric, percentile)
        im = ax.imshow(data, origin="lower", extent=ext, cmap=cmap, vmin=vmin, vmax=vmax,
                       interpolation="nearest")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04,
                          extend=_extend(panels[i][1], vmin, vmax))
        if label:
            cb.set_label(label)
        if ext is not None:
            _scale_bar(ax, ext[1] - ext[0], length=bar)
        for (a, b) in lines or ():
            ax.plot([a[0], b[0]], [a[1], b[1]], color="k", lw=0.9, ls="--")
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    return _to_png(fig)


#: (x0, x1, y0, y1) of an image's pixel edges, mm
_Extent = tuple[float, float, float, float]


def image_panels(panels: Sequence[tuple[str, np.ndarray | None]], *,
                 extent: _Extent | list[_Extent | None] | None = None, suptitle: str = "",
                 gray_label: str = "", axis_labels: bool = True, panel_size: tuple[float, float] = (4.6, 3.9),
                 dpi: int = 100, scale_mm: tuple[float, float] | list[tuple[float, float]] | None = None,
                 notes: Sequence[str | None] | None = None) -> bytes:
    """Side-by-side rendered images (grey intensity 0..1 or RGB 0..1), row 0 = smallest y
    (drawn at the bottom).

    A grey panel gets a colour bar labelled ``gray_label``; ``axis_labels=False`` hides
    the axes (perspective views).  Every image gets a scale bar: from ``extent`` (mm)
    or, for a perspective view, ``scale_mm`` = (bar length in mm, bar length in image
    pixels at the part's centre).  ``notes`` (one string per panel) is written into
    the picture (e.g. the vertical exaggeration)."""
    from mpl_toolkits.axes_grid1.anchored_artists import AnchoredSizeBar

    plt = _plt()
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(panel_size[0] * n, panel_size[1]), dpi=dpi,
                             squeeze=False, layout="constrained")
    bar = _shared_bar([extent[i] if isinstance(extent, list) else extent
                       for i in range(n) if panels[i][1] is not None]) if axis_labels else None
    for i, (title, img) in enumerate(panels):
        ax = axes[0, i]
        ext = extent[i] if isinstance(extent, list) else extent
        ax.set_title(title, fontsize=10)
        if img is None:
            ax.text(0.5, 0.5, "not available", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
            continue
        a = np.clip(np.nan_to_num(np.asarray(img, dtype=np.float64)), 0, 1)
        if a.ndim == 2:
            a = display_map(a, 2 * DISPLAY_PIXELS)
            im = ax.imshow(a, origin="lower", extent=ext, cmap="gray", vmin=0, vmax=1,
                           interpolation="antialiased")
            cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
            if gray_label:
                cb.set_label(gray_label)
        else:
            ax.imshow(a, origin="lower", extent=ext, interpolation="antialiased")
        if axis_labels and ext is not None:
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("y (mm)")
            _scale_bar(ax, ext[1] - ext[0], color="black", length=bar)
        else:
            ax.set_xticks([])
            ax.set_yticks([])
            if scale_mm is not None:
                mm, px = scale_mm[i] if isinstance(scale_mm, list) else scale_mm
                bar = AnchoredSizeBar(ax.transData, px, length_label(mm) + " (at the centre)",
                                      "lower right", pad=0.3, borderpad=0.4, sep=3,
                                      color="black", frameon=True, size_vertical=0,
                                      fontproperties={"size": 8})
                bar.patch.set_alpha(0.75)
                bar.patch.set_edgecolor("none")
                ax.add_artist(bar)
        if notes and notes[i]:
            ax.text(0.02, 0.98, notes[i], transform=ax.transAxes, ha="left", va="top",
                    fontsize=8, color="black", wrap=True,
                    bbox={"facecolor": "white", "alpha": 0.75, "edgecolor": "none", "pad": 2})
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    return _to_png(fig)


def lowpass_map(z: np.ndarray, pixel: float, cutoff_mm: float) -> np.ndarray:
    """``z`` through the ISO 16610-61 Gaussian low-pass of nesting index ``cutoff_mm``
    (50 % transmission at that wavelength), NaN-aware (normalised convolution: NaN stays
    NaN).  Detail the map cannot hold (marks finer than a few pixels, which alias into
    false stripes) is averaged out before the map is drawn."""
    from scipy import ndimage

    z = np.asarray(z, dtype=np.float64)
    sigma = ISO_GAUSSIAN_ALPHA * cutoff_mm / math.sqrt(2 * math.pi) / pixel
    if not sigma > 0.3:
        return z
    ok = np.isfinite(z)
    num = ndimage.gaussian_filter(np.where(ok, z, 0.0), sigma, mode="nearest")
    den = ndimage.gaussian_filter(ok.astype(np.float64), sigma, mode="nearest")
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(ok & (den > 1e-6), num / den, np.nan)


def radial_profile_figure(sections: Any, *, dpi: int = 100, radial: bool = True) -> bytes:
    """Sections like Li et al. (2018), Fig. 16 (b, c): per variant (column), the design and
    machined heights along sections at a few angles (top, um), machined minus design
    along them (middle, nm) and, where given, the filtered residual (bottom, nm: the
    waviness that the tool marks hide).

    Parameters
    ----------
    sections : dict variant -> list of dict(angle_deg, s, design, machined[, filtered])
        ``s`` in mm from the section's centre, heights in mm.
    radial : bool
        Radial sections through the spindle axis (turning); else straight sections
        through the window's centre.
    """
    plt = _plt()
    names = list(sections)
    n = max(len(names), 1)
    has_f = any(sec.get("filtered") is not None for v in sections.values() for sec in v)
    rows = 3 if has_f else 2
    fig, axes = plt.subplots(rows, n, figsize=(5.0 * n, 3.1 * rows), dpi=dpi, squeeze=False,
                             sharey="row")
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    kind = "radial sections" if radial else "sections"
    xl = "radius (mm)" if radial else "position along the section (mm)"
    for j, name in enumerate(names):
        top, bot = axes[0, j], axes[1, j]
        for k, sec in enumerate(sections[name]):
            c = colors[k % len(colors)]
            s = np.asarray(sec["s"])
            lab = f"{sec['angle_deg']:g} deg"
            if sec.get("design") is not None:
                top.plot(s, np.asarray(sec["design"]) * MM_TO_UM, color=c, lw=0.8, ls="--")
            top.plot(s, np.asarray(sec["machined"]) * MM_TO_UM, color=c, lw=1.0, label=lab)
            if sec.get("design") is not None:
                bot.plot(s, (np.asarray(sec["machined"]) - np.asarray(sec["design"])) * MM_TO_NM,
                         color=c, lw=0.9, label=lab)
            if has_f and sec.get("filtered") is not None:
                axes[2, j].plot(s, np.asarray(sec["filtered"]) * MM_TO_NM, color=c, lw=0.9, label=lab)
        if has_f:
            fa = axes[2, j]
            fa.set_title(f"{name}: filtered residual (waviness)", fontsize=10)
            fa.set_ylabel("filtered (nm)")
            fa.set_xlabel(xl)
            fa.axhline(0, color="k", lw=0.5)
        top.set_title(f"{name}: {kind} (dashed = design)", fontsize=10)
        top.set_ylabel("height (um)")
        bot.set_title(f"{name}: machined - design", fontsize=10)
        bot.set_ylabel("residual (nm)")
        bot.set_xlabel(xl)
        bot.axhline(0, color="k", lw=0.5)
        top.legend(fontsize=8, loc="best")
    return _to_png(fig, tight_layout=True)


def annotate_rgb(rgb8: np.ndarray, *, lines: Sequence[str] = (), scale_mm: float | None = None,
                 scale_px: float | None = None) -> np.ndarray:
    """Write text lines (top left) and a scale bar (bottom right) into an 8-bit image.

    Parameters
    ----------
    rgb8 : (H, W, 3) uint8, row 0 at the top
    lines : sequence of str
        E.g. ``"heights x20 (vertical exaggeration)"``.
    scale_mm, scale_px : float, optional
        A bar of ``scale_px`` pixels labelled ``scale_mm`` (mm).

    Returns
    -------
    (H, W, 3) uint8, a new image.
    """
    from PIL import Image, ImageDraw, ImageFont

    img = Image.fromarray(np.ascontiguousarray(rgb8))
    h, w = rgb8.shape[:2]
    size = max(10, int(round(min(h, w) / 34)))
    font = ImageFont.load_default(size=size)
    draw = ImageDraw.Draw(img, "RGBA")
    y: float = 3
    for text in lines:
        box = draw.textbbox((4, y), text, font=font)
        draw.rectangle((box[0] - 2, box[1] - 2, box[2] + 2, box[3] + 2), fill=(255, 255, 255, 190))
        draw.text((4, y), text, fill=(0, 0, 0, 255), font=font)
        y = box[3] + 4
    if scale_mm is not None and scale_px is not None and scale_px >= 4:
        label = length_label(scale_mm)
        tb = draw.textbbox((0, 0), label, font=font)
        bw = int(round(scale_px))
        x1 = w - 8
        x0 = x1 - bw
        yb = h - 8
        ty = yb - 6 - (tb[3] - tb[1]) - 2
        draw.rectangle((min(x0, x1 - (tb[2] - tb[0])) - 4, ty - 3, x1 + 4, yb + 4),
                       fill=(255, 255, 255, 190))
        draw.line((x0, yb, x1, yb), fill=(0, 0, 0, 255), width=max(2, size // 6))
        draw.text((x1 - (tb[2] - tb[0]), ty - tb[1]), label, fill=(0, 0, 0, 255), font=font)
    return np.asarray(img.convert("RGB"))


def line_panels(panels: Sequence[dict], *, suptitle: str = "", dpi: int = 90) -> bytes:
    """Line plots side by side (instrument characterisation curves).

    Parameters
    ----------
    panels : list of dict
        ``title``, ``xlabel``, ``ylabel``, ``series``: list of dict(``x``, ``y``,
        ``label``, optional ``style`` ("line" | "points" | "dashed")), optional
        ``vlines``: list of (x, label), ``ylim``.
    """
    plt = _plt()
    n = max(len(panels), 1)
    fig, axes = plt.subplots(1, n, figsize=(5.0 * n, 3.6), dpi=dpi, squeeze=False)
    for ax, p in zip(axes[0], panels):
        for srs in p["series"]:
            style = srs.get("style", "line")
            kw = {"marker": "o", "ls": "none", "ms": 4} if style == "points" else (
                {"ls": "--", "lw": 1.0} if style == "dashed" else {"lw": 1.2})
            ax.plot(np.asarray(srs["x"]), np.asarray(srs["y"]), label=srs.get("label"), **kw)
        for xv, lab in p.get("vlines", []):
            ax.axvline(xv, color="0.4", lw=0.8, ls=":")
            ax.annotate(lab, (xv, 0.98), xycoords=("data", "axes fraction"), fontsize=8,
                        rotation=90, va="top", ha="right")
        if p.get("ylim") is not None:
            ax.set_ylim(*p["ylim"])
        ax.set_title(p.get("title", ""), fontsize=10)
        ax.set_xlabel(p.get("xlabel", ""))
        ax.set_ylabel(p.get("ylabel", ""))
        ax.grid(alpha=0.3)
        if any(s.get("label") for s in p["series"]):
            ax.legend(fontsize=8, loc="best")
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    return _to_png(fig, tight_layout=True)
