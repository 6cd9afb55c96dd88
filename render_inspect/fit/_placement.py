"""Where the measured field lies on the part, and which part of it is fitted.

The field is placed in the scene's coordinates from the file's origin (a ``height.exr``
written by ``measure`` carries the scene's coordinates), at a given centre (``--at X,Y``),
or by registration: a normalised cross-correlation of the measured map with the design over
the scene's region gives the translation, refined by the least-squares rigid registration of
:mod:`render_inspect.metrology` (translation, piston and tilts)."""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.lazy import lazy_attr
from ..core.units import MM_TO_NM
from ..metrology import register_lsq, remove_form

#: SciPy, imported on first use (render_inspect.core.lazy): every run imports this module
fftconvolve = lazy_attr("scipy.signal", "fftconvolve")

__all__ = ["field_extent", "centred_origin", "fit_window", "register_field", "check_units"]

#: smallest fit window, pixels a side
MIN_WINDOW_PX = 32


def field_extent(shape: tuple[int, ...], pixel: Sequence[float], origin: Sequence[float]) -> tuple:
    """(x0, y0, x1, y1): the pixel edges of a map, mm."""
    ny, nx = shape
    px, py = pixel
    return (origin[0] - px / 2, origin[1] - py / 2, origin[0] + px * (nx - 0.5),
            origin[1] + py * (ny - 0.5))


def centred_origin(shape: tuple[int, ...], pixel: Sequence[float],
                   centre: Sequence[float]) -> tuple:
    """The origin (pixel [0, 0]'s centre) that puts the field's centre at ``centre``."""
    ny, nx = shape
    px, py = pixel
    return (centre[0] - px * (nx - 1) / 2, centre[1] - py * (ny - 1) / 2)


def _fmt(box) -> str:
    return f"x {box[0]:.4g}..{box[2]:.4g}, y {box[1]:.4g}..{box[3]:.4g} mm"


def fit_window(z: np.ndarray, pixel: Sequence[float], origin: Sequence[float],
               region: Sequence[float], size_mm: float, *, how: str = "") -> tuple:
    """(rows, cols) slices of the fit window: the central square of at most ``size_mm``
    inside the overlap of the measured field and the scene's ``region``, moved onto the
    densest valid part of that overlap when its centre is not measured."""
    ext = field_extent(z.shape, pixel, origin)
    x0, y0 = max(ext[0], region[0]), max(ext[1], region[1])
    x1, y1 = min(ext[2], region[2]), min(ext[3], region[3])
    if x1 <= x0 or y1 <= y0:
        raise InputError(f"the measured field ({_fmt(ext)}, placed {how}) does not overlap the "
                         f"scene's simulation.region {list(region)}: place the field with "
                         f"--at X,Y (its centre, mm) or --at register, or move the region")
    px, py = pixel
    c0 = int(math.ceil((x0 - ext[0]) / px - 1e-9))
    c1 = int(math.floor((x1 - ext[0]) / px + 1e-9))
    r0 = int(math.ceil((y0 - ext[1]) / py - 1e-9))
    r1 = int(math.floor((y1 - ext[1]) / py + 1e-9))
    nx = min(c1 - c0, int(math.floor(size_mm / px + 1e-9)))
    ny = min(r1 - r0, int(math.floor(size_mm / py + 1e-9)))
    n = min(nx, ny)
    if n < MIN_WINDOW_PX:
        raise InputError(f"the measured field overlaps the scene's region by {c1 - c0} x "
                         f"{r1 - r0} pixels (field {_fmt(ext)}, placed {how}; region "
                         f"{list(region)}); at least {MIN_WINDOW_PX} x {MIN_WINDOW_PX} are needed "
                         f"(--window {size_mm:g} mm)")
    ok = np.isfinite(z)
    # the n x n square of the overlap with the most valid points, centred when equal
    sub = ok[r0:r1, c0:c1].astype(np.float64)
    cs = np.pad(sub.cumsum(0).cumsum(1), ((1, 0), (1, 0)))
    counts = cs[n:, n:] - cs[:-n, n:] - cs[n:, :-n] + cs[:-n, :-n]
    cy, cx = (counts.shape[0] - 1) / 2, (counts.shape[1] - 1) / 2
    yy, xx = np.mgrid[:counts.shape[0], :counts.shape[1]]
    score = counts - 1e-6 * np.hypot(yy - cy, xx - cx)  # not a unit conversion
    i, j = np.unravel_index(int(np.argmax(score)), score.shape)
    if counts[i, j] < 0.5 * n * n:
        raise InputError(f"the fit window has {int(counts[i, j])} of {n * n} pixels measured; at "
                         f"least half are needed (choose another --window or place the field "
                         f"elsewhere)")
    return slice(r0 + i, r0 + i + n), slice(c0 + j, c0 + j + n)


def register_field(z: np.ndarray, pixel: Sequence[float], design: Any, region: Sequence[float], *,
                   max_side: int = 512) -> dict:
    """Find where a measured map lies on the design inside ``region`` (mm).

    Both the map and the design (sampled over the region at the map's pixel) lose their
    best-fit plane; the normalised cross-correlation's peak gives the translation, which
    :func:`~render_inspect.metrology.register_lsq` refines (translation, piston and tilts).

    Returns
    -------
    dict
        ``origin_mm`` (the map's pixel [0, 0] centre in scene coordinates), ``peak`` (the
        correlation at the match), ``peak_ratio`` (the second-best separated peak over the
        best: near 1 means the match is ambiguous, e.g. a periodic or flat design),
        ``registration`` (the refinement's result).
    """
    px, py = pixel
    zz = np.asarray(z, dtype=np.float64)
    ny, nx = zz.shape
    step = max(1, int(math.ceil(max(ny, nx) / max_side)))
    t = zz[::step, ::step]
    sx, sy = px * step, py * step
    rx = np.arange(region[0] + sx / 2, region[2], sx)
    ry = np.arange(region[1] + sy / 2, region[3], sy)
    if rx.size < t.shape[1] or ry.size < t.shape[0]:
        raise InputError(f"--at register: the measured field ({nx * px:.4g} x {ny * py:.4g} mm) "
                         f"is larger than the scene's simulation.region {list(region)}; enlarge "
                         f"the region to search in")
    d = np.asarray(design.height(rx[None, :], ry[:, None]), dtype=np.float64)
    d, _ = remove_form(d, pixel=(sx, sy), method="plane")
    t, _ = remove_form(t, pixel=(sx, sy), method="plane")
    ok = np.isfinite(t)
    tm = np.where(ok, t - np.mean(t[ok]), 0.0)
    m = ok.astype(np.float64)
    dd = np.nan_to_num(d)
    num = fftconvolve(dd, tm[::-1, ::-1], mode="valid")
    s1 = fftconvolve(dd, m[::-1, ::-1], mode="valid")
    s2 = fftconvolve(dd * dd, m[::-1, ::-1], mode="valid")
    cnt = m.sum()
    # the design under each placement loses its own best plane too (the template has lost
    # its): the variance less the projections on the window's constant and two ramps
    yy, xx = np.mgrid[:t.shape[0], :t.shape[1]].astype(np.float64)
    var_d = s2 - s1 * s1 / cnt
    for ramp in (xx, yy):
        r = (ramp - np.sum(ramp * m) / cnt) * m
        sr = fftconvolve(dd, r[::-1, ::-1], mode="valid")
        var_d = var_d - sr * sr / max(float(np.sum(r * r)), 1e-300)
    var_d = np.maximum(var_d, 1e-300)
    ncc = num / np.sqrt(var_d * float(np.sum(tm * tm)) + 1e-300)
    i, j = np.unravel_index(int(np.argmax(ncc)), ncc.shape)
    peak = float(ncc[i, j])
    # the best peak at least half the field away
    far = np.ones_like(ncc, dtype=bool)
    ri = max(1, t.shape[0] // 2)
    rj = max(1, t.shape[1] // 2)
    far[max(0, i - ri):i + ri + 1, max(0, j - rj):j + rj + 1] = False
    second = float(ncc[far].max()) if far.any() else float("nan")
    origin0 = (rx[j] - sx / 2 + px / 2, ry[i] - sy / 2 + py / 2)
    # refine: the design moved into the measured frame; the map keeps its file coordinates
    reg = register_lsq(zz, design, pixel=(px, py), origin=origin0,
                       fit=("tx", "ty", "tz", "alpha", "beta"), max_points=40_000)
    origin = (origin0[0] - reg["tx_mm"], origin0[1] - reg["ty_mm"])
    return {"origin_mm": [float(origin[0]), float(origin[1])], "peak": peak,
            "peak_ratio": second / peak if peak > 0 else None,
            "registration": {k: v for k, v in reg.items() if k != "sigma_formal"}}


def check_units(measured_rms_mm: float, predicted_rms_mm: float, *, limit: float = 100.0) -> None:
    """Refuse a fit whose measured and predicted roughness (form removed) differ by more
    than ``limit`` times: a map in micrometres read as millimetres (or the reverse)."""
    if not (measured_rms_mm > 0 and predicted_rms_mm > 0):
        return
    ratio = measured_rms_mm / predicted_rms_mm
    if not 1.0 / limit < ratio < limit:
        raise InputError(f"unit mismatch: the measured map's rms height (form removed) is "
                         f"{measured_rms_mm * MM_TO_NM:.4g} nm but the scene predicts "
                         f"{predicted_rms_mm * MM_TO_NM:.4g} nm at its own values (ratio "
                         f"{ratio:.3g}); "
                         f"the file's height unit is probably wrong, or the scene does not "
                         f"describe this part")
