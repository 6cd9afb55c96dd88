"""One height map in, the ISO 25178-2 parameters a metrologist asks for out.

Chain: outliers (off by default) -> form removal (none | plane | poly2 | sphere) ->
ISO 16610-61 S- and L-filters -> Sa, Sq, Sz, Sp, Sv, Ssk, Sku, Sdq, Sdr, Sal, Str.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.errors import InputError, check_positive
from ..core.limits import MAX_ABS_MM, MOSTLY_EMPTY_FRACTION, check_memory, mostly_empty_warning
from ..core.units import MIB_TO_BYTES, MM_TO_NM, MM_TO_UM, UM_TO_MM
from ._filters import fit_sphere, l_filter, pixel_xy, remove_form, s_filter, valid_mask
from ._params import SLOPE_ESTIMATORS, areal_parameters, spatial_parameters
from ._registration import detect_outliers

__all__ = ["FORMS", "OUTLIER_METHODS", "Analysis", "analyze_map", "parse_filter",
           "check_filter", "filter_range", "analyze_memory", "analyze_memory_per_point",
           "ANALYZE_BYTES_PER_POINT"]

#: Form removal choices of :func:`analyze_map`.
FORMS = ("none", "plane", "poly2", "sphere")
#: Outlier choices of :func:`analyze_map`.
OUTLIER_METHODS = ("none", "sigma")
#: Sdq or Sdr with the hole borders differing by more than this share gets a warning
HOLE_BORDER_WARN = 0.05
HOLE_BORDER_RULE = ("gradients and Sdr cells whose stencil, or the next point beyond it in "
                    "+x or +y, is not measured are left out (SurfaceTopography's rms_gradient)")


@dataclass
class Analysis:
    """Result of :func:`analyze_map`.

    Attributes
    ----------
    metrics : dict
        JSON-able (see :func:`analyze_map`).
    height : (ny, nx) array or None
        The evaluated surface (outliers left out, form removed, filtered), mm (None when
        a map analysed window by window is not kept whole).
    outliers : (ny, nx) bool array or None
        Points flagged as outliers (all False when outliers are off; None when not
        counted).
    """

    metrics: dict
    height: np.ndarray | None
    outliers: np.ndarray | None = field(default=None)


def parse_filter(text: str | None) -> tuple[float | None, float | None]:
    """``"S,L"`` (mm; either may be empty or 0 for none) -> ``(s_mm, l_mm)``."""
    if text is None or str(text).strip() == "":
        return None, None
    parts = [p.strip() for p in str(text).split(",")]
    if len(parts) != 2:
        raise InputError(f"--filter must be 'S,L' (nesting indices in mm, e.g. '0.0025,0.8' or "
                         f"',0.8'), received {str(text)[:80]!r}")
    out: list[float | None] = []
    for name, p in zip(("S", "L"), parts):
        if p == "":
            out.append(None)
            continue
        try:
            v = float(p)
        except ValueError:
            raise InputError(f"--filter {name} must be a number of mm >= 0, received "
                             f"{p[:40]!r}") from None
        if not (math.isfinite(v) and v >= 0):
            raise InputError(f"--filter {name} must be a finite number of mm >= 0, received "
                             f"{p[:40]!r}")
        out.append(v or None)
    s_mm, l_mm = out
    if s_mm and l_mm and not l_mm > s_mm:
        raise InputError(f"--filter L must be longer than S, received S {s_mm:g} mm and L "
                         f"{l_mm:g} mm")
    return s_mm, l_mm


def filter_range(pixel: float | tuple[float, float], shape: tuple[int, ...]) -> tuple[float, float]:
    """(shortest, longest) nesting index in mm a filter may have on a map of ``shape``
    (rows, columns) with ``pixel`` (mm, one number or (x, y)): two of the larger pixel,
    and the smaller side of the field."""
    px, py = pixel_xy(pixel)
    ny, nx = int(shape[0]), int(shape[1])
    return 2.0 * max(px, py), min(px * nx, py * ny)


def check_filter(s_mm: float | None, l_mm: float | None, *, pixel: float | tuple[float, float],
                 shape: tuple[int, ...], option: str = "--filter") -> None:
    """Refuse S- and L-filter nesting indices (mm) that this map cannot carry: shorter
    than two pixels or longer than the field's smaller side (:func:`filter_range`), with
    one line naming ``option``, the unit, the allowed range and the value, and, when the
    values read as micrometres would fit, the values that were probably meant."""
    lo, hi = filter_range(pixel, shape)
    px, py = pixel_xy(pixel)
    ny, nx = int(shape[0]), int(shape[1])
    values = {"S": s_mm, "L": l_mm}
    for name, v in values.items():
        if v is None:
            continue
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise InputError(f"{option} {name} must be a number of mm, received {v!r}") from None
        if not math.isfinite(v) or v <= 0:
            raise InputError(f"{option} {name} must be a number of mm > 0, received {v!r}")
        if lo <= v <= hi:
            continue
        where = "shorter than two pixels" if v < lo else "longer than the map"
        msg = (f"{option} {name} must lie within {lo:.3g} .. {hi:.3g} mm on this map "
               f"({nx} x {ny} points of {px:.3g} x {py:.3g} mm: two pixels to the field's "
               f"smaller side), received {v:.6g} mm ({where})")
        as_um = {k: (float(x) * UM_TO_MM if x is not None else None) for k, x in values.items()}
        if v > hi and all(x is None or lo <= x <= hi for x in as_um.values()) \
                and (as_um["L"] is None or as_um["L"] >= 5 * lo):
            meant = ",".join("" if x is None else f"{x:g}" for x in as_um.values())
            msg += (f"; the value looks like micrometres: {option} {meant} (mm) was probably "
                    f"meant")
        raise InputError(msg)


#: bytes at the peak of ``analyze``, measured as the peak resident memory of the command
#: (above the interpreter's) on random 2000 x 2000 to 6000 x 6000 maps (docs/limits.md):
#: ``held`` per map point (the map, its working copies, the slopes in row blocks) plus
#: ``fft`` per point of the zero-padded grid of the autocorrelation (about 4 per map
#: point), ``holes_fft`` more on a map with missing points (the pair counts); the steps
#: ``form_poly2`` and ``outliers_sigma`` peak higher per map point by themselves.
ANALYZE_BYTES_PER_POINT = {"held": 80.0, "fft": 22.0, "holes_fft": 8.0, "form_poly2": 215.0,
                           "outliers_sigma": 215.0, "form_sphere": 180.0}
#: zero-padded FFT points per map point assumed before the map's shape is known
_FFT_PER_POINT = 4.4
#: fixed part of the estimate (figures, file buffers)
_ANALYZE_FIXED = 64 * MIB_TO_BYTES


def _fft_points(shape) -> int:
    from scipy import fft as sfft

    ny, nx = int(shape[0]), int(shape[1])
    return sfft.next_fast_len(2 * ny - 1, real=True) * sfft.next_fast_len(2 * nx - 1, real=True)


def _step_peak(form: str, outliers: str) -> float:
    b = ANALYZE_BYTES_PER_POINT
    peaks = [0.0]
    if form == "poly2":
        peaks.append(b["form_poly2"])
    if form == "sphere":
        peaks.append(b["form_sphere"])
    if outliers == "sigma":
        peaks.append(b["outliers_sigma"])
    return max(peaks)


def analyze_memory(shape: tuple[int, ...], *, form: str = "plane",
                   s_filter_mm: float | None = None, l_filter_mm: float | None = None,
                   outliers: str = "none", slope: str = "forward", holes: bool = True) -> float:
    """Bytes at the peak of ``analyze`` on a map of ``shape`` (rows, columns) with these
    options (:data:`ANALYZE_BYTES_PER_POINT`): the map, the analysis and the figures;
    reading the file peaks lower and is over by then.  ``holes``: count the pair counts
    of the autocorrelation that a map with missing points needs."""
    b = ANALYZE_BYTES_PER_POINT
    n = float(int(shape[0]) * int(shape[1]))
    spatial = b["held"] * n + (b["fft"] + (b["holes_fft"] if holes else 0.0)) * _fft_points(shape)
    return max(spatial, _step_peak(form, outliers) * n) + _ANALYZE_FIXED


def analyze_memory_per_point(*, form: str = "plane", s_filter_mm: float | None = None,
                             l_filter_mm: float | None = None,
                             outliers: str = "none", slope: str = "forward",
                             holes: bool = True) -> float:
    """:func:`analyze_memory` per map point before the map's shape is known (the padded
    FFT grid taken as 4.4 points per map point): for
    :func:`render_inspect.io.reading_for`, so that a file too large to analyse is refused
    before it is read."""
    b = ANALYZE_BYTES_PER_POINT
    spatial = b["held"] + (b["fft"] + (b["holes_fft"] if holes else 0.0)) * _FFT_PER_POINT
    return max(spatial, _step_peak(form, outliers))


def areal_metrics(p: dict, sp: dict) -> tuple[dict, dict]:
    """(``metrics["areal"]`` in the file's units: heights in nm, Sdr in %, Sal in mm; the
    texture's fastest and slowest decay directions in degrees) from the height and slope
    parameters ``p`` (mm) and the spatial ones ``sp``."""
    areal = {"Sa_nm": p["Sa"] * MM_TO_NM, "Sq_nm": p["Sq"] * MM_TO_NM, "Sz_nm": p["Sz"] * MM_TO_NM,
             "Sp_nm": p["Sp"] * MM_TO_NM, "Sv_nm": p["Sv"] * MM_TO_NM, "Ssk": p["Ssk"],
             "Sku": p["Sku"], "Sdq": p["Sdq"], "Sdr_percent": p["Sdr"], "Sal_mm": sp["Sal_mm"],
             "Str": sp["Str"]}
    ang = {k: (None if sp.get(k) is None else math.degrees(sp[k]))
           for k in ("fastest_direction_rad", "slowest_direction_rad")}
    return areal, ang


def hole_border_facts(p: dict, *, n_total: int, n_valid: int, warnings: list) -> dict:
    """``metrics["holes"]`` of a map with ``n_total - n_valid`` unmeasured points, from the
    slope parameters ``p`` (``n_border``, ``Sdq``/``Sdr`` without and ``*_with_border``
    with the gradients that border the holes); a line is appended to ``warnings`` when
    those gradients would change Sdq or Sdr by more than :data:`HOLE_BORDER_WARN`."""
    holes = {"n_unmeasured": int(n_total - n_valid),
             "unmeasured_fraction": float(1.0 - n_valid / n_total),
             "n_border_gradients": int(p["n_border"]),
             "Sdq_with_border": _nan_to_none(float(p["Sdq_with_border"])),
             "Sdr_percent_with_border": _nan_to_none(float(p["Sdr_with_border"])),
             "rule": HOLE_BORDER_RULE}
    dq = p["Sdq_with_border"] / p["Sdq"] - 1.0 if p["Sdq"] > 0 else 0.0
    dr = p["Sdr_with_border"] / p["Sdr"] - 1.0 if p["Sdr"] > 0 else 0.0
    if p["n_border"] and max(abs(dq), abs(dr)) > HOLE_BORDER_WARN:
        warnings.append(
            f"{p['n_border']} gradients border the map's {holes['n_unmeasured']} missing "
            f"points; they are left out of Sdq and Sdr (as SurfaceTopography does): with "
            f"them Sdq would be {p['Sdq_with_border']:.4g} ({dq:+.0%}) and Sdr "
            f"{p['Sdr_with_border']:.4g} % ({dr:+.0%}); see metrics holes")
    return holes


def _nan_to_none(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def analyze_map(z: Any, *, pixel: float | tuple[float, float] | None = None,
                origin: Sequence[float] = (0.0, 0.0), form: str = "plane",
                s_filter_mm: float | None = None, l_filter_mm: float | None = None,
                outliers: str = "none", outlier_sigma: float = 3.0, slope: str = "forward",
                acf_threshold: float = 0.2, source: dict | None = None,
                budget: int | tuple[int, str] | None = None,
                filter_option: str = "--filter") -> Analysis:
    """ISO 25178-2 parameters of one height map, with everything said about how.

    Parameters
    ----------
    z : (ny, nx) array, or a map object with ``z``, ``pixel``, ``origin``, ``meta``
        Heights, mm (NaN = not measured); e.g. :func:`render_inspect.io.read_surface`.
    pixel : float or (pixel_x, pixel_y)
        mm (taken from the map object when one is given).
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    form : {"none", "plane", "poly2", "sphere"}
        ``none`` removes the mean only (the parameters are about the mean); ``plane`` a
        least-squares plane; ``poly2`` a least-squares polynomial of total degree 2;
        ``sphere`` a least-squares sphere (:func:`fit_sphere`).
    s_filter_mm, l_filter_mm : float, optional
        ISO 16610-61 Gaussian nesting indices (mm): S removes shorter, L longer
        wavelengths.
    outliers : {"none", "sigma"}
        ``sigma``: points flagged by the ``outlier_sigma``-sigma spike rule
        (:func:`detect_outliers`) are left out (not replaced) of the form fit and the
        parameters; their count and fraction are reported either way.
    slope : {"forward", "central"}
        Derivative estimator of Sdq and Sdr (:func:`slope_parameters`).
    acf_threshold : float
        ``s`` of Sal / Str (ISO 25178-3 default 0.2).
    source : dict, optional
        What the file said about itself (reader, units in the file, ...), copied into
        ``metrics["source"]``.
    budget : (bytes, source) or bytes, optional
        Memory budget (default: the automatic one): a map whose analysis
        (:func:`analyze_memory`) would not fit is refused before any work.
    filter_option : str
        How messages name the filter (``--filter`` on the command line).

    The filters must lie within :func:`filter_range` (two pixels to the field's smaller
    side, :func:`check_filter`) and the heights within +-10 000 mm; a map more than half
    of which is not measured gets a warning, and on a map with missing points the
    gradients bordering them are left out of Sdq and Sdr (``metrics["holes"]`` gives
    both values; a warning when they differ by more than 5 %).

    Returns
    -------
    Analysis
        ``metrics`` holds ``areal`` = {Sa_nm, Sq_nm, Sz_nm, Sp_nm, Sv_nm, Ssk, Sku, Sdq,
        Sdr_percent, Sal_mm, Str}, ``pixel_mm`` = [x, y], ``shape`` = [rows, cols],
        ``origin_mm``, ``valid_fraction``, ``n_valid``, ``units``, ``form``, ``filter``,
        ``outliers`` = {method, sigma, count, fraction}, ``slope_estimator``, ``spatial``,
        ``warnings``, ``source`` and, on a map with missing points, ``holes`` =
        {n_unmeasured, unmeasured_fraction, n_border_gradients, Sdq_with_border,
        Sdr_percent_with_border, rule}.  Undefined values (Str when the autocorrelation does
        not decay in every direction) are None.
    """
    if hasattr(z, "z") and hasattr(z, "pixel"):
        m = z
        z, pixel, origin = m.z, m.pixel, m.origin
        if source is None:
            source = dict(getattr(m, "meta", {}) or {})
    if pixel is None:
        raise InputError("analyze_map: pixel= (mm, one number or (x, y)) is needed with an array")
    px, py = pixel_xy(pixel)
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 3:
        raise InputError(f"analyze_map: z must be a 2-D map of at least 3 x 3 points, got {z.shape}")
    if form not in FORMS:
        raise InputError(f"form must be one of {FORMS}, got {form!r}")
    if outliers not in OUTLIER_METHODS:
        raise InputError(f"outliers must be one of {OUTLIER_METHODS}, got {outliers!r}")
    if slope not in SLOPE_ESTIMATORS:
        raise InputError(f"slope must be one of {SLOPE_ESTIMATORS}, got {slope!r}")
    check_positive("outlier_sigma", outlier_sigma)
    for name, v in (("s_filter_mm", s_filter_mm), ("l_filter_mm", l_filter_mm)):
        if v is not None:
            check_positive(name, v)
    if s_filter_mm and l_filter_mm and not l_filter_mm > s_filter_mm:
        raise InputError(f"l_filter_mm ({l_filter_mm}) must be > s_filter_mm ({s_filter_mm})")
    check_filter(s_filter_mm, l_filter_mm, pixel=(px, py), shape=z.shape, option=filter_option)
    need = analyze_memory(z.shape, form=form, s_filter_mm=s_filter_mm, l_filter_mm=l_filter_mm,
                          outliers=outliers, slope=slope, holes=not np.isfinite(z).all())
    check_memory(need, what=f"analysing a {z.shape[0]} x {z.shape[1]} map", budget=budget,
                 hint="crop or resample the map (fewer points)")
    warnings_ = []
    ok = valid_mask(z)
    n_measured = int(ok.sum())
    if n_measured < 10:
        raise InputError(f"analyze_map: need at least 10 valid points, got {n_measured}")
    big = float(np.max(np.abs(z), where=ok, initial=0.0))
    if big > MAX_ABS_MM:
        raise InputError(f"analyze_map: heights must lie within +-{MAX_ABS_MM:g} mm, received "
                         f"values up to {big:.3g} mm (heights are in mm)")
    if n_measured < (1.0 - MOSTLY_EMPTY_FRACTION) * z.size:
        warnings_.append(mostly_empty_warning(1.0 - n_measured / z.size))
    _, flagged = detect_outliers(z, pixel=(px, py), k=outlier_sigma, replace=False)
    flagged &= ok
    n_flag = int(flagged.sum())
    use = ok & ~flagged if outliers == "sigma" else ok
    work = np.where(use, z, np.nan)
    form_info: dict[str, Any] = {"method": form}
    if form == "none":
        res = work - np.nanmean(work)
    elif form in ("plane", "poly2"):
        res, _ = remove_form(work, pixel=(px, py), origin=origin,
                             method="plane" if form == "plane" else "polynomial", degree=2)
        if form == "poly2":
            form_info["degree"] = 2
    else:
        fit = fit_sphere(work, pixel=(px, py), origin=origin)
        res = np.where(np.isfinite(work), work - fit["form"], np.nan)
        form_info.update({"radius_mm": _nan_to_none(fit["radius_mm"]), "apex_mm": fit["apex_mm"],
                          "fit_rms_nm": fit["rms_mm"] * MM_TO_NM})
    if s_filter_mm:
        res = s_filter(res, pixel=(px, py), nesting_index=s_filter_mm)
    if l_filter_mm:
        res = l_filter(res, pixel=(px, py), nesting_index=l_filter_mm)
    p = areal_parameters(res, pixel=(px, py), slope=slope)
    holes = None
    if "n_border" in p and p["n_valid"] < z.size:
        holes = hole_border_facts(p, n_total=z.size, n_valid=p["n_valid"], warnings=warnings_)
    sp = spatial_parameters(res, pixel=(px, py), s=acf_threshold)
    if not sp["decays_in_all_directions"]:
        warnings_.append(f"Str undefined: the autocorrelation stays above s = {acf_threshold:g} "
                         f"across the field in at least one direction (a lay longer than the field)")
    if outliers == "none" and n_flag:
        frac = n_flag / n_measured
        one = n_flag == 1
        warnings_.append(f"{n_flag} point{'' if one else 's'} ({frac:.2%}) "
                         f"{'is a spike' if one else 'are spikes'} by the {outlier_sigma:g}-sigma rule; "
                         f"{'it is' if one else 'they are'} kept (--outliers sigma leaves "
                         f"{'it' if one else 'them'} out)")
    if not math.isclose(px, py, rel_tol=1e-6):
        warnings_.append(f"non-square pixels ({px * MM_TO_UM:.6g} x {py * MM_TO_UM:.6g} um): slopes and "
                         f"lengths use each axis' own spacing")
    areal, ang = areal_metrics(p, sp)
    src = {k: v for k, v in (source or {}).items() if k not in ("scene",)}
    metrics = {
        "areal": {k: _nan_to_none(float(v)) for k, v in areal.items()},
        "pixel_mm": [px, py], "shape": [int(z.shape[0]), int(z.shape[1])],
        "origin_mm": [float(origin[0]), float(origin[1])],
        "field_mm": [px * z.shape[1], py * z.shape[0]],
        "valid_fraction": float(np.isfinite(res).sum() / z.size),
        "measured_fraction": float(n_measured / z.size), "n_valid": int(p["n_valid"]),
        "units": {"lateral": "mm", "heights": "nm (keys *_nm); maps and files in mm",
                  "Sdq": "1 (rms slope, dz/dx)", "Sdr_percent": "%", "Sal_mm": "mm",
                  "Str": "1", "pixel_mm": "mm",
                  "in_file": src.get("units_in_file")},
        "form": form_info,
        "filter": {"S_mm": s_filter_mm, "L_mm": l_filter_mm,
                   "kind": "ISO 16610-61 Gaussian (masked, normalised)"},
        "outliers": {"method": outliers, "sigma": float(outlier_sigma), "count": n_flag,
                     "fraction": n_flag / n_measured,
                     "left_out": outliers == "sigma",
                     "rule": "spikes: a second difference beyond k robust sigma (1.4826 MAD) with both neighbours' of the opposite sign, along x and y"},
        "slope_estimator": slope,
        "spatial": {"s": acf_threshold, "decays_in_all_directions": sp["decays_in_all_directions"],
                    "fastest_direction_deg": ang["fastest_direction_rad"],
                    "slowest_direction_deg": ang["slowest_direction_rad"],
                    "longest_decay_mm": _nan_to_none(sp["longest_decay_mm"])},
        "warnings": warnings_,
        "source": src,
    }
    if holes is not None:
        metrics["holes"] = holes
    return Analysis(metrics, res, flagged)
