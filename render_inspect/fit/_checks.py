"""Model checks of a fit: does the scene describe this measurement at all?

Before the fit (:func:`check_before`): the measured marks and those the scene predicts at
its own values must be of one kind: marks in both or in neither, the same direction in
each part of the field (a field placed elsewhere on the part, or mirrored, has its marks
turned), a period the free keys can reach, and a form (the waviness) that the scene
explains.  Any failure refuses the fit with its reason.

After the fit (:func:`check_after`): the misfit against its noise floor (the misfit the
random parts and the camera's noise alone leave at the true values) and the marks tile by
tile, measured against fitted: a period that varies across the field (a feed that changes
with the radius), a second family of marks, a direction that differs.  Any failure turns
the fit's verdict into "this model does not describe this measurement".

Arrays in, findings out: the pipeline hands in the maps (form removed) and the pixel.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np

from ..core.errors import InputError
from ..core.units import MM_TO_NM, MM_TO_UM
from ._features import PEAK_MIN_PERIODS, feed_peak

__all__ = ["mark_tiles", "check_before", "check_after", "profile_marks", "MARK_KEYS",
           "within_reach"]

#: scene keys that set the marks' period (a fit that frees one may move it)
MARK_KEYS = ("process.feed_mm_per_min", "process.spindle_rpm")
#: relative period difference beyond which the marks are not the scene's (no feed key free)
PERIOD_TOLERANCE = 0.03
#: relative distance by which the measured period may lie beyond what the free keys' bounds
#: reach and still be fitted: the period read from a window of ten or more marks is uncertain
#: by a few tenths of a per cent, so a truth at a bound can read just beyond it
REACH_TOLERANCE = 0.01
#: degrees by which the marks' direction may differ between measured and predicted
ANGLE_TOLERANCE_DEG = 15.0
#: relative spread of the tiles' periods beyond which the feed varies across the field
PERIOD_SPREAD = 0.02
#: the misfit over its noise floor beyond which the model does not describe the measurement
MISMATCH = 30.0
#: relative spread of a profile's segment periods beyond which the feed varies along it
PROFILE_SPREAD = 0.03
#: waviness difference (nm rms) between measured and predicted above which the form must
#: agree (half the larger of the two at most)
FORM_MIN_NM = 20.0


def _tile_peak(z, pixel):
    """(period mm, direction deg in [0, 180), strength) of the strongest marks in a tile,
    or None."""
    ok = np.isfinite(z)
    if ok.mean() < 0.5:
        return None
    zz = np.where(ok, z - np.nanmean(z), 0.0)
    ny, nx = zz.shape
    w = np.outer(np.hanning(ny), np.hanning(nx))
    p = np.abs(np.fft.fft2(zz * w)) ** 2
    ky = np.fft.fftfreq(ny, pixel)
    kx = np.fft.fftfreq(nx, pixel)
    kxx, kyy = np.meshgrid(kx, ky)
    kr = np.hypot(kxx, kyy)
    length = min(ny, nx) * pixel
    p = np.where(kr >= PEAK_MIN_PERIODS / 2 / length, p, 0.0)
    i = int(np.argmax(p))
    if p.flat[i] <= 0 or p.flat[i] < 20 * float(np.median(p[p > 0])):
        return None
    k = feed_peak(zz, pixel=(pixel, pixel), k_min=PEAK_MIN_PERIODS / 2 / length)
    if k is None:
        k = float(kr.flat[i])
    ang = math.degrees(math.atan2(kyy.flat[i], kxx.flat[i])) % 180.0
    return 1.0 / k, ang, float(p.flat[i])


def mark_tiles(z: np.ndarray, pixel: float, tiles: int = 2) -> list:
    """The marks in ``tiles`` x ``tiles`` parts of a map (form removed): per tile (row, col,
    period mm or None, direction deg or None)."""
    z = np.asarray(z, dtype=np.float64)
    ny, nx = z.shape
    out = []
    for a in range(tiles):
        for b in range(tiles):
            t = z[a * ny // tiles:(a + 1) * ny // tiles, b * nx // tiles:(b + 1) * nx // tiles]
            pk = _tile_peak(t, pixel)
            out.append((a, b, None if pk is None else pk[0], None if pk is None else pk[1]))
    return out


def _angle_diff(a, b) -> float:
    d = abs(a - b) % 180.0
    return min(d, 180.0 - d)


def _rms(z) -> float:
    ok = np.isfinite(z)
    return float(np.sqrt(np.mean(z[ok] ** 2))) if ok.any() else 0.0


def within_reach(period: float, reach: Sequence[float]) -> bool:
    """Whether a measured period lies within the periods ``reach`` = (lower, upper) the
    free keys' bounds reach, or at most :data:`REACH_TOLERANCE` beyond them."""
    return (reach[0] * (1.0 - REACH_TOLERANCE) <= period
            <= reach[1] * (1.0 + REACH_TOLERANCE))


def check_before(measured: np.ndarray, predicted: np.ndarray, *, pixel: float,
                 free_keys: Sequence[str], measured_period: float | None,
                 predicted_period: float | None, measured_wavy: np.ndarray,
                 predicted_wavy: np.ndarray, reach: Sequence[float] | None = None) -> dict:
    """Refuse (:class:`InputError`, one line with the reason) a measurement the scene does
    not describe; return what was checked.

    Parameters
    ----------
    measured, predicted : 2-D arrays
        The measured window and the scene's prediction at its own values (form removed).
    free_keys : list of str
    measured_period, predicted_period : float or None
        The marks' period (mm) of each (None: no marks found).
    measured_wavy, predicted_wavy : 2-D arrays
        Their waviness (the marks filtered out).
    reach : (lower, upper) mm, optional
        The periods the free keys can reach (None: unknown).
    """
    free_feed = any(k in MARK_KEYS for k in free_keys)
    out = {"measured_period_um": None if measured_period is None else measured_period * MM_TO_UM,
           "scene_period_um": None if predicted_period is None else predicted_period * MM_TO_UM}
    if (measured_period is None) != (predicted_period is None):
        which = "the measured map has feed marks but the scene predicts none" \
            if predicted_period is None else \
            "the scene predicts feed marks but the measured map has none"
        raise InputError(f"this scene does not describe this measurement: {which} (a "
                         f"different process, or the wrong file)")
    if measured_period is not None and predicted_period is not None:  # (both or neither)
        rel = predicted_period / measured_period - 1.0
        out["period_difference"] = rel
        if reach is not None:
            if not within_reach(measured_period, reach):
                raise InputError(
                    f"this scene does not describe this measurement: the marks' period "
                    f"{measured_period * MM_TO_UM:.4g} um lies outside the "
                    f"{reach[0] * MM_TO_UM:.4g}..{reach[1] * MM_TO_UM:.4g} um the free keys' "
                    f"bounds can reach; widen --bounds or check the scene's spindle speed")
        elif not free_feed and abs(rel) > PERIOD_TOLERANCE:
            raise InputError(
                f"this scene does not describe this measurement: the marks' period is "
                f"{measured_period * MM_TO_UM:.4g} um, the scene's "
                f"{predicted_period * MM_TO_UM:.4g} um ({100 * rel:+.3g} %), and no key that "
                f"sets it is free; add process.feed_mm_per_min to --free or fix the scene")
        mt, pt = mark_tiles(measured, pixel), mark_tiles(predicted, pixel)
        worst = 0.0
        for (a, b, _, am), (_, _, _, ap) in zip(mt, pt):
            if am is not None and ap is not None:
                d = _angle_diff(am, ap)
                if d > worst:
                    worst = d
                if d > ANGLE_TOLERANCE_DEG:
                    raise InputError(
                        f"this scene does not describe this measurement: in the field's "
                        f"{'lower upper'.split()[a]} {'left right'.split()[b]} part the marks "
                        f"run at {(am + 90) % 180:.0f} deg, the scene's at "
                        f"{(ap + 90) % 180:.0f} deg: the field lies elsewhere on the part "
                        f"(or is mirrored); place it with --at X,Y or --at register")
        out["direction_difference_deg"] = worst
    wm = _rms(measured_wavy)
    wp = _rms(predicted_wavy)
    d = measured_wavy - predicted_wavy
    wd = _rms(d)
    out["waviness_rms_nm"] = wm * MM_TO_NM
    out["scene_waviness_rms_nm"] = wp * MM_TO_NM
    out["waviness_unexplained_nm"] = wd * MM_TO_NM
    if wd * MM_TO_NM > FORM_MIN_NM and wd > 0.5 * max(wm, wp):
        raise InputError(
            f"this scene does not describe this measurement: the measured waviness "
            f"({wm * MM_TO_NM:.4g} nm rms) and the scene's ({wp * MM_TO_NM:.4g} nm rms) differ by "
            f"{wd * MM_TO_NM:.4g} nm rms (the design, or the field's place on the part, "
            f"differs); check the scene's design and --at")
    return out


def check_after(measured: np.ndarray, fitted: np.ndarray, *, pixel: float,
                goodness: dict) -> dict:
    """The verdict after the fit: ``{"describes": bool, "findings": [text], ...}``."""
    findings = []
    ratio = goodness.get("ratio")
    if ratio is not None and ratio > MISMATCH:
        findings.append(f"the misfit is {ratio:.3g} times what the random parts and the "
                        f"camera's noise alone leave")
    mt, ft = mark_tiles(measured, pixel), mark_tiles(fitted, pixel)
    pm = [t[2] for t in mt if t[2] is not None]
    pf = [t[2] for t in ft if t[2] is not None]
    spread = None
    if len(pm) >= 2:
        spread = (max(pm) - min(pm)) / float(np.mean(pm))
        own = (max(pf) - min(pf)) / float(np.mean(pf)) if len(pf) >= 2 else 0.0
        if spread > PERIOD_SPREAD + own:
            findings.append(f"the marks' period varies across the field from "
                            f"{min(pm) * MM_TO_UM:.4g} to {max(pm) * MM_TO_UM:.4g} um (a feed "
                            f"that changes; the model cuts one)")
    for (a, b, _, am), (_, _, _, af) in zip(mt, ft):
        if am is not None and af is not None and _angle_diff(am, af) > ANGLE_TOLERANCE_DEG:
            findings.append(f"the marks run at {(am + 90) % 180:.0f} deg in one part of the "
                            f"field, the fitted model's at {(af + 90) % 180:.0f} deg (a second "
                            f"family of marks, or marks mirrored across the axis)")
            break
    if sum(t[2] is not None for t in mt) != sum(t[2] is not None for t in ft):
        findings.append("marks are found in some parts of the measured field and not in the "
                        "same parts of the fitted one")
    return {"describes": not findings, "findings": findings,
            "period_spread": spread, "misfit_over_noise": ratio,
            "verdict": ("the model describes this measurement" if not findings else
                        "this model does not describe this measurement: "
                        + "; ".join(findings))}


def profile_marks(z: np.ndarray, pixel: float, *, segments: int = 4,
                  mirror: bool = True) -> dict:
    """The marks of a measured profile (a slice across turning marks; heights mm, NaN =
    not measured): the period in each of ``segments`` parts and whether the profile is
    mirrored about a point (a diameter through the spindle axis: the marks on the two
    sides are mirror images, two families for a model of one; ``mirror=False`` skips that
    test, for one side of such a profile).

    Returns ``{"periods_mm": [...], "spread": relative, "mirror_at": index or None,
    "one_family": bool, "reason": text}``; the period of a segment is its spectrum's
    strongest peak refined by the power-weighted centroid."""
    z = np.asarray(z, dtype=np.float64)
    x = np.arange(z.size)
    ok = np.isfinite(z)
    zf = np.interp(x, x[ok], z[ok]) if ok.sum() > 16 else np.zeros_like(z)
    mirror_at = _mirror_point(zf) if mirror else None
    periods = []
    bounds = np.linspace(0, z.size, segments + 1).astype(int)
    for a, b in zip(bounds[:-1], bounds[1:]):
        periods.append(_profile_period(zf[a:b], pixel))
    good = [p for p in periods if p is not None]
    spread = (max(good) - min(good)) / float(np.mean(good)) if len(good) >= 2 else None
    reasons = []
    if mirror_at is not None:
        reasons.append(f"the profile is mirrored about {mirror_at * pixel:.4g} mm (a line "
                       f"through the spindle axis)")
    if spread is not None and spread > PROFILE_SPREAD:
        reasons.append(f"the period varies from {min(good) * MM_TO_UM:.4g} to "
                       f"{max(good) * MM_TO_UM:.4g} um along it")
    return {"periods_mm": periods, "spread": spread, "mirror_at": mirror_at,
            "one_family": not reasons, "reason": "; ".join(reasons)}


def _profile_period(z, pixel):
    n = z.size
    if n < 32:
        return None
    zz = z - np.polyval(np.polyfit(np.arange(n), z, 2), np.arange(n))
    p = np.abs(np.fft.rfft(zz * np.hanning(n))) ** 2
    k = np.fft.rfftfreq(n, pixel)
    use = k >= PEAK_MIN_PERIODS / (n * pixel)
    if not use.any():
        return None
    i = int(np.argmax(np.where(use, p, 0.0)))
    lo, hi = max(i - 2, 0), min(i + 3, p.size)
    w = p[lo:hi]
    return 1.0 / float(np.sum(w * k[lo:hi]) / np.sum(w))


def _mirror_point(z):
    """The index about which the profile is mirror-symmetric (correlation of the profile
    with its reflection above 0.6 over at least a quarter of it on each side), or None."""
    n = z.size
    zz = z - np.polyval(np.polyfit(np.arange(n), z, 2), np.arange(n))
    best, where = 0.0, None
    span = n // 4
    for c in range(span, n - span):
        m = min(c, n - 1 - c)
        a = zz[c - m:c][::-1]
        b = zz[c + 1:c + 1 + m]
        if a.size < span:
            continue
        den = float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
        r = float(np.sum(a * b)) / den if den > 0 else 0.0
        if r > best:
            best, where = r, c
    return where if best > 0.6 else None
