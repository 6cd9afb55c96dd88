"""Profile texture parameters (ISO 21920-2) on the roughness profile that the ISO 16610-21
Gaussian filters make, with the default cut-offs of ISO 21920-3.

Chain, for a profile ``z(x)`` sampled every ``spacing`` mm:

1. form: a least-squares line (``form="line"``, the default), a parabola (``"poly2"``) or
   nothing (``"none"``) is removed;
2. the primary profile ``P`` is the profile low-pass filtered with the Gaussian filter of
   nesting index ``lambda_s``; the waviness (mean line) ``W`` is ``P`` low-pass filtered
   with ``lambda_c``; the roughness profile is ``R = P - W``;
3. the Gaussian weighting function of ISO 16610-21 is
   ``s(x) = 1 / (alpha lambda) exp(-pi (x / (alpha lambda))^2)`` with
   ``alpha = sqrt(ln 2 / pi)``, so that a sinusoid of wavelength ``lambda`` keeps 50 % of
   its amplitude in the mean line; it is applied as a spatial convolution truncated at
   ``+-lambda`` (where the weight is below ``exp(-pi / alpha^2) = 1e-6`` of its peak), the
   weights renormalised over measured points (gaps and ends);
4. the evaluation length leaves out ``lambda_c / 2`` at each end (where the filter lacks
   half its support) and is split into ``n_sections`` section lengths (5 by default;
   fewer, with a warning, when the trace is shorter than 5 ``lambda_c`` plus the ends);
5. the parameters are taken on ``R`` over the evaluation length, about its mean.

Parameters (heights in the unit of the profile, here mm; ``RSm`` in mm; ``Rdq`` a slope):

- ``Ra`` mean |R|, ``Rq`` root mean square, ``Rsk`` = mean R^3 / Rq^3, ``Rku`` = mean R^4 /
  Rq^4 over the evaluation length;
- ``Rp``, ``Rv``, ``Rz`` (= Rp + Rv per section): the means over the section lengths of the
  highest peak, deepest valley and their sum; ``Rt`` the peak-to-valley over the whole
  evaluation length;
- ``RSm``: the mean width of the profile elements (a peak above the mean line followed by
  a valley below it), counted with the height discrimination of 10 % of Rz (a crossing
  counts once the profile has gone 5 % of Rz beyond the mean line on the other side)
  and the width discrimination of 1 % of the section length;
- ``Rdq``: the root mean square local slope, the seven-point derivative
  ``(z[i+3] - 9 z[i+2] + 45 z[i+1] - 45 z[i-1] + 9 z[i-2] - z[i-3]) / (60 dx)`` (ISO 4287);
- the material ratio curve (the fraction of the evaluation length where ``R >= c``) and
  ``Rmr(c)`` with ``c`` measured down from the highest peak.

Default cut-offs (ISO 21920-3, the table carried over from ISO 4288:1996): a periodic
profile takes ``lambda_c`` from RSm, a non-periodic one from Ra; the choice is iterated
until the RSm (or Ra) measured with it falls in its row.  ``lambda_s`` follows ``lambda_c``
(2.5 um up to 0.8 mm, 8 um for 2.5 mm, 25 um for 8 mm).  A trace too short for the table's
cut-off (2 lambda_c are needed: the ends and one section length) takes the largest cut-off
of the ISO 16610-21 series that fits, continued below the table to 0.025 mm (lambda_s
0.8 um) and 0.008 mm (lambda_s 0.25 um), with a warning.

References
----------
ISO 16610-21:2011 (profile Gaussian filter); ISO 21920-2:2021 (profile parameters);
ISO 21920-3:2021 (specification operators: default cut-offs); ISO 4287:1997 / ISO 4288:1996
(the predecessors whose element and derivative definitions are kept).
"""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError, check_positive
from ..core.units import MM_TO_UM
from ._periods import dominant_periods

__all__ = ["GAUSSIAN_ALPHA", "LAMBDA_C_SERIES", "gaussian_profile_weights",
           "profile_gaussian_filter", "default_cutoffs", "roughness_profile",
           "profile_texture", "material_ratio_curve", "rmr", "rsm", "rdq", "evaluate_profile",
           "parse_profile_filter"]

GAUSSIAN_ALPHA = math.sqrt(math.log(2.0) / math.pi)

#: the nesting index series of lambda_c, mm (ISO 16610-21 / ISO 21920-3)
LAMBDA_C_SERIES = (0.08, 0.25, 0.8, 2.5, 8.0)

#: lambda_s that goes with each lambda_c, mm (ISO 21920-3 / ISO 3274)
_LAMBDA_S = {0.008: 0.00025, 0.025: 0.0008, 0.08: 0.0025, 0.25: 0.0025, 0.8: 0.0025, 2.5: 0.008, 8.0: 0.025}

#: default lambda_c by RSm (periodic profiles): (RSm upper bound mm, lambda_c mm)
_BY_RSM = ((0.04, 0.08), (0.13, 0.25), (0.4, 0.8), (1.3, 2.5), (math.inf, 8.0))

#: default lambda_c by Ra (non-periodic profiles): (Ra upper bound mm, lambda_c mm)
_BY_RA = ((0.02e-3, 0.08), (0.1e-3, 0.25), (2e-3, 0.8), (10e-3, 2.5), (math.inf, 8.0))

_FORMS = ("none", "line", "poly2")


def gaussian_profile_weights(spacing: float, cutoff: float) -> np.ndarray:
    """The ISO 16610-21 weighting function sampled every ``spacing`` mm over ``+-cutoff``,
    normalised to sum 1."""
    check_positive("spacing", spacing)
    check_positive("cutoff", cutoff)
    half = max(1, int(math.ceil(cutoff / spacing)))
    x = np.arange(-half, half + 1) * spacing
    a = GAUSSIAN_ALPHA * cutoff
    w = np.exp(-math.pi * (x / a) ** 2)
    return w / w.sum()


def profile_gaussian_filter(z: np.ndarray, *, spacing: float, cutoff: float) -> np.ndarray:
    """Gaussian mean line (low-pass) of a profile, NaN = not measured.

    The weights are renormalised over the measured points inside the support, so gaps
    and the ends do not pull the mean line toward zero; the result is NaN where less than
    half of the weight lies on measured points."""
    z = np.asarray(z, dtype=np.float64).ravel()
    w = gaussian_profile_weights(spacing, cutoff)
    if w.size == 1:
        return z.copy()
    ok = np.isfinite(z)
    num = np.convolve(np.where(ok, z, 0.0), w, mode="same")
    den = np.convolve(ok.astype(np.float64), w, mode="same")
    if w.size > z.size:  # np.convolve(mode="same") keeps the longer input's length
        c = (w.size - z.size) // 2
        num, den = num[c:c + z.size], den[c:c + z.size]
    with np.errstate(invalid="ignore", divide="ignore"):
        out = num / den
    out[den < 0.5] = np.nan
    return out


def parse_profile_filter(text: str | tuple | None, *, option: str = "--filter"
                         ) -> tuple[float | None, float | None]:
    """``"S,L"`` (mm; either may be empty for the default) -> (lambda_s, lambda_c)."""
    if text is None:
        return None, None
    if isinstance(text, (tuple, list)):
        s, l_ = text
    else:
        parts = str(text).split(",")
        if len(parts) != 2:
            raise InputError(f"{option} must be S,L (Gaussian cut-offs lambda_s,lambda_c in mm, "
                             f"e.g. 0.0025,0.8 or ,0.25), received {text!r}")
        try:
            s, l_ = (float(p) if p.strip() else None for p in parts)
        except ValueError:
            raise InputError(f"{option} must be S,L with numbers in mm, received {text!r}") from None
    for name, v in (("lambda_s", s), ("lambda_c", l_)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise InputError(f"{option}: {name} must be a number > 0 (mm), received {v!r}")
    if s is not None and l_ is not None and not s < l_:
        raise InputError(f"{option}: lambda_s ({s:g} mm) must be smaller than lambda_c "
                         f"({l_:g} mm)")
    return s, l_


def _remove_form(x: np.ndarray, z: np.ndarray, form: str) -> np.ndarray:
    if form not in _FORMS:
        raise InputError(f"form must be one of {_FORMS}, received {form!r}")
    if form == "none":
        return z.copy()
    ok = np.isfinite(z)
    deg = 1 if form == "line" else 2
    if ok.sum() <= deg:
        raise InputError(f"form {form!r} needs at least {deg + 1} measured points, got {int(ok.sum())}")
    xm = x.mean()
    c = np.polyfit(x[ok] - xm, z[ok], deg)
    return z - np.polyval(c, x - xm)


def roughness_profile(x: np.ndarray, z: np.ndarray, *, spacing: float, lambda_s: float | None,
                      lambda_c: float,
                      form: str = "line") -> dict:
    """The primary, waviness and roughness profiles and the evaluation region.

    Returns
    -------
    dict
        ``primary``, ``waviness``, ``roughness`` (n,) arrays (mm, NaN where not
        measured or not defined), ``evaluate`` (n,) bool (the evaluation length:
        ``lambda_c / 2`` left out at each end), ``n_sections``, ``warnings``."""
    x = np.asarray(x, dtype=np.float64).ravel()
    z = np.asarray(z, dtype=np.float64).ravel()
    check_positive("lambda_c", lambda_c)
    warnings_: list[str] = []
    z0 = _remove_form(x, z, form)
    if lambda_s:
        check_positive("lambda_s", lambda_s)
        if not lambda_s < lambda_c:
            raise InputError(f"lambda_s ({lambda_s:g} mm) must be smaller than lambda_c "
                             f"({lambda_c:g} mm)")
        if spacing > lambda_s / 2:
            warnings_.append(f"the sampling ({spacing * MM_TO_UM:.3g} um) is coarser than half of "
                             f"lambda_s ({lambda_s * MM_TO_UM:.3g} um): the instrument's own lateral "
                             f"resolution, not the lambda_s filter, sets the short-wavelength "
                             f"limit (ISO 21920-3 asks for a sampling of lambda_s / 5 or finer)")
        p = profile_gaussian_filter(z0, spacing=spacing, cutoff=lambda_s)
        p[~np.isfinite(z0)] = np.nan
    else:
        p = z0
    w = profile_gaussian_filter(p, spacing=spacing, cutoff=lambda_c)
    r = p - w
    n_end = int(math.ceil(lambda_c / 2 / spacing))
    ev = np.zeros(x.size, dtype=bool)
    ev[n_end:x.size - n_end] = True
    ev &= np.isfinite(r)
    if not ev.any():
        raise InputError(f"the profile ({x[-1] - x[0]:.4g} mm) is too short for lambda_c = "
                         f"{lambda_c:g} mm: at least lambda_c / 2 is left out at each end; "
                         f"choose a smaller lambda_c with --filter ,L")
    idx = np.flatnonzero(ev)
    le = (idx[-1] - idx[0]) * spacing
    n_sec = int(min(5, max(1, math.floor(le / lambda_c + 1e-9))))
    if le < lambda_c * (1 - 1e-9):
        raise InputError(f"the profile ({x[-1] - x[0]:.4g} mm) leaves an evaluation length of "
                         f"{le:.4g} mm after the lambda_c / 2 ends, shorter than one section "
                         f"length lambda_c = {lambda_c:g} mm; choose a smaller lambda_c with "
                         f"--filter ,L")
    if n_sec < 5:
        warnings_.append(f"the evaluation length ({le:.4g} mm) holds {n_sec} section lengths "
                         f"of lambda_c = {lambda_c:g} mm, not the standard 5")
    return {"primary": p, "waviness": w, "roughness": r, "evaluate": ev, "n_sections": n_sec,
            "evaluation_length_mm": float(le), "warnings": warnings_}


def rdq(r: np.ndarray, *, spacing: float) -> float:
    """Root mean square slope of ``r`` (seven-point derivative; NaN-free stretches only)."""
    r = np.asarray(r, dtype=np.float64)
    if r.size < 7:
        return float("nan")
    d = (r[6:] - 9 * r[5:-1] + 45 * r[4:-2] - 45 * r[2:-4] + 9 * r[1:-5] - r[:-6]) / (60 * spacing)  # not a unit conversion: the 7-point stencil's 60
    d = d[np.isfinite(d)]
    return float(np.sqrt(np.mean(d * d))) if d.size else float("nan")


def rsm(r: np.ndarray, *, spacing: float, rz: float, section_length: float) -> tuple[float, int]:
    """Mean width of the profile elements (mm) and their number.

    A profile element is a peak (the profile above the mean line) and the valley that
    follows it; the mean line is crossed upward at the start of each element.  A crossing
    counts only once the profile has gone ``0.05 Rz`` beyond the mean line on the other
    side (the 10 % of Rz height discrimination), and an element narrower than 1 % of the
    section length is merged with the next.  The widths are measured between
    interpolated upward crossings."""
    r = np.asarray(r, dtype=np.float64)
    h = 0.05 * rz
    state = 0
    ups: list[float] = []
    last_zero = None
    for i in range(r.size):
        v = r[i]
        if not math.isfinite(v):
            state, last_zero = 0, None  # a gap ends the run of elements
            ups.append(math.nan)
            continue
        if i > 0 and math.isfinite(r[i - 1]) and (r[i - 1] < 0) != (v < 0):
            # the crossing between i-1 and i, interpolated
            last_zero = (i - 1) + r[i - 1] / (r[i - 1] - v)
        if state <= 0 and v > h:
            if state < 0 and last_zero is not None:
                ups.append(last_zero * spacing)
            state = 1
        elif state >= 0 and v < -h:
            state = -1
    gaps: list[float] = []
    prev = math.nan
    for u in ups:
        if math.isfinite(u) and math.isfinite(prev):
            gaps.append(u - prev)
        prev = u
    widths = np.asarray(gaps)
    if widths.size == 0:
        return float("nan"), 0
    # width discrimination: merge elements narrower than 1 % of the section length
    merged, acc = [], 0.0
    for w_ in widths:
        acc += w_
        if acc >= 0.01 * section_length:
            merged.append(acc)
            acc = 0.0
    if not merged:
        return float("nan"), 0
    return float(np.mean(merged)), len(merged)


def material_ratio_curve(r: np.ndarray, *, n: int = 101) -> tuple[np.ndarray, np.ndarray]:
    """The material ratio curve: heights ``c`` (from the highest peak down to the deepest
    valley, n levels) and the fraction of the profile at or above each (0..1)."""
    v = np.sort(np.asarray(r, dtype=np.float64)[np.isfinite(r)])[::-1]
    c = np.linspace(v[0], v[-1], n)
    frac = np.searchsorted(-v, -c, side="right") / v.size
    return c, frac


def rmr(r: np.ndarray, c_depth: float) -> float:
    """Rmr(c): the fraction (0..1) of the profile at or above the level ``c_depth`` below
    its highest peak."""
    v = np.asarray(r, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(np.count_nonzero(v >= v.max() - c_depth) / v.size)


def profile_texture(r: np.ndarray, *, spacing: float, n_sections: int = 5) -> dict:
    """ISO 21920-2 parameters of a roughness profile ``r`` (its evaluation length, mm):
    see the module docstring.  Gaps (NaN) are left out of the sums; sections split the
    points evenly."""
    r = np.asarray(r, dtype=np.float64).ravel()
    check_positive("spacing", spacing)
    ok = np.isfinite(r)
    n_sections = int(n_sections)
    if n_sections < 1 or ok.sum() < max(7, 2 * n_sections):
        raise InputError(f"profile parameters need at least {max(7, 2 * n_sections)} measured "
                         f"points for {n_sections} sections, got {int(ok.sum())}")
    d = r - np.nanmean(r)
    v = d[ok]
    rq = float(np.sqrt(np.mean(v * v)))
    secs = [s[np.isfinite(s)] for s in np.array_split(d, n_sections)]
    secs = [s for s in secs if s.size]
    rp = float(np.mean([s.max() for s in secs]))
    rv = float(np.mean([-s.min() for s in secs]))
    rz = float(np.mean([s.max() - s.min() for s in secs]))
    length = spacing * (r.size - 1)
    rsm_, n_el = rsm(d, spacing=spacing, rz=rz, section_length=length / n_sections)
    c, frac = material_ratio_curve(d)
    rt = float(v.max() - v.min())
    return {"Ra": float(np.mean(np.abs(v))), "Rq": rq, "Rp": rp, "Rv": rv, "Rz": rz, "Rt": rt,
            "Rsk": float(np.mean(v ** 3) / rq ** 3) if rq > 0 else float("nan"),
            "Rku": float(np.mean(v ** 4) / rq ** 4) if rq > 0 else float("nan"),
            "RSm": rsm_, "n_elements": n_el, "Rdq": rdq(d, spacing=spacing),
            "Rmr": {f"{p}%Rz": rmr(d, p / 100 * rz) for p in (10, 25, 50)},
            "material_ratio": {"depth": (c[0] - c).tolist(), "ratio": frac.tolist()},
            "n_sections": n_sections, "n_points": int(ok.sum())}


def default_cutoffs(x: np.ndarray, z: np.ndarray, *, spacing: float, form: str = "line",
                    periodic: bool | None = None,
                    max_iter: int = 5) -> dict:
    """``lambda_c`` (and ``lambda_s``) by ISO 21920-3: from RSm for a periodic profile,
    from Ra otherwise, iterated until the parameter measured with the chosen cut-off
    falls in that cut-off's row.  ``periodic=None`` decides from the power spectrum
    (:func:`~render_inspect.metrology.dominant_periods`: a dominant period that holds
    at least a third of the variance).  Returns ``lambda_s``, ``lambda_c``, ``by``
    ("RSm" or "Ra"), ``value`` (the RSm or Ra that chose it, mm), ``periodic``,
    ``iterations`` and ``note`` (when the profile is too short for the row's cut-off)."""
    x = np.asarray(x, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    length = float(x[-1] - x[0])
    if periodic is None:
        pk = dominant_periods(_remove_form(x, z, form), spacing=spacing)
        periodic = bool(pk.get("period_mm") and pk.get("fraction", 0.0) >= 1 / 3)
    by = "RSm" if periodic else "Ra"
    table = _BY_RSM if periodic else _BY_RA
    lc = 0.8
    seen = []
    note = None
    value = float("nan")
    for _ in range(max_iter):
        want, lc = lc, _fits(length, spacing, lc)
        note = (f"the trace ({length:.4g} mm) is too short for lambda_c = {want:g} mm; "
                f"{lc:g} mm is used") if want != lc else None
        rp = roughness_profile(x, z, spacing=spacing, lambda_s=_LAMBDA_S.get(lc), lambda_c=lc,
                               form=form)
        rr = rp["roughness"][rp["evaluate"]]
        t = profile_texture(rr, spacing=spacing, n_sections=rp["n_sections"])
        value = t["RSm"] if periodic else t["Ra"]
        if not math.isfinite(value):
            break
        nxt = next(c for bound, c in table if value <= bound)
        if nxt == want or _fits(length, spacing, nxt) == lc or nxt in seen:
            if nxt != want and nxt != lc:
                note = (f"the trace ({length:.4g} mm) is too short for lambda_c = {nxt:g} mm; "
                        f"{lc:g} mm is used")
            break
        seen.append(want)
        lc = nxt
    return {"lambda_s": _LAMBDA_S.get(lc), "lambda_c": lc, "by": by, "value": value,
            "periodic": periodic, "note": note}


def _fits(length: float, spacing: float, lc: float) -> float:
    """``lc``, or the largest cut-off of the series (down to 0.008 mm, continuing the
    ISO 16610-21 series below the standard's table) that leaves one section length after
    the ends on a trace of ``length`` (with a spare sample at each end)."""
    series = (0.008, 0.025) + LAMBDA_C_SERIES
    need = 2.0 * lc + 2 * spacing
    if length >= need:
        return lc
    ok = [c for c in series if length >= 2.0 * c + 2 * spacing and c < lc]
    if not ok:
        raise InputError(f"the trace ({length:.4g} mm) is too short for any Gaussian cut-off "
                         f"of the series down to 0.008 mm (a trace of 2 lambda_c is needed); "
                         f"set one with --filter S,L")
    return max(ok)


def evaluate_profile(x: np.ndarray, z: np.ndarray, *, spacing: float, lambda_s: float | None = None,
                     lambda_c: float | None = None, form: str = "line") -> dict:
    """Filter a profile and take its ISO 21920-2 parameters.

    ``lambda_s`` / ``lambda_c`` (mm) default to ISO 21920-3's choice
    (:func:`default_cutoffs`); ``lambda_s=0`` turns the short-wavelength filter off.

    Returns
    -------
    dict
        ``parameters`` (:func:`profile_texture`, heights mm), ``filter`` (``lambda_s``,
        ``lambda_c``, ``chosen_by``: "--filter" or "ISO 21920-3 from RSm|Ra"),
        ``evaluation_length_mm``, the ``primary`` / ``waviness`` / ``roughness`` arrays
        and the ``evaluate`` mask, and ``warnings``."""
    x = np.asarray(x, dtype=np.float64).ravel()
    z = np.asarray(z, dtype=np.float64).ravel()
    chosen = "--filter"
    notes: list[str] = []
    if lambda_c is None:
        d = default_cutoffs(x, z, spacing=spacing, form=form)
        lambda_c = d["lambda_c"]
        chosen = f"ISO 21920-3 from {d['by']}"
        if lambda_s is None:
            lambda_s = d["lambda_s"]
        if d["note"]:
            notes.append(d["note"])
    elif lambda_s is None:
        lambda_s = _LAMBDA_S.get(lambda_c, lambda_c / 300)
    rp = roughness_profile(x, z, spacing=spacing, lambda_s=lambda_s or None,
                           lambda_c=lambda_c, form=form)
    ev = rp["evaluate"]
    idx = np.flatnonzero(ev)
    r = rp["roughness"][idx[0]:idx[-1] + 1]
    params = profile_texture(r, spacing=spacing, n_sections=rp["n_sections"])
    return {"parameters": params,
            "filter": {"lambda_s": lambda_s or None, "lambda_c": lambda_c, "chosen_by": chosen,
                       "form": form},
            "evaluation_length_mm": rp["evaluation_length_mm"],
            "primary": rp["primary"], "waviness": rp["waviness"],
            "roughness": rp["roughness"], "evaluate": ev,
            "warnings": notes + rp["warnings"]}
