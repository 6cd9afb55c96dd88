"""Figures drawn straight into PNG with Pillow: a false-colour map with a colour bar (or
several side by side), and stacked line panels.

Writing a simulation's outputs should cost less than the simulation.  matplotlib takes
about 0.5 s to import and 0.2-0.4 s per figure on the 2-core benchmark machine; these
figures take a few tens of milliseconds.  The data are small by construction: the map
is an area-averaged preview (:func:`render_inspect.io.preview`) and the line panels
are per-bin minimum / maximum envelopes, so single-point spikes stay visible.

Colour maps are linear interpolations of ColorBrewer's 11-class diverging "RdBu"
(reversed: blue below zero, red above) and of a perceptually ordered blue-green-yellow
ramp for one-sided data.
"""

from __future__ import annotations

from collections.abc import Sequence
import io
import math
from pathlib import Path

import numpy as np

from ..io import atomic_write_bytes
from ._savefig import PNG_COMPRESS_LEVEL

__all__ = ["map_png", "maps_png", "panels_png", "CMAPS"]

#: ColorBrewer RdBu (11 classes), from blue (low) to red (high)
_RDBU_R = ["#053061", "#2166ac", "#4393c3", "#92c5de", "#d1e5f0", "#f7f7f7", "#fddbc7", "#f4a582", "#d6604d",
           "#b2182b", "#67001f"]
_RAMP = ["#440154", "#3b528b", "#21918c", "#5ec962", "#fde725"]
CMAPS = {"RdBu_r": _RDBU_R, "ramp": _RAMP}


def _lut(name: str) -> np.ndarray:
    stops = np.array([[int(c[i:i + 2], 16) for i in (1, 3, 5)] for c in CMAPS[name]], dtype=np.float64)
    t = np.linspace(0, 1, 256)
    s = np.linspace(0, 1, len(stops))
    return np.stack([np.interp(t, s, stops[:, k]) for k in range(3)], axis=1).round().astype(np.uint8)


def _ticks(lo: float, hi: float, n: int = 5) -> list[float]:
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [lo]
    raw = (hi - lo) / n
    mag = 10 ** math.floor(math.log10(raw))
    step = next(m * mag for m in (1, 2, 2.5, 5, 10) if m * mag >= raw)
    first = math.ceil(lo / step - 1e-9) * step
    return [first + i * step for i in range(int((hi - first) / step + 1e-9) + 1)]


def _fmt(v: float, step: float | None = None) -> str:
    if v == 0 or (step is not None and abs(v) < 1e-9 * step):  # not a unit conversion
        return "0"
    if step is not None and 1e-4 <= abs(v) < 1e6 and step >= 1e-6:
        txt = f"{v:.{max(0, -math.floor(math.log10(step)) + 1)}f}"
        return txt.rstrip("0").rstrip(".") if "." in txt else txt
    return f"{v:.4g}"


def _offset(lo: float, hi: float) -> float:
    """A value to subtract from tick labels whose range is tiny against their size."""
    big = max(abs(lo), abs(hi))
    if big > 0 and hi - lo < 1e-3 * big:  # not a unit conversion
        q = 10.0 ** (math.floor(math.log10(hi - lo)) + 1)
        return round((lo + hi) / 2 / q) * q
    return 0.0


def _font(size: int):
    from PIL import ImageFont

    return ImageFont.load_default(size=size)


def _png(img) -> bytes:
    buf = io.BytesIO()
    img.save(buf, format="PNG", compress_level=PNG_COMPRESS_LEVEL)
    return buf.getvalue()


def map_png(path: str | Path, data: np.ndarray, *, extent: Sequence[float], title: str = "",
            label: str = "",
            cmap: str = "RdBu_r", symmetric: bool = False, vmin: float | None = None,
            vmax: float | None = None, size: int = 420) -> Path:
    """False-colour map with axes in mm and a colour bar, written atomically.

    Parameters
    ----------
    data : (ny, nx) array, row 0 the smallest y (drawn at the bottom); NaN drawn grey
    extent : (x0, x1, y0, y1) of the pixel edges, mm
    size : larger side of the drawn image, screen pixels (the data are resampled with a
        box filter when larger, nearest-neighbour when smaller)
    """
    return atomic_write_bytes(path, _png(_map_image(data, extent=extent, title=title, label=label,
                                                    cmap=cmap, symmetric=symmetric, vmin=vmin,
                                                    vmax=vmax, size=size)))


def maps_png(path: str | Path, maps: Sequence[dict], *, extent: Sequence[float], title: str = "",
             size: int = 420) -> Path:
    """False-colour maps of one field side by side, each with its axes in mm and its own
    colour bar (as :func:`map_png`), under one ``title``, written atomically.  Each map:
    ``data`` and optionally ``title``, ``label``, ``cmap``, ``symmetric``, ``vmin``,
    ``vmax``."""
    from PIL import Image, ImageDraw

    panels = [_map_image(m["data"], extent=extent, title=m.get("title", ""), label=m.get("label", ""),
                         cmap=m.get("cmap", "RdBu_r"), symmetric=m.get("symmetric", False),
                         vmin=m.get("vmin"), vmax=m.get("vmax"), size=size) for m in maps]
    f = _font(12)
    top = 8 + 16 * (title.count("\n") + 1) if title else 0
    W = sum(p.width for p in panels) + 10 * max(len(panels) - 1, 0)
    canvas = Image.new("RGB", (max(W, 1), top + max((p.height for p in panels), default=1)), "white")
    dr = ImageDraw.Draw(canvas)
    for i, line in enumerate(title.splitlines()):
        dr.text(((canvas.width - dr.textlength(line, font=f)) / 2, 6 + 16 * i), line, fill="black", font=f)
    x = 0
    for p in panels:
        canvas.paste(p, (x, top))
        x += p.width + 10
    return atomic_write_bytes(path, _png(canvas))


def _map_image(data: np.ndarray, *, extent: Sequence[float], title: str, label: str, cmap: str,
               symmetric: bool, vmin: float | None, vmax: float | None, size: int):
    """The image of :func:`map_png`."""
    from PIL import Image, ImageDraw

    d = np.asarray(data, dtype=np.float64)
    finite = np.isfinite(d)
    if symmetric and vmin is None and vmax is None:
        m = float(np.max(np.abs(d[finite]))) if finite.any() else 1.0
        vmin, vmax = -m, m
    if vmin is None:
        vmin = float(d[finite].min()) if finite.any() else 0.0
    if vmax is None:
        vmax = float(d[finite].max()) if finite.any() else 1.0
    if vmax <= vmin:
        vmax = vmin + (abs(vmin) or 1.0) * 1e-6  # not a unit conversion
    lut = _lut(cmap)
    idx = np.clip(((d - vmin) / (vmax - vmin) * 255 + 0.5), 0, 255)
    rgb = lut[np.where(finite, idx, 0).astype(np.uint8)]
    rgb[~finite] = (160, 160, 160)
    x0, x1, y0, y1 = extent
    aspect = (y1 - y0) / (x1 - x0)
    w, h = (size, max(int(size * aspect), 1)) if aspect <= 1 else (max(int(size / aspect), 1), size)
    im = Image.fromarray(np.ascontiguousarray(rgb[::-1]))
    im = im.resize((w, h), Image.Resampling.BOX if im.width >= w else Image.Resampling.NEAREST)
    f, fs = _font(12), _font(11)
    nlines = title.count("\n") + 1 if title else 0
    left, top, bar = 70, 12 + 16 * nlines, 18
    W, H = left + w + 30 + bar + 80, top + h + 50
    canvas = Image.new("RGB", (W, H), "white")
    canvas.paste(im, (left, top))
    dr = ImageDraw.Draw(canvas)
    dr.rectangle([left - 1, top - 1, left + w, top + h], outline="black")
    for i, line in enumerate(title.splitlines()):
        tw = dr.textlength(line, font=f)
        dr.text(((W - tw) / 2, 6 + 16 * i), line, fill="black", font=f)
    xt = _ticks(x0, x1)
    for t in xt:
        px = left + (t - x0) / (x1 - x0) * w
        dr.line([px, top + h, px, top + h + 4], fill="black")
        s = _fmt(t, xt[1] - xt[0] if len(xt) > 1 else None)
        dr.text((px - dr.textlength(s, font=fs) / 2, top + h + 6), s, fill="black", font=fs)
    dr.text((left + w / 2 - 20, top + h + 24), "x (mm)", fill="black", font=f)
    yt = _ticks(y0, y1)
    for t in yt:
        py = top + h - (t - y0) / (y1 - y0) * h
        dr.line([left - 5, py, left - 1, py], fill="black")
        s = _fmt(t, yt[1] - yt[0] if len(yt) > 1 else None)
        dr.text((left - 8 - dr.textlength(s, font=fs), py - 7), s, fill="black", font=fs)
    ylab = Image.new("RGB", (60, 16), "white")
    ImageDraw.Draw(ylab).text((0, 0), "y (mm)", fill="black", font=f)
    canvas.paste(ylab.rotate(90, expand=True), (4, top + h // 2 - 30))
    bx = left + w + 30
    ramp = lut[np.linspace(255, 0, h).astype(np.uint8)]
    canvas.paste(Image.fromarray(np.repeat(ramp[:, None, :], bar, axis=1)), (bx, top))
    dr.rectangle([bx - 1, top - 1, bx + bar, top + h], outline="black")
    vt = _ticks(vmin, vmax)
    for t in vt:
        py = top + h - (t - vmin) / (vmax - vmin) * h
        dr.line([bx + bar, py, bx + bar + 4, py], fill="black")
        dr.text((bx + bar + 7, py - 7), _fmt(t, vt[1] - vt[0] if len(vt) > 1 else None), fill="black", font=fs)
    if label:
        lab = Image.new("RGB", (int(dr.textlength(label, font=fs)) + 4, 14), "white")
        ImageDraw.Draw(lab).text((0, 0), label, fill="black", font=fs)
        lab = lab.rotate(90, expand=True)
        canvas.paste(lab, (W - 16, max(top + h // 2 - lab.height // 2, 0)))
    return canvas


def panels_png(path: str | Path, panels: list[dict], *, title: str = "", width: int = 560,
               height: int = 200) -> Path:
    """Stacked line panels, written atomically.  Each panel: ``x``, ``lo``, ``hi`` (equal
    arrays for a plain line; a filled band between them otherwise), ``xlabel``,
    ``ylabel`` and an optional ``title``."""
    from PIL import Image, ImageDraw

    f, fs = _font(12), _font(11)
    left, right, gap = 80, 20, 58
    ttl = 18 * (title.count("\n") + 1) if title else 0
    W = left + width + right
    H = ttl + len(panels) * (height + gap) + 10
    canvas = Image.new("RGB", (W, H), "white")
    dr = ImageDraw.Draw(canvas)
    for i, line in enumerate(title.splitlines()):
        dr.text(((W - dr.textlength(line, font=f)) / 2, 4 + 18 * i), line, fill="black", font=f)
    for k, p in enumerate(panels):
        top = ttl + k * (height + gap) + (18 if p.get("title") else 6)
        x, lo, hi = (np.asarray(p[n], dtype=np.float64) for n in ("x", "lo", "hi"))
        ok = np.isfinite(x) & np.isfinite(lo) & np.isfinite(hi)
        x, lo, hi = x[ok], lo[ok], hi[ok]
        if p.get("title"):
            dr.text((left, top - 16), p["title"], fill="black", font=fs)
        dr.rectangle([left, top, left + width, top + height], outline="black")
        if x.size == 0:
            continue
        xa, xb = float(x.min()), float(x.max())
        ya, yb = float(lo.min()), float(hi.max())
        if xb <= xa:
            xb = xa + 1.0
        if yb <= ya:
            ya, yb = ya - 0.5 * (abs(ya) or 1.0), yb + 0.5 * (abs(yb) or 1.0)
        pad = 0.05 * (yb - ya)
        ya, yb = ya - pad, yb + pad

        def X(v):
            return left + (v - xa) / (xb - xa) * width

        def Y(v):
            return top + height - (v - ya) / (yb - ya) * height

        off = _offset(ya, yb)
        yt = _ticks(ya - off, yb - off, 4)
        for t in yt:
            py = Y(t + off)
            dr.line([left, py, left + width, py], fill=(225, 225, 225))
            s = _fmt(t, yt[1] - yt[0] if len(yt) > 1 else None)
            dr.text((left - 6 - dr.textlength(s, font=fs), py - 7), s, fill="black", font=fs)
        if off:
            q = max(0, -math.floor(math.log10(abs(yb - ya))) + 1)
            note = f"values {'+' if off > 0 else '-'} {abs(off):.{q}f}"
            dr.text((left + width - dr.textlength(note, font=fs) - 4, top + 2), note, fill="black", font=fs)
        xt = _ticks(xa, xb, 6)
        for t in xt:
            px = X(t)
            dr.line([px, top + height, px, top + height + 4], fill="black")
            s = _fmt(t, xt[1] - xt[0] if len(xt) > 1 else None)
            dr.text((px - dr.textlength(s, font=fs) / 2, top + height + 6), s, fill="black", font=fs)
        px, pl, ph = X(x), Y(lo), Y(hi)
        if not np.array_equal(lo, hi):
            for a, b, c in zip(px, pl, ph):
                dr.line([a, b, a, c], fill=(140, 170, 210))
        dr.line(list(zip(px, pl)), fill=(31, 90, 160), width=1)
        if not np.array_equal(lo, hi):
            dr.line(list(zip(px, ph)), fill=(31, 90, 160), width=1)
        dr.text((left + width / 2 - dr.textlength(p["xlabel"], font=fs) / 2, top + height + 22), p["xlabel"],
                fill="black", font=fs)
        lab = Image.new("RGB", (int(dr.textlength(p["ylabel"], font=fs)) + 4, 14), "white")
        ImageDraw.Draw(lab).text((0, 0), p["ylabel"], fill="black", font=fs)
        lab = lab.rotate(90, expand=True)
        canvas.paste(lab, (2, int(top + height / 2 - lab.height / 2)))
    return atomic_write_bytes(path, _png(canvas))
