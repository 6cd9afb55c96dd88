"""Dominant spatial periods of a profile or a map from the power spectrum: the feed-mark
period with its harmonics and, for a profile through the spindle axis of a turned part,
where the centre is and the period on each side of it.

The profile (gaps filled by linear interpolation, a parabola removed) is multiplied by a
Hann window and its periodogram taken; the fundamental is the strongest peak (a line
higher than the one below it and not lower than the one above) strictly inside the range
from 4 samples to a quarter of the trace (so that at least four periods are seen),
refined by a parabola through the logarithm of the three bins about it (the Hann window's
main lobe is close to a Gaussian, for which that is exact; about a peak the vertex lies
within half a bin).  A spectrum that rises to an end of the range has no period there:
form left over rises to the longest period searched, and ``note`` says so (with no period
at all when the range holds no peak).  Harmonics are the lines at
k times the fundamental (k = 2 .. 6, each looked for within two bins) that rise ten times
above the spectrum's median.  ``fraction`` is the share of the variance in the
fundamental and its harmonics (two bins either side of each, the Hann main lobe); a
period holding less than 5 % is weak and ``note`` says so, with the share that lies at
periods longer than the range searched (form or waviness left over) when that is most
of it.

A map's spectrum is the radial average of its 2-D periodogram (Hann window in both
directions), so marks of any direction (arcs of a turned part) count alike.

The centre of a profile through the spindle axis is where the profile is most nearly
mirror-symmetric: the correlation coefficient of ``z(c + t)`` with ``z(c - t)`` over the
longer of the two arms that both sides cover (at least a fifth of the trace), found on a
half-sample grid.  Mirror symmetry alone does not make a trace through the axis (a long
even bow is mirror-symmetric about its vertex): the two arms must also show the same
feed-mark period (:func:`arms_agree`).
"""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError, check_positive
from ..core.units import MM_TO_UM

__all__ = ["dominant_periods", "map_periods", "mirror_centre", "profile_periods"]

#: a harmonic counts when its line rises this many times above the median of the spectrum
HARMONIC_ABOVE_MEDIAN = 10.0

#: a period holding less than this share of the variance (fundamental and harmonics) is
#: weak, and says so: the strongest line of a random profile (white noise) of 1000 points
#: holds 2-4.5 % (its median and largest share over 50 draws; 4.5-9 % at 500 points), so a
#: share below this cannot tell feed marks from roughness, or marks from the form or
#: waviness that holds the rest
WEAK_PERIOD_FRACTION = 0.05

#: a profile counts as through the spindle axis when its mirror correlation is at least this
MIRROR_MIN = 0.5

#: the two arms of a trace through the spindle axis show the same period to this share
#: (of their frequencies) or one line of the shorter arm's periodogram, whichever is wider
ARMS_REL_TOL = 0.1



def _filled(z) -> np.ndarray:
    z = np.asarray(z, dtype=np.float64).ravel()
    ok = np.isfinite(z)
    if ok.sum() < 8:
        raise InputError(f"a spectrum needs at least 8 measured points, got {int(ok.sum())}")
    i = np.arange(z.size)
    f = np.interp(i, i[ok], z[ok])
    c = np.polyfit(i - i.mean(), f, 2)
    return f - np.polyval(c, i - i.mean())


def _search_range(freq, power, *, spacing, n_total):
    """The bins searched for the fundamental (between 4 samples and a quarter of the
    trace) and the peaks among them: local maxima of the spectrum (higher than the bin
    below, not lower than the bin above, those beyond the range's ends included: a trace
    of exactly four periods has its peak on the range's end bin)."""
    fmin = 1.0 / (n_total * spacing / 4.0)
    fmax = 1.0 / (4.0 * spacing)
    ib = np.flatnonzero((freq >= fmin) & (freq <= fmax))
    peaks = np.array([i for i in ib if 0 < i < power.size - 1
                      and power[i] > power[i - 1] and power[i] >= power[i + 1]], dtype=int)
    return ib, peaks


def _range_note(freq, power, ib, peaks) -> tuple[str | None, str | None]:
    """Why the largest line of the search range is not a period, when it is not: it lies
    at an end of the range and the spectrum rises on beyond it (the end of the search, not
    a feed mark): ("longest" or "shortest", the words), or (None, None)."""
    j = int(ib[np.argmax(power[ib])])
    if j in peaks:
        return None, None
    if j == ib[0]:
        return "longest", (f"the spectrum rises to the longest period searched "
                           f"({1.0 / freq[j] * MM_TO_UM:.4g} um, a quarter of the length): form "
                           f"or waviness left over")
    if j == ib[-1]:
        return "shortest", (f"the spectrum rises to the shortest period searched "
                            f"({1.0 / freq[j] * MM_TO_UM:.4g} um, 4 samples): noise or marks "
                            f"finer than the sampling")
    return None, None


def _peaks(freq, power, *, spacing, n_total, n_harmonics=6) -> dict:
    """Fundamental and harmonics from a one-sided spectrum ``power`` at ``freq`` (1/mm):
    the strongest peak strictly inside the search range (none when the range holds no
    peak; ``note`` says why, or that the spectrum is larger still at an end of the
    range)."""
    ib, peaks = _search_range(freq, power, spacing=spacing, n_total=n_total)
    rng = {"shortest_mm": 4.0 * spacing, "longest_mm": n_total * spacing / 4.0}
    if ib.size < 3:
        return {"period_mm": None, "harmonics": [], "fraction": 0.0, "search_mm": rng,
                "rises_to": None, "note": "too few points to look for a period"}
    rises_to, note = _range_note(freq, power, ib, peaks)
    if not peaks.size:
        return {"period_mm": None, "harmonics": [], "fraction": 0.0, "search_mm": rng,
                "rises_to": rises_to,
                "note": note or "the spectrum has no peak between 4 samples and a quarter of "
                                "the length"}
    k = int(peaks[np.argmax(power[peaks])])
    df = float(freq[1] - freq[0])
    off = 0.0
    if min(power[k - 1:k + 2]) > 0:
        # a parabola through the log of the three bins about a local maximum: its vertex
        # lies within half a bin of it
        la, lb, lc = np.log(power[k - 1:k + 2])
        den = la - 2 * lb + lc
        off = 0.5 * (la - lc) / den if den < 0 else 0.0
    f0 = float(freq[k] + off * df)
    floor = float(np.median(power[1:])) if power.size > 2 else 0.0
    total = float(power[1:].sum())
    lobe = 2

    def share(idx):
        lo, hi = max(1, idx - lobe), min(power.size, idx + lobe + 1)
        return float(power[lo:hi].sum())

    used = share(k)
    harmonics = []
    for order in range(2, n_harmonics + 1):
        fk = order * f0
        if fk > freq[-1]:
            break
        j = int(round(fk / df))
        lo, hi = max(1, j - 2), min(power.size, j + 3)
        if lo >= hi:
            break
        jj = lo + int(np.argmax(power[lo:hi]))
        if power[jj] > HARMONIC_ABOVE_MEDIAN * floor:
            harmonics.append({"order": order, "period_mm": float(1.0 / fk),
                              "relative_power": float(power[jj] / power[k])})
            used += share(jj)
    fraction = float(min(1.0, used / total)) if total > 0 else 0.0
    weak = fraction < WEAK_PERIOD_FRACTION
    if weak:
        longer = float(power[1:ib[0]].sum() / total) if total > 0 else 0.0
        w = (f"a weak period: it holds {100 * fraction:.2g} % of the variance (under "
             f"{100 * WEAK_PERIOD_FRACTION:g} %, what the strongest line of random roughness "
             f"holds)")
        if longer >= 0.5:
            w += (f"; {100 * longer:.3g} % lies at periods longer than the longest searched "
                  f"({rng['longest_mm'] * MM_TO_UM:.4g} um): form or waviness left over, which "
                  f"removing more form takes away (the period stays, its share rises)")
        note = w if note is None else f"{note}; {w}"
    return {"period_mm": float(1.0 / f0), "frequency_per_mm": f0,
            "harmonics": harmonics, "fraction": fraction, "weak": weak,
            "above_median": float(power[k] / floor) if floor > 0 else float("inf"),
            "search_mm": rng, "rises_to": rises_to, "note": note}


def dominant_periods(z: np.ndarray, *, spacing: float) -> dict:
    """The dominant period of a profile (heights any unit, ``spacing`` mm) and its
    harmonics: ``period_mm`` (None when the trace is too short), ``frequency_per_mm``,
    ``harmonics`` (``order``, ``period_mm``, ``relative_power``), ``fraction`` (share of the
    variance in them), ``above_median`` (the line's height over the spectrum's median),
    ``search_mm`` (``shortest_mm``, ``longest_mm``: the range searched), ``rises_to``
    ("longest" or "shortest" when the spectrum is largest at that end of the range, else
    None), ``weak`` (the period holds less than :data:`WEAK_PERIOD_FRACTION` of the
    variance) and ``note`` (why there is no period, that the spectrum rises to an end of
    the range, or that the period is weak and where the rest of the variance lies; None
    when none of these)."""
    check_positive("spacing", spacing)
    f = _filled(z)
    w = np.hanning(f.size)
    power = np.abs(np.fft.rfft(f * w)) ** 2
    freq = np.fft.rfftfreq(f.size, d=spacing)
    return _peaks(freq, power, spacing=spacing, n_total=f.size)


def map_periods(z: np.ndarray, *, pixel: float) -> dict:
    """:func:`dominant_periods` of a map (``pixel`` mm, square) from its radially averaged
    2-D periodogram."""
    check_positive("pixel", pixel)
    z = np.asarray(z, dtype=np.float64)
    ok = np.isfinite(z)
    if ok.sum() < 64 or min(z.shape) < 8:
        raise InputError(f"a map spectrum needs at least 8 x 8 measured points, got shape {z.shape}")
    f = np.where(ok, z - np.nanmean(z), 0.0)
    ny, nx = f.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    a = np.c_[np.ones(ok.sum()), xx[ok], yy[ok]]
    c, *_ = np.linalg.lstsq(a, z[ok], rcond=None)
    f = np.where(ok, z - (c[0] + c[1] * xx + c[2] * yy), 0.0)
    w = np.outer(np.hanning(ny), np.hanning(nx))
    p2 = np.abs(np.fft.fft2(f * w)) ** 2
    fy = np.fft.fftfreq(ny, d=pixel)
    fx = np.fft.fftfreq(nx, d=pixel)
    fr = np.hypot(fy[:, None], fx[None, :])
    n = min(nx, ny)
    df = 1.0 / (n * pixel)
    b = np.rint(fr / df).astype(int)
    nb = n // 2 + 1
    keep = b < nb
    power = np.bincount(b[keep], weights=p2[keep], minlength=nb)
    count = np.bincount(b[keep], minlength=nb)
    power = power / np.maximum(count, 1) * (2 * math.pi * np.arange(nb) + 1)  # ring total
    freq = np.arange(nb) * df
    return _peaks(freq, power, spacing=pixel, n_total=n)


#: profiles longer than this are searched for their mirror centre on block means first
MIRROR_FULL_POINTS = 4000


def _mirror_search(f, ok, twices, min_arm):
    """(correlation, centre in samples, arm) of the best mirror centre among ``twices``
    (twice the centre, in samples)."""
    n = f.size
    best = (-2.0, None, 0)
    for twice in twices:
        c = twice / 2.0
        k = twice // 2
        if twice % 2 == 0:  # centre on sample k: pairs (k - t, k + t), t >= 1
            arm = min(k, n - 1 - k)
            t = np.arange(1, arm + 1)
            left, right = k - t, k + t
        else:  # centre between k and k + 1: pairs (k - t, k + 1 + t), t >= 0
            arm = min(k, n - 2 - k)
            t = np.arange(0, arm + 1)
            left, right = k - t, k + 1 + t
        if arm < 1:
            continue
        m = ok[left] & ok[right]
        if m.sum() < min_arm:
            continue
        a, b = f[left][m], f[right][m]
        sa, sb = a.std(), b.std()
        if sa == 0 or sb == 0:
            continue
        r = float(np.mean((a - a.mean()) * (b - b.mean())) / (sa * sb))
        if r > best[0]:
            best = (r, c, arm)
    return best


def mirror_centre(z: np.ndarray, *, spacing: float, x0: float = 0.0) -> dict:
    """Where a profile is most nearly mirror-symmetric: ``centre_mm`` (position, with
    ``x0`` the position of the first point), ``symmetry`` (the correlation coefficient of
    the two arms, -1..1) and ``arm_mm`` (the length compared on each side).  A profile of
    more than :data:`MIRROR_FULL_POINTS` points is searched on block means first and the
    centre then refined on the points themselves."""
    f = _filled(z)
    ok = np.isfinite(np.asarray(z, dtype=np.float64).ravel())
    n = f.size
    min_arm = max(4, n // 5)
    twices = range(2 * min_arm, 2 * (n - 1 - min_arm) + 1)
    if n > MIRROR_FULL_POINTS:
        q = int(math.ceil(n / (MIRROR_FULL_POINTS / 2)))
        m = n // q
        fc = f[:m * q].reshape(m, q).mean(axis=1)
        okc = ok[:m * q].reshape(m, q).all(axis=1)
        coarse = _mirror_search(fc, okc, range(2 * max(4, m // 5), 2 * (m - 1 - max(4, m // 5)) + 1),
                                max(4, m // 5))
        if coarse[1] is not None:
            # block j's mean sits at sample j q + (q - 1) / 2
            c = coarse[1] * q + (q - 1) / 2
            twices = range(max(twices.start, int(2 * c) - 4 * q),
                           min(twices.stop, int(2 * c) + 4 * q + 1))
    best = _mirror_search(f, ok, twices, min_arm)
    if best[1] is None:
        return {"centre_mm": None, "symmetry": None, "arm_mm": 0.0}
    return {"centre_mm": float(x0 + best[1] * spacing), "symmetry": best[0],
            "arm_mm": float(best[2] * spacing)}


def arms_agree(left: dict, right: dict) -> tuple[bool, str]:
    """Whether the two arms of a profile about its mirror centre show the same feed-mark
    period, as a trace through a turned part's spindle axis does (each arm crosses the
    same radii): (agree, why).  ``left`` and ``right`` are :func:`dominant_periods` with
    ``length_mm``.  They agree when their frequencies differ by no more than
    :data:`ARMS_REL_TOL` of their mean or one line of the shorter arm's periodogram
    (1 / its length), whichever is wider: the spectrum resolves no finer, and the
    allowance (not derived from a model) admits arms of unequal length, the longer of which
    also crosses radii where a program that changes its feed with the radius cuts another
    period."""
    pl, pr = left.get("period_mm"), right.get("period_mm")
    if not pl or not pr:
        side = "left" if not pl else "right"
        return False, f"the {side} arm shows no period"
    fl, fr = 1.0 / pl, 1.0 / pr
    tol = max(ARMS_REL_TOL * 0.5 * (fl + fr),
              1.0 / min(left.get("length_mm", math.inf), right.get("length_mm", math.inf)))
    if abs(fl - fr) <= tol:
        return True, ""
    return False, (f"the arms' periods differ ({pl * MM_TO_UM:.4g} um left, {pr * MM_TO_UM:.4g} um "
                   f"right), more than a trace through the spindle axis allows")


def profile_periods(x: np.ndarray, z: np.ndarray, *, spacing: float) -> dict:
    """The periods a profile report shows: ``whole`` (:func:`dominant_periods`),
    ``mirror`` (:func:`mirror_centre` with ``through_axis`` True or False and, when False,
    ``why``) and, when the profile is a trace through the spindle axis of a turned part,
    ``through_axis`` = {``centre_mm``, ``symmetry``, ``left``, ``right``}: the period on
    each side of the centre.  Through the axis means mirror-symmetric about a point
    (:data:`MIRROR_MIN`) with the same period on both arms (:func:`arms_agree`)."""
    x = np.asarray(x, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    out = {"whole": dominant_periods(z, spacing=spacing)}
    mc = dict(mirror_centre(z, spacing=spacing, x0=float(x[0])))
    out["mirror"] = mc
    mc["through_axis"] = False
    if mc["centre_mm"] is None:
        mc["why"] = "the trace is too short to look for a mirror centre"
        return out
    if mc["symmetry"] < MIRROR_MIN:
        mc["why"] = (f"not mirror-symmetric (best correlation {mc['symmetry']:.3g} at "
                     f"{mc['centre_mm']:.4g} mm, under {MIRROR_MIN:g})")
        return out
    side = {}
    for name, sel in (("left", x < mc["centre_mm"]), ("right", x > mc["centre_mm"])):
        zz = z[sel]
        if np.isfinite(zz).sum() >= 16:
            side[name] = dominant_periods(zz, spacing=spacing)
            side[name]["length_mm"] = float(sel.sum() * spacing)
        else:
            side[name] = {"period_mm": None, "length_mm": float(sel.sum() * spacing)}
    agree, why = arms_agree(side["left"], side["right"])
    if not agree:
        mc["why"] = (f"mirror-symmetric about {mc['centre_mm']:.4g} mm (correlation "
                     f"{mc['symmetry']:.3g}) but {why}")
        return out
    mc["through_axis"] = True
    out["through_axis"] = {"centre_mm": mc["centre_mm"], "symmetry": mc["symmetry"], **side}
    return out
