"""Figures of the comparison report, as PNG bytes (matplotlib, Agg backend).

Every map is drawn with row 0 (the smallest y) at the bottom and x, y in mm; panels that
are compared share one colour scale so that equal colours mean equal heights.
"""

from __future__ import annotations

import io

import numpy as np

__all__ = ["map_panels", "image_panels", "radial_profile_figure", "png_bytes", "line_panels"]


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _to_png(fig) -> bytes:
    plt = _plt()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=fig.dpi)
    plt.close(fig)
    return buf.getvalue()


def png_bytes(image) -> bytes:
    """8-bit PNG of a float image in [0, 1] (H x W or H x W x 3), row 0 at the top."""
    from PIL import Image

    a = np.clip(np.nan_to_num(np.asarray(image, dtype=np.float64)), 0, 1)
    buf = io.BytesIO()
    Image.fromarray((a * 255 + 0.5).astype(np.uint8)).save(buf, format="PNG")
    return buf.getvalue()


def _limits(arrays, symmetric, percentile=None):
    vals = [np.asarray(a, dtype=np.float64) for a in arrays if a is not None]
    vals = [v[np.isfinite(v)] for v in vals]
    vals = [v for v in vals if v.size]
    if not vals:
        return -1.0, 1.0
    allv = np.concatenate(vals)
    if percentile is not None:
        lo, hi = np.percentile(allv, [percentile, 100 - percentile])
    else:
        lo, hi = float(allv.min()), float(allv.max())
    if symmetric:
        m = max(abs(lo), abs(hi)) or 1.0
        return -m, m
    if hi <= lo:
        hi = lo + 1.0
    return float(lo), float(hi)


def map_panels(panels, *, extent=None, label: str = "", cmap: str = "viridis",
               symmetric: bool = False, shared: bool = True, suptitle: str = "",
               percentile: float | None = None, panel_size=(4.2, 3.6), dpi: int = 90) -> bytes:
    """Side-by-side false-colour maps, each with a colour bar.

    Parameters
    ----------
    panels : list of (title, (ny, nx) array)
        Maps with row 0 = smallest y; NaN is drawn blank.
    extent : (x0, x1, y0, y1) or list of them, mm
        Pixel-edge extent (one for all panels or one per panel).
    label : str
        Colour-bar label (say the unit).
    symmetric : bool
        Colour scale symmetric about 0 (differences, residuals).
    shared : bool
        One colour scale for all panels (compare like with like).
    percentile : float, optional
        Clip the scale to this lower/upper percentile (robust to a few spikes).
    """
    plt = _plt()
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(panel_size[0] * n, panel_size[1]), dpi=dpi,
                             squeeze=False)
    lim = _limits([p[1] for p in panels], symmetric, percentile) if shared else None
    for i, (title, data) in enumerate(panels):
        ax = axes[0, i]
        ext = extent[i] if isinstance(extent, list) else extent
        if data is None:
            ax.text(0.5, 0.5, "not available", ha="center", va="center", transform=ax.transAxes)
            ax.set_axis_off()
            ax.set_title(title, fontsize=10)
            continue
        vmin, vmax = lim if lim is not None else _limits([data], symmetric, percentile)
        im = ax.imshow(np.asarray(data, dtype=np.float64), origin="lower", extent=ext, cmap=cmap,
                       vmin=vmin, vmax=vmax, interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
        if label:
            cb.set_label(label)
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    fig.tight_layout()
    return _to_png(fig)


def image_panels(panels, *, extent=None, suptitle: str = "", gray_label: str = "",
                 axis_labels: bool = True, panel_size=(4.2, 3.6), dpi: int = 90) -> bytes:
    """Side-by-side rendered images (grey intensity 0..1 or RGB 0..1), row 0 = smallest y
    (drawn at the bottom).

    A grey panel gets a colour bar labelled ``gray_label``; ``axis_labels=False`` hides
    the axes (perspective views have no x, y scale)."""
    plt = _plt()
    n = len(panels)
    fig, axes = plt.subplots(1, n, figsize=(panel_size[0] * n, panel_size[1]), dpi=dpi,
                             squeeze=False)
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
            im = ax.imshow(a, origin="lower", extent=ext, cmap="gray", vmin=0, vmax=1,
                           interpolation="nearest")
            cb = fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04)
            if gray_label:
                cb.set_label(gray_label)
        else:
            ax.imshow(a, origin="lower", extent=ext, interpolation="nearest")
        if axis_labels:
            ax.set_xlabel("x (mm)")
            ax.set_ylabel("y (mm)")
        else:
            ax.set_axis_off()
    if suptitle:
        fig.suptitle(suptitle, fontsize=11)
    fig.tight_layout()
    return _to_png(fig)


def radial_profile_figure(sections, *, dpi: int = 90) -> bytes:
    """Radial profiles like seed 000 Fig. 16 (b, c): per variant (column), the design and
    machined heights along radial sections at a few angles (top, um), machined minus
    design along them (middle, nm) and, where given, the filtered residual (bottom, nm:
    the waviness that the turning marks hide).

    Parameters
    ----------
    sections : dict variant -> list of dict(angle_deg, s, design, machined[, filtered])
        ``s`` in mm from the centre, heights in mm.
    """
    plt = _plt()
    names = list(sections)
    n = max(len(names), 1)
    has_f = any(sec.get("filtered") is not None for v in sections.values() for sec in v)
    rows = 3 if has_f else 2
    fig, axes = plt.subplots(rows, n, figsize=(4.6 * n, 3.1 * rows), dpi=dpi, squeeze=False,
                             sharey="row")
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for j, name in enumerate(names):
        top, bot = axes[0, j], axes[1, j]
        for k, sec in enumerate(sections[name]):
            c = colors[k % len(colors)]
            s = np.asarray(sec["s"])
            lab = f"{sec['angle_deg']:g} deg"
            if sec.get("design") is not None:
                top.plot(s, np.asarray(sec["design"]) * 1e3, color=c, lw=0.8, ls="--")
            top.plot(s, np.asarray(sec["machined"]) * 1e3, color=c, lw=1.0, label=lab)
            if sec.get("design") is not None:
                bot.plot(s, (np.asarray(sec["machined"]) - np.asarray(sec["design"])) * 1e6,
                         color=c, lw=0.9, label=lab)
            if has_f and sec.get("filtered") is not None:
                axes[2, j].plot(s, np.asarray(sec["filtered"]) * 1e6, color=c, lw=0.9, label=lab)
        if has_f:
            fa = axes[2, j]
            fa.set_title(f"{name}: filtered residual (waviness)", fontsize=10)
            fa.set_ylabel("filtered (nm)")
            fa.set_xlabel("radius (mm)")
            fa.axhline(0, color="k", lw=0.5)
        top.set_title(f"{name}: radial sections (dashed = design)", fontsize=10)
        top.set_ylabel("height (um)")
        bot.set_title(f"{name}: machined - design", fontsize=10)
        bot.set_ylabel("residual (nm)")
        bot.set_xlabel("radius (mm)")
        bot.axhline(0, color="k", lw=0.5)
        top.legend(fontsize=8, loc="best")
    fig.tight_layout()
    return _to_png(fig)


def line_panels(panels, *, suptitle: str = "", dpi: int = 90) -> bytes:
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
    fig.tight_layout()
    return _to_png(fig)
