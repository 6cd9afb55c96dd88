"""``compare --measured PROFILE``'s registration and checks: the measured profile
registered along the line (:func:`_register`, against chance: phase-randomised
surrogates), the cut as the virtual instrument sees it (:func:`cut_as_seen`), and the
virtual measurement checked against it (:func:`_measurement_check`)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..core.units import MM_TO_NM, MM_TO_UM
from ..instruments import Microscope
# NULL_SURROGATES: the phase-randomised surrogates of the measured profile the
# registration's correlation is set against, as many as a measured map's
from ..metrology import NULL_SURROGATES, mirror_centre, phase_surrogate
from ..core.lazy import lazy_attr

#: SciPy, imported on first use (render_inspect.core.lazy)
map_coordinates = lazy_attr("scipy.ndimage", "map_coordinates")

__all__ = ["cut_as_seen"]


def _fmt(v, key=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    if key == "RSm_mm":
        v = v * MM_TO_UM
    return f"{v:.4g}"


def _filled(z):
    ok = np.isfinite(z)
    i = np.arange(z.size)
    f = np.interp(i, i[ok], z[ok])
    c = np.polyfit(i - i.mean(), f, 2)
    return f - np.polyval(c, i - i.mean())


def cut_as_seen(machined: np.ndarray, *, pixel: float, origin: tuple[float, float],
                microscope: Microscope, camera_pixel: float,
                camera_origin: tuple[float, float], camera_shape: tuple[int, int]) -> np.ndarray:
    """The simulated cut as the virtual instrument's camera sees it: the map (``pixel``
    mm, its first sample at ``origin``) through the objective's and the pixel's lateral
    response (:meth:`~render_inspect.instruments.Microscope.lateral_response`), sampled at
    the camera's pixel centres (``camera_pixel`` mm, the first at ``camera_origin``, a
    ``camera_shape`` grid), where the measurement's heights are.  Sampled along a line as
    the measurement is, it is what a measurement that follows the cut reports there: the
    objective rounds sharp cusps and edges, and a camera pixel wider than the line's
    spacing is interpolated between its centres."""
    seen = microscope.lateral_response(machined, pixel=pixel, camera_pixel=camera_pixel)
    rows = (camera_origin[1] + camera_pixel * np.arange(camera_shape[0]) - origin[1]) / pixel
    cols = (camera_origin[0] + camera_pixel * np.arange(camera_shape[1]) - origin[0]) / pixel
    rr, cc = np.meshgrid(rows, cols, indexing="ij")
    return map_coordinates(seen, [rr, cc], order=1, mode="constant", cval=np.nan)


#: a point of the virtual measurement departs from the cut it measured when it is off by
#: more than this many of the instrument's own noise (one standard deviation; a Gaussian
#: excursion this large has a chance of 6e-7 per point)
DEPARTURE_NOISE_FACTOR = 5.0
#: ... and by more than this fraction of the effective wavelength: half a fringe order
#: (a lost fringe order puts a point off by lambda_eff / 2, a whole order)
DEPARTURE_WAVELENGTH_FRACTION = 0.25
#: the virtual measurement failed when this many neighbouring points depart together (a lost
#: fringe order moves a connected run of the profile; a point or two at the edge of a
#: dropout, or at a steep edge the objective blurs, do not), or ...
DEPARTURE_MIN_RUN = 3
#: ... when at least this share of the points depart, run or not
DEPARTURE_MIN_FRACTION = 0.01


def _register(s_meas, z_meas, s_sim, z_sim, *, spacing, period, axis_s=None, seed=0):
    """The shift (mm) to add to the measured positions so that they best match the
    simulated measurement, the correlation there and how the search was bounded.

    Feed marks repeat every period, so many scallops match many scallops about equally
    well: the search is bounded to one period either side of where the measured mirror
    centre (a trace through the spindle axis) meets the simulated profile's centre: its
    heights' own mirror centre and, where the line passes through the spindle axis, the
    axis's place on the line (``axis_s``, mm from the line's start); the best match over
    both windows is taken."""
    a = _filled(z_meas)
    b = _filled(z_sim)
    ma = mirror_centre(z_meas, spacing=spacing, x0=float(s_meas[0]))
    mb = mirror_centre(z_sim, spacing=spacing, x0=float(s_sim[0]))
    n = min(a.size, b.size)
    # where the simulated profile's centre may be: its heights' mirror centre (a row of
    # cusps is mirror-symmetric about every cusp, so it can be a period or more off) and,
    # on a line through the spindle axis, the axis's place on the line
    centres = []
    if (mb["symmetry"] or 0) >= 0.5:
        centres.append((mb["centre_mm"], "the simulated profile's mirror centre"))
    if axis_s is not None:
        centres.append((float(axis_s), "the spindle axis on the line"))
    if (ma["symmetry"] or 0) >= 0.5 and centres and period:
        reach = int(math.ceil(period / spacing))
        lags = np.unique(np.concatenate([
            np.arange(int(round((c - ma["centre_mm"]) / spacing)) - reach,
                      int(round((c - ma["centre_mm"]) / spacing)) + reach + 1)
            for c, _ in centres]))
        how = ("within one period of the measured mirror centre on "
               + " or on ".join(w for _, w in centres))
    else:
        lags = np.arange(-(n // 2), n // 2 + 1)
        how = "over half the line either way"
    k_start = int(round((s_meas[0] - s_sim[0]) / spacing))
    r, lag = _best_lag(a, b, lags, k_start)
    null = _null_correlation(a, b, lags, k_start, seed=seed)
    return lag * spacing, r, how, null


def _best_lag(a, b, lags, k_start):
    """(correlation, lag) of the best-scoring lag: the correlation weighted by the
    overlap's share of the longest overlap possible."""
    n = min(a.size, b.size)
    best = (-2.0, 0, -2.0)
    for lag in lags:
        # measured sample i lies at simulated sample i + lag (positions from the line start)
        k0 = k_start + int(lag)
        i0, i1 = max(0, -k0), min(a.size, b.size - k0)
        if i1 - i0 < max(16, a.size // 3):
            continue
        u, v = a[i0:i1], b[i0 + k0:i1 + k0]
        su, sv = u.std(), v.std()
        if su == 0 or sv == 0:
            continue
        r = float(np.mean((u - u.mean()) * (v - v.mean())) / (su * sv))
        # a partial overlap counts for its share of the longest one possible
        score = r * (i1 - i0) / n
        if score > best[2]:
            best = (r, int(lag), score)
    return best[0], best[1]


def _null_correlation(a, b, lags, k_start, *, seed=0, n=NULL_SURROGATES) -> float | None:
    """The correlation the same search reaches with profiles unrelated to the simulation:
    the best of ``n`` phase-randomised surrogates of the measured profile (the same power
    spectrum, so the same feed marks and roughness, with random phases), searched over
    the same lags.  A registration whose correlation does not beat it has found nothing
    a profile of the same spectrum would not find by chance."""
    if a.size < 16:
        return None
    rng = np.random.default_rng(seed)
    amp = np.abs(np.fft.rfft(a - a.mean()))
    best = [_best_lag(phase_surrogate(a, rng, amp), b, lags, k_start)[0] for _ in range(n)]
    return float(max(best)) if best else None


def _measurement_check(z_sim, z_true, noise, *, lambda_eff_nm, mode, rt_sim, rt_true) -> dict:
    """Does the virtual measurement along the line follow the cut it measured?  Points of
    the simulated measurement (its median offset removed: an interferometer's heights are
    relative) depart from the cut when they are off by more than both
    :data:`DEPARTURE_NOISE_FACTOR` times the instrument's own noise (the median, along the
    line, of each pixel's noise estimated from its frames) and
    :data:`DEPARTURE_WAVELENGTH_FRACTION` of the effective wavelength (half a fringe
    order), after a line (the instrument's levelling: piston and tilt) is removed; a run of
    :data:`DEPARTURE_MIN_RUN` neighbouring such points, or :data:`DEPARTURE_MIN_FRACTION`
    of all: ``status`` "failed".  ``z_true`` is the cut as the instrument sees it
    (:func:`cut_as_seen`, sampled along the line as the measurement is): a sharp cusp the
    objective rounds, or a camera pixel wider than the measured spacing, is not a
    departure."""
    d = (np.asarray(z_sim) - np.asarray(z_true)) * MM_TO_NM
    ok = np.isfinite(d)
    out: dict[str, Any] = {"status": "ok", "points": int(ok.sum()), "mode": mode,
                           "lambda_eff_nm": lambda_eff_nm, "Rt_nm": rt_sim, "Rt_cut_nm": rt_true}
    nz = np.asarray(noise, float)[ok] * MM_TO_NM if noise is not None else np.zeros(0)
    nz = nz[np.isfinite(nz)]
    sigma = float(np.median(nz)) if nz.size else None
    out["noise_nm"] = sigma
    if not ok.any():
        out.update(status="unknown", rms_departure_nm=None, threshold_nm=None, departing=0,
                   departing_fraction=0.0)
        return out
    i = np.flatnonzero(ok)
    d = d[ok]
    thr = max(DEPARTURE_WAVELENGTH_FRACTION * lambda_eff_nm,
              DEPARTURE_NOISE_FACTOR * (sigma or 0.0))
    # piston and tilt (the instrument's levelling), fitted to the points that follow the
    # cut (those within the threshold of the median offset, twice over), so that the
    # points that do not cannot tilt the line
    r = d - np.median(d)
    for _ in range(2):
        inl = np.abs(r) <= thr
        if inl.sum() < 2:
            break
        r = d - np.polyval(np.polyfit(i[inl].astype(float), d[inl], 1), i)
    d = r
    off = np.abs(d) > thr
    far = int(np.count_nonzero(off))
    run = _longest_run(off, i)
    out.update(rms_departure_nm=float(np.sqrt(np.mean(d ** 2))), threshold_nm=float(thr),
               departing=far, departing_fraction=far / d.size,
               rule=f"a point departs when it is off the cut by more than "
                    f"{DEPARTURE_NOISE_FACTOR:g} x the instrument's noise and more than half a "
                    f"fringe order (lambda_eff / 4 = {lambda_eff_nm / 4:.4g} nm), a line "
                    f"removed; failed with a run of {DEPARTURE_MIN_RUN} neighbouring such "
                    f"points or {100 * DEPARTURE_MIN_FRACTION:g} % of all",
               longest_run=run)
    if run >= DEPARTURE_MIN_RUN or far >= DEPARTURE_MIN_FRACTION * d.size:
        out["status"] = "failed"
    return out


def _longest_run(flags: np.ndarray, index: np.ndarray) -> int:
    """The most ``flags`` in a row at neighbouring ``index`` positions (a gap breaks a
    run)."""
    best = cur = 0
    prev = None
    for f, k in zip(flags, index):
        cur = cur + 1 if f and prev is not None and k == prev + 1 and cur > 0 else (1 if f else 0)
        best = max(best, cur)
        prev = k
    return best


def _measurement_warning(chk: dict) -> str | None:
    """The one-line warning of a failed virtual measurement (None when it followed the
    cut)."""
    if chk.get("status") != "failed":
        return None
    noise = "" if chk.get("noise_nm") is None else \
        f" against the instrument's noise of {chk['noise_nm']:.2g} nm"
    other = ("coherence scanning (CSI: render.interferometer.mode = \"csi\") follows slopes "
             "phase shifting cannot, and is how the real parts were measured (a white-light "
             "interferometer)" if chk.get("mode") == "psi" else
             "check render.interferometer (objective, mode) against the part's slopes")
    return (f"the virtual measurement ({str(chk.get('mode')).upper()}) does not follow the cut "
            f"it measured: {chk['departing']} of {chk['points']} points "
            f"({100 * chk['departing_fraction']:.3g} %) are off by more than "
            f"{chk['threshold_nm']:.3g} nm (rms departure {chk['rms_departure_nm']:.4g} nm"
            f"{noise}; Rt {_fmt(chk.get('Rt_nm'))} nm against the cut's "
            f"{_fmt(chk.get('Rt_cut_nm'))} nm): lost fringe orders or dropouts, so its column is "
            f"not what the instrument would report of this part; {other}")


def _registration_warning(reg: dict) -> str | None:
    """The one-line warning of a registration no better than chance (None otherwise)."""
    if reg.get("reliable", True):
        return None
    why = (f"its correlation {reg['correlation']:.3f} is no better than the "
           f"{reg['null_correlation']:.3f} a profile of the same spectrum unrelated to the "
           f"{'cut' if reg.get('against') == 'cut_as_seen' else 'simulation'} reaches in the "
           f"same search")
    return (f"the registration is not reliable: {why}; the profiles overlaid "
            f"are not aligned point for point (compare their parameters and periods, which "
            f"do not depend on the registration, not their shapes)")
