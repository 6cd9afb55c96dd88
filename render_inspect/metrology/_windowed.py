"""ISO 25178-2 parameters of a height map too large for memory, from bands of rows.

A map held in a chunked store is read band by band, twice:

1. the form fit: the least-squares plane or polynomial of degree 2 (the Legendre basis
   of :func:`~render_inspect.metrology.remove_form`) from the sums of its normal
   equations over the measured points (``A^T A`` and ``A^T z`` add up across bands);
   the mean of the residual follows from the same sums;
2. the residual's parameters: Sa, Sq, Sp, Sv, Sz, Ssk, Sku from sums of ``|d|``,
   ``d^2``, ``d^3``, ``d^4`` and the extremes (``d`` the residual less its mean), Sdq
   and Sdr from the gradient and area sums of
   :func:`~render_inspect.metrology.forward_slope_sums` (each band with the two rows
   after it) or the central differences (each band with one row either side).

These are the whole map's values (the same sums in another order: equal to the in-memory
:func:`~render_inspect.metrology.analyze_map` to about 1e-12).  What needs the whole map
at once is not done window by window: the S- and L-filters (a Gaussian convolution
across the field), the sphere (a non-linear fit), the outlier rule (a robust sigma of the
whole map); :func:`windowed_refusal` names them.  Sal and Str (the autocorrelation of the
whole field) come from a coarser view of the map (a pyramid level of area means) when
one is given, and the metrics say which.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import math
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.limits import MAX_ABS_MM, MOSTLY_EMPTY_FRACTION, mostly_empty_warning
from ..core.units import MM_TO_UM
from ._analysis import Analysis, areal_metrics, hole_border_facts
from ._filters import _legendre_design, pixel_xy
from ._params import SLOPE_ESTIMATORS, forward_slope_sums, spatial_parameters

__all__ = ["WINDOWED_FORMS", "windowed_refusal", "analyze_bands", "band_bytes_per_point",
           "form_on_grid"]

#: form removals done window by window (the others need the whole map)
WINDOWED_FORMS = ("none", "plane", "poly2")
_DEGREE = {"plane": 1, "poly2": 2}
#: a decay length from the coarse view is given only when it spans at least this many of
#: its pixels
MIN_RESOLVED_PIXELS = 2
#: float64 values held per map point of a band at its peak (the band, its mask and
#: residual, the form's basis (up to 6 terms) and the slope step's arrays)
_BAND_VALUES = {"none": 10, "plane": 14, "poly2": 18}


def band_bytes_per_point(form: str) -> float:
    """Bytes a band holds per map point at its peak (for choosing the band's rows)."""
    return 8.0 * _BAND_VALUES.get(form, 18)


def windowed_refusal(*, form: str, s_filter_mm: float | None = None,
                     l_filter_mm: float | None = None, outliers: str = "none",
                     x3p: bool = False) -> str | None:
    """What among these options needs the whole map in memory at once (None: nothing)."""
    why = []
    if form not in WINDOWED_FORMS:
        why.append(f"--form {form} (a non-linear fit over the whole map; --form "
                   f"{', '.join(WINDOWED_FORMS)} are fitted window by window)")
    if s_filter_mm or l_filter_mm:
        why.append("--filter (a Gaussian convolution across the field)")
    if outliers != "none":
        why.append(f"--outliers {outliers} (a robust sigma of the whole map)")
    if x3p:
        why.append("--x3p (the evaluated surface written whole)")
    return "; ".join(why) or None


def _uv(n: int) -> np.ndarray:
    return np.linspace(-1.0, 1.0, n) if n > 1 else np.zeros(1)


def form_on_grid(coef: np.ndarray, shape: tuple[int, ...], rows: slice, *, factor: int = 1,
                 form: str = "plane") -> np.ndarray:
    """The fitted form (Legendre coefficients of the full map of ``shape``) on rows
    ``rows`` of the map, or of a level of ``factor`` whose pixel centres sit at the
    centres of ``factor`` x ``factor`` blocks."""
    ny, nx = shape
    if form == "none":
        return np.full(((rows.stop - rows.start), -(-nx // factor)), float(coef[0]))
    if factor == 1:
        u = _uv(nx)
        v = _uv(ny)[rows]
    else:
        cu = (np.arange(-(-nx // factor)) * factor + (factor - 1) / 2.0)
        cv = (np.arange(rows.start, rows.stop) * factor + (factor - 1) / 2.0)
        u = -1.0 + 2.0 * cu / max(nx - 1, 1)
        v = -1.0 + 2.0 * cv / max(ny - 1, 1)
    uu, vv = np.meshgrid(u, v)
    return _legendre_design(uu, vv, _DEGREE[form]) @ np.asarray(coef)


def _bands(ny: int, rows: int):
    for r0 in range(0, ny, rows):
        yield r0, min(r0 + rows, ny)


def analyze_bands(read: Callable[[int, int], np.ndarray], shape: tuple[int, ...], *,
                  pixel: float | tuple[float, float], origin: Sequence[float] = (0.0, 0.0),
                  form: str = "plane",
                  slope: str = "forward", band_rows: int = 1024, spatial: tuple[np.ndarray, int, str] | None = None,
                  acf_threshold: float = 0.2, source: dict | None = None,
                  progress: Callable[[int, int], None] | None = None) -> Analysis:
    """The parameters of :func:`~render_inspect.metrology.analyze_map` (without filters,
    sphere or outliers: :func:`windowed_refusal`) of a map read in bands of rows.

    Parameters
    ----------
    read : callable(r0, r1) -> (r1 - r0, nx) float array
        Rows ``r0`` .. ``r1 - 1`` of the map, mm (NaN = not measured).
    shape : (ny, nx)
    pixel : float or (pixel_x, pixel_y), mm
    origin : (x, y) of pixel [0, 0], mm
    form : {"none", "plane", "poly2"}
    slope : {"forward", "central"}
    band_rows : int
        Rows per band (the memory held is about ``band_rows x nx x``
        :func:`band_bytes_per_point`).
    spatial : (z, factor, note), optional
        A coarser view of the map (area means of ``factor`` x ``factor`` blocks) for Sal
        and Str; ``note`` says what it is.  Without it Sal and Str are None.
    progress : callable(done, total), optional
        Called after each band of each pass.

    Returns
    -------
    Analysis
        ``metrics`` as :func:`analyze_map`'s (``outliers.count`` None: not counted),
        plus ``windowed`` = {band_rows, passes, spatial}; ``height`` is the coarse view's
        residual (or None).
    """
    if form not in WINDOWED_FORMS:
        raise InputError(f"form must be one of {WINDOWED_FORMS} window by window, got {form!r}")
    if slope not in SLOPE_ESTIMATORS:
        raise InputError(f"slope must be one of {SLOPE_ESTIMATORS}, got {slope!r}")
    px, py = pixel_xy(pixel)
    ny, nx = (int(shape[0]), int(shape[1]))
    if ny < 3 or nx < 3:
        raise InputError(f"analyze: the map must be at least 3 x 3 points, got {ny} x {nx}")
    band_rows = max(int(band_rows), 2)
    bands = list(_bands(ny, band_rows))
    total = 2 * len(bands)
    step = [0]

    def tick():
        step[0] += 1
        if progress is not None:
            progress(step[0], total)

    # ---- pass 1: the form's normal equations, the measured points, the largest height
    deg = _DEGREE.get(form)
    nterms = (deg + 1) * (deg + 2) // 2 if deg else 1
    ata = np.zeros((nterms, nterms))
    atz = np.zeros(nterms)
    n_measured = 0
    big = 0.0
    u = _uv(nx)
    v_all = _uv(ny)
    for r0, r1 in bands:
        z = np.asarray(read(r0, r1), dtype=np.float64)
        ok = np.isfinite(z)
        n = int(ok.sum())
        if n:
            n_measured += n
            big = max(big, float(np.max(np.abs(z), where=ok, initial=0.0)))
            if deg:
                uu, vv = np.meshgrid(u, v_all[r0:r1])
                a = _legendre_design(uu[ok], vv[ok], deg)
                ata += a.T @ a
                atz += a.T @ z[ok]
                del a, uu, vv
            else:
                ata[0, 0] += n
                atz[0] += float(np.sum(z[ok]))
        del z, ok
        tick()
    if n_measured < 10:
        raise InputError(f"analyze_map: need at least 10 valid points, got {n_measured}")
    if big > MAX_ABS_MM:
        raise InputError(f"analyze_map: heights must lie within +-{MAX_ABS_MM:g} mm, received "
                         f"values up to {big:.3g} mm (heights are in mm)")
    if deg and n_measured < nterms:
        raise InputError(f"remove_form: {form} needs at least {nterms} valid points, the map "
                         f"has {n_measured}")
    coef = np.linalg.lstsq(ata, atz, rcond=None)[0]
    # the residual's sum follows from the normal equations (the constant term's column)
    mean = float((atz[0] - ata[0] @ coef) / n_measured)
    holes = n_measured < ny * nx

    # ---- pass 2: the residual's moments, extremes and slopes
    s_abs = s2 = s3 = s4 = 0.0
    dmax, dmin = -math.inf, math.inf
    g2_sum, g2_n = np.zeros(2), np.zeros(2, np.int64)
    area_sum, area_n = np.zeros(2), np.zeros(2, np.int64)
    c_g2 = c_area = 0.0
    c_n = 0
    for r0, r1 in bands:
        a0 = max(r0 - 1, 0)
        a1 = min(r1 + 2, ny)
        z = np.asarray(read(a0, a1), dtype=np.float64)
        res = z - form_on_grid(coef, (ny, nx), slice(a0, a1), form=form)
        del z
        ok = np.isfinite(res)
        own = slice(r0 - a0, r1 - a0)
        d = res[own][ok[own]] - mean
        if d.size:
            ad = np.abs(d)
            s_abs += float(ad.sum())
            d2 = d * d
            s2 += float(d2.sum())
            s3 += float((d2 * d).sum())
            s4 += float((d2 * d2).sum())
            dmax = max(dmax, float(d.max()))
            dmin = min(dmin, float(d.min()))
            del ad, d2
        del d
        if slope == "forward":
            c1 = min(r1, ny - 1)  # corners r0 .. c1 - 1 (the last row has none)
            if c1 > r0:
                g, gn, ar, an = forward_slope_sums(res, ok, (px, py), (r0 - a0, c1 - a0),
                                                   holes=holes)
                g2_sum += g
                g2_n += gn
                area_sum += ar
                area_n += an
        else:
            zz = np.where(ok, res, np.nan)
            gy, gx = np.gradient(zz, py, px)
            g2 = (gx * gx + gy * gy)[own]
            del gx, gy, zz
            gok = np.isfinite(g2)
            c_g2 += float(g2[gok].sum())
            c_area += float((np.sqrt(1.0 + g2[gok]) - 1.0).sum())
            c_n += int(gok.sum())
        del res, ok
        tick()
    n = n_measured
    sq = math.sqrt(s2 / n)
    p = {"Sa": s_abs / n, "Sq": sq, "Sp": dmax, "Sv": -dmin, "Sz": dmax - dmin,
         "Ssk": (s3 / n) / sq ** 3 if sq > 0 else 0.0,
         "Sku": (s4 / n) / sq ** 4 if sq > 0 else 0.0, "n_valid": n}
    nan = float("nan")
    if slope == "forward":
        sdq = [math.sqrt(g2_sum[k] / g2_n[k]) if g2_n[k] else nan for k in (0, 1)]
        sdr = [100.0 * (area_sum[k] / (area_n[k] * px * py) - 1.0) if area_n[k] else nan
               for k in (0, 1)]
        p.update(Sdq=sdq[0], Sdr=sdr[0], Sdq_with_border=sdq[1], Sdr_with_border=sdr[1],
                 n_border=int(g2_n[1] - g2_n[0]))
    else:
        p.update(Sdq=math.sqrt(c_g2 / c_n) if c_n else nan,
                 Sdr=100.0 * c_area / c_n if c_n else nan)
    warnings_ = [f"analysed window by window in {len(bands)} bands of {band_rows} rows (the "
                 f"whole map is not held in memory at once): the height parameters and slopes "
                 f"are the whole map's; outliers are not counted"]
    if n_measured < (1.0 - MOSTLY_EMPTY_FRACTION) * ny * nx:
        warnings_.append(mostly_empty_warning(1.0 - n_measured / (ny * nx)))
    holes_info = None
    if "n_border" in p and holes:
        holes_info = hole_border_facts(p, n_total=ny * nx, n_valid=n, warnings=warnings_)
    # ---- Sal and Str from the coarse view
    sp = {"Sal_mm": None, "Str": None, "decays_in_all_directions": None,
          "fastest_direction_rad": None, "slowest_direction_rad": None, "longest_decay_mm": None}
    spatial_note = "not computed (the whole field is not held in memory at once)"
    height = None
    if spatial is not None:
        zc, factor, note = spatial
        zc = np.asarray(zc, dtype=np.float64)
        height = zc - form_on_grid(coef, (ny, nx), slice(0, zc.shape[0]), factor=factor,
                                   form=form)
        height -= np.nanmean(height)
        coarse = max(px, py) * factor
        if np.isfinite(height).sum() >= 10 and min(height.shape) >= 3:
            sp = spatial_parameters(height, pixel=(px * factor, py * factor), s=acf_threshold)
            sal = sp.get("Sal_mm")
            if sal is not None and math.isfinite(sal) and sal < MIN_RESOLVED_PIXELS * coarse:
                warnings_.append(
                    f"Sal and Str not given: at the {coarse * MM_TO_UM:.4g} um sampling of {note} "
                    f"(the whole field at full resolution is not held in memory at once) the "
                    f"autocorrelation decays within {MIN_RESOLVED_PIXELS} pixels ({sal * MM_TO_UM:.3g} "
                    f"um), too short to resolve")
                sp = {k: None for k in sp}
                spatial_note = f"not resolved by {note}"
            else:
                spatial_note = note
                warnings_.append(f"Sal and Str come from {note}: the autocorrelation of the map "
                                 f"seen at {coarse * MM_TO_UM:.4g} um sampling (the whole field at "
                                 f"full resolution is not held in memory at once)")
    if sp.get("decays_in_all_directions") is False:
        warnings_.append(f"Str undefined: the autocorrelation stays above s = {acf_threshold:g} "
                         f"across the field in at least one direction (a lay longer than the field)")
    areal, ang = areal_metrics(p, sp)
    form_info: dict[str, Any] = {"method": form}
    if form == "poly2":
        form_info["degree"] = 2
    src = {k: val for k, val in (source or {}).items() if k != "scene"}
    metrics = {
        "areal": {k: _finite(val) for k, val in areal.items()},
        "pixel_mm": [px, py], "shape": [ny, nx],
        "origin_mm": [float(origin[0]), float(origin[1])],
        "field_mm": [px * nx, py * ny],
        "valid_fraction": n / (ny * nx), "measured_fraction": n / (ny * nx), "n_valid": n,
        "units": {"lateral": "mm", "heights": "nm (keys *_nm); maps and files in mm",
                  "Sdq": "1 (rms slope, dz/dx)", "Sdr_percent": "%", "Sal_mm": "mm",
                  "Str": "1", "pixel_mm": "mm", "in_file": src.get("units_in_file")},
        "form": form_info,
        "filter": {"S_mm": None, "L_mm": None, "kind": "ISO 16610-61 Gaussian (masked, normalised)"},
        "outliers": {"method": "none", "sigma": None, "count": None, "fraction": None,
                     "left_out": False, "rule": "not counted on a map analysed window by window"},
        "slope_estimator": slope,
        "spatial": {"s": acf_threshold, "decays_in_all_directions": sp.get("decays_in_all_directions"),
                    "fastest_direction_deg": ang["fastest_direction_rad"],
                    "slowest_direction_deg": ang["slowest_direction_rad"],
                    "longest_decay_mm": _finite(sp.get("longest_decay_mm")),
                    "source": spatial_note},
        "windowed": {"band_rows": band_rows, "bands": len(bands), "passes": 2,
                     "spatial": spatial_note},
        "warnings": warnings_,
        "source": src,
    }
    if holes_info is not None:
        metrics["holes"] = holes_info
    return Analysis(metrics, height, None)


def _finite(v):
    if v is None:
        return None
    v = float(v)
    return v if math.isfinite(v) else None
