"""Dominant spatial periods of a profile or a map from the power spectrum: the feed-mark
period with its harmonics and, for a profile through the spindle axis of a turned part,
where the centre is and the period on each side of it.

The profile (gaps filled by linear interpolation, a parabola removed) is multiplied by a
Hann window and its periodogram taken; the fundamental is the strongest spectral line
between 4 samples and a quarter of the trace (so that at least four periods are seen),
refined by a parabola through the logarithm of the three bins about it (the Hann window's
main lobe is close to a Gaussian, for which that is exact).  Harmonics are the lines at
k times the fundamental (k = 2 .. 6, each looked for within two bins) that rise ten times
above the spectrum's median.  ``fraction`` is the share of the variance in the
fundamental and its harmonics (two bins either side of each, the Hann main lobe).

A map's spectrum is the radial average of its 2-D periodogram (Hann window in both
directions), so marks of any direction (arcs of a turned part) count alike.

The centre of a profile through the spindle axis is where the profile is most nearly
mirror-symmetric: the correlation coefficient of ``z(c + t)`` with ``z(c - t)`` over the
longer of the two arms that both sides cover (at least a fifth of the trace), found on a
half-sample grid.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError, check_positive

__all__ = ["dominant_periods", "map_periods", "mirror_centre", "profile_periods"]

#: a harmonic counts when its line rises this many times above the median of the spectrum
HARMONIC_ABOVE_MEDIAN = 10.0

#: a profile counts as through the spindle axis when its mirror correlation is at least this
MIRROR_MIN = 0.5


def _filled(z) -> np.ndarray:
    z = np.asarray(z, dtype=np.float64).ravel()
    ok = np.isfinite(z)
    if ok.sum() < 8:
        raise InputError(f"a spectrum needs at least 8 measured points, got {int(ok.sum())}")
    i = np.arange(z.size)
    f = np.interp(i, i[ok], z[ok])
    c = np.polyfit(i - i.mean(), f, 2)
    return f - np.polyval(c, i - i.mean())


def _peaks(freq, power, *, spacing, n_total, n_harmonics=6) -> dict:
    """Fundamental and harmonics from a one-sided spectrum ``power`` at ``freq`` (1/mm)."""
    fmin = 1.0 / (n_total * spacing / 4.0)
    fmax = 1.0 / (4.0 * spacing)
    band = (freq >= fmin) & (freq <= fmax)
    if band.sum() < 3:
        return {"period_mm": None, "harmonics": [], "fraction": 0.0}
    ib = np.flatnonzero(band)
    k = int(ib[np.argmax(power[ib])])
    df = float(freq[1] - freq[0])
    off = 0.0
    if 0 < k < power.size - 1 and min(power[k - 1:k + 2]) > 0:
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
    return {"period_mm": float(1.0 / f0), "frequency_per_mm": f0,
            "harmonics": harmonics, "fraction": float(min(1.0, used / total)) if total > 0 else 0.0,
            "above_median": float(power[k] / floor) if floor > 0 else float("inf")}


def dominant_periods(z: np.ndarray, *, spacing: float) -> dict:
    """The dominant period of a profile (heights any unit, ``spacing`` mm) and its
    harmonics: ``period_mm`` (None when the trace is too short), ``frequency_per_mm``,
    ``harmonics`` (``order``, ``period_mm``, ``relative_power``), ``fraction`` (share of the
    variance in them), ``above_median`` (the line's height over the spectrum's median)."""
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


def profile_periods(x: np.ndarray, z: np.ndarray, *, spacing: float) -> dict:
    """The periods a profile report shows: ``whole`` (:func:`dominant_periods`) and, when
    the profile is mirror-symmetric about a point (:data:`MIRROR_MIN`; a trace through the
    spindle axis of a turned part), ``through_axis`` = {``centre_mm``, ``symmetry``,
    ``left``, ``right``}: the period on each side of the centre."""
    x = np.asarray(x, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    out = {"whole": dominant_periods(z, spacing=spacing)}
    mc = mirror_centre(z, spacing=spacing, x0=float(x[0]))
    out["mirror"] = mc
    if mc["centre_mm"] is not None and mc["symmetry"] >= MIRROR_MIN:
        side = {}
        for name, sel in (("left", x < mc["centre_mm"]), ("right", x > mc["centre_mm"])):
            zz = z[sel]
            if np.isfinite(zz).sum() >= 16:
                side[name] = dominant_periods(zz, spacing=spacing)
                side[name]["length_mm"] = float(sel.sum() * spacing)
        out["through_axis"] = {"centre_mm": mc["centre_mm"], "symmetry": mc["symmetry"], **side}
    return out
