"""Instrument characterisation numbers (ISO 25178-600 / -604 style), arrays in, numbers
out: the transfer of a sinusoid, the response to a step (edge width, batwing), contrast
and drop-out against slope, and measurement noise by subtraction.

Lengths in mm; ``_nm`` / ``_um`` in a key name say where another unit is used.
"""

from __future__ import annotations

from collections.abc import Sequence
import itertools
import math
from typing import NamedTuple

import numpy as np

from ..core.errors import InputError
from ..core.units import NM_TO_MM

__all__ = [
    "batwing",
    "BatwingLobes",
    "dropout_slope",
    "edge_width",
    "noise_by_subtraction",
    "pupil_overlap",
    "sinusoid_amplitude",
    "slope_table",
]


def sinusoid_amplitude(profile: np.ndarray, x: np.ndarray, period: float) -> float:
    """Amplitude of the sinusoid of ``period`` in ``profile`` (least squares with an
    offset; NaN samples left out).

    Parameters
    ----------
    profile : (n,) array;  x : (n,) array, same unit as ``period``
    """
    p = np.asarray(profile, dtype=np.float64)
    xx = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(p)
    if ok.sum() < 3:
        return float("nan")
    a = np.stack([np.cos(2 * np.pi * xx / period), np.sin(2 * np.pi * xx / period),
                  np.ones_like(xx)], axis=1)[ok]
    c = np.linalg.lstsq(a, p[ok], rcond=None)[0]
    return float(math.hypot(c[0], c[1]))


def pupil_overlap(frequency: np.ndarray, *, numerical_aperture: float, illumination_na: float,
                  wavelength_nm: float) -> np.ndarray:
    """The textbook transfer of the interference term for Koehler illumination: the area
    of the illumination disc (radius ``NA_ill / lambda``) inside the pupil (radius
    ``NA / lambda``) shifted by the spatial frequency, over the illumination disc's area.
    A filled pupil gives the incoherent OTF, ``NA_ill = 0`` a step at ``NA / lambda``.

    Parameters
    ----------
    frequency : array, cycles/mm
    numerical_aperture, illumination_na : float
    wavelength_nm : float

    Returns
    -------
    array of the shape of ``frequency``, 0..1
    """
    lam = wavelength_nm * NM_TO_MM
    r1, r2 = illumination_na / lam, numerical_aperture / lam
    d = np.abs(np.asarray(frequency, dtype=np.float64))
    if r1 <= 0:
        return np.where(d < r2, 1.0, np.where(d == r2, 0.5, 0.0))
    out = np.zeros_like(d)
    full = d <= abs(r2 - r1)
    out[full] = 1.0 if r1 <= r2 else (r2 / r1) ** 2
    part = (~full) & (d < r1 + r2)
    dd = d[part]
    a1 = r1 * r1 * np.arccos(np.clip((dd * dd + r1 * r1 - r2 * r2) / (2 * dd * r1), -1, 1))
    a2 = r2 * r2 * np.arccos(np.clip((dd * dd + r2 * r2 - r1 * r1) / (2 * dd * r2), -1, 1))
    a3 = 0.5 * np.sqrt(np.maximum((-dd + r1 + r2) * (dd + r1 - r2) * (dd - r1 + r2) * (dd + r1 + r2), 0))
    out[part] = (a1 + a2 - a3) / (math.pi * r1 * r1)
    return out


def edge_width(profile: np.ndarray, x: np.ndarray, *, low: float = 0.1, high: float = 0.9) -> float:
    """Lateral distance between the ``low`` and ``high`` fractions of a rising edge's
    height (10 % to 90 % by default), by linear interpolation.

    Parameters
    ----------
    profile : (n,) array, rising from one plateau to the next
    x : (n,) array
    """
    p = np.asarray(profile, dtype=np.float64)
    xx = np.asarray(x, dtype=np.float64)
    ok = np.isfinite(p)
    p, xx = p[ok], xx[ok]
    if p.size < 4:
        return float("nan")
    q = max(2, p.size // 8)
    lo, hi = np.median(p[:q]), np.median(p[-q:])
    if not hi > lo:
        raise InputError("edge_width: the profile must rise from its first to its last samples")
    t = (p - lo) / (hi - lo)
    xs = []
    for level in (low, high):
        i = int(np.argmax(t >= level))
        if i == 0:
            xs.append(xx[0])
            continue
        f = (level - t[i - 1]) / (t[i] - t[i - 1])
        xs.append(xx[i - 1] + f * (xx[i] - xx[i - 1]))
    return float(xs[1] - xs[0])


class BatwingLobes(NamedTuple):
    """The two lobes of a batwing at a rising step, in the error's unit (positions in
    ``x``'s unit).

    A step is symmetric under a half-turn about its edge (x -> -x, z -> h - z), so the
    error of an ideal instrument is odd about the edge: the lobe on the upper terrace and
    the lobe on the lower one are equal and opposite, and neither is "the largest". Both
    are reported, each with its side, and their peak-to-valley.
    """

    #: signed extreme of measured - true on the lower terrace (negative: measured too low)
    low: float
    #: distance from the edge to where the lower lobe falls to half its extreme
    low_width: float
    #: signed extreme on the upper terrace (positive: the upper corner overshoots)
    high: float
    #: distance from the edge to where the upper lobe falls to half its extreme
    high_width: float
    #: largest minus smallest error within ``side_length`` of the edge, both sides
    peak_to_valley: float

    @property
    def height(self) -> float:
        """The larger lobe's magnitude (unsigned, so ties between the two sides cannot
        flip it)."""
        return max(abs(self.low), abs(self.high))

    @property
    def width(self) -> float:
        """The mean of the two lobes' half-widths."""
        return 0.5 * (self.low_width + self.high_width)


def batwing(error: np.ndarray, x: np.ndarray, *, edge: float, side_length: float,
            exclude: float = 0.0,
            rising: bool = True) -> BatwingLobes:
    """Batwing of a measured step: the excursion of the measured profile from the true
    one on each side of an edge, and its peak-to-valley.

    Parameters
    ----------
    error : (n,) array
        Measured minus true height along a line across the edge (its far-field median
        removed), same unit as the result.
    x : (n,) array
        Positions; ``edge`` is where the step is.
    side_length : float
        How far from the edge to look, each side.
    exclude : float
        Samples closer than this to the edge are left out (the pixels that straddle it).
    rising : bool
        True when the surface is higher for ``x > edge`` (the upper terrace is on the
        side of larger ``x``).

    Returns
    -------
    BatwingLobes
        ``low`` / ``high``: the signed extreme on the lower / upper terrace (0 where a
        side has no sample), ``low_width`` / ``high_width``: the distance from the edge to
        where each falls to half its extreme, ``peak_to_valley`` over both sides. The
        result does not depend on which side's extreme is larger by a rounding error.
    """
    e = np.asarray(error, dtype=np.float64)
    xx = np.asarray(x, dtype=np.float64)
    lobes = {}
    values = []
    for side in (+1, -1):
        sel = ((side * (xx - edge) >= exclude) & (side * (xx - edge) <= side_length)
               & np.isfinite(e))
        upper = (side > 0) == bool(rising)
        if not sel.any():
            lobes[upper] = (0.0, 0.0)
            continue
        dist = np.abs(xx[sel] - edge)
        order = np.argsort(dist, kind="stable")
        dist, ee = dist[order], e[sel][order]
        values.append(ee)
        i = int(np.argmax(np.abs(ee)))  # first of equal magnitudes: the one nearest the edge
        peak = float(ee[i])
        after = np.nonzero(np.abs(ee[i:]) < abs(peak) / 2)[0]
        width = float(dist[i + after[0]] if after.size else dist[-1])
        lobes[upper] = (peak, width)
    allv = np.concatenate(values) if values else np.zeros(1)
    return BatwingLobes(low=lobes[False][0], low_width=lobes[False][1],
                        high=lobes[True][0], high_width=lobes[True][1],
                        peak_to_valley=float(allv.max() - allv.min()))


def slope_table(slope: np.ndarray, valid: np.ndarray, modulation: np.ndarray, *, bin_rad: float,
                error: np.ndarray | None = None) -> list[dict]:
    """Valid fraction and median contrast of pixels binned by their surface slope.

    Parameters
    ----------
    slope : array, rad (the artefact's known slope at each pixel)
    valid : bool array;  modulation : array (fringe contrast)
    bin_rad : float, bin width, rad
    error : array, optional (measured - true, aligned), its rms per bin

    Returns
    -------
    list of dict
        ``slope_deg`` (bin centre), ``pixels``, ``valid_fraction``, ``contrast``, and
        ``error_rms`` where given.
    """
    s = np.asarray(slope, dtype=np.float64).ravel()
    v = np.asarray(valid, dtype=bool).ravel()
    m = np.asarray(modulation, dtype=np.float64).ravel()
    e = None if error is None else np.asarray(error, dtype=np.float64).ravel()
    ok = np.isfinite(s)
    edges = np.arange(0.0, float(s[ok].max()) + bin_rad, bin_rad)
    rows = []
    for a, b in itertools.pairwise(edges):
        sel = ok & (s >= a) & (s < b)
        n = int(sel.sum())
        if n == 0:
            continue
        row = {"slope_deg": math.degrees(0.5 * (a + b)), "pixels": n,
               "valid_fraction": float(v[sel].mean()), "contrast": float(np.median(m[sel]))}
        if e is not None:
            ee = e[sel & v & np.isfinite(e)]
            row["error_rms"] = float(np.sqrt(np.mean(ee * ee))) if ee.size else float("nan")
        rows.append(row)
    return rows


def dropout_slope(rows: Sequence[dict], *, fraction: float = 0.5) -> float:
    """The slope (deg) at which the valid fraction of :func:`slope_table` first falls below
    ``fraction`` (linear interpolation between bins; NaN if it never does)."""
    for r0, r1 in itertools.pairwise(rows):
        if r0["valid_fraction"] >= fraction > r1["valid_fraction"]:
            t = (r0["valid_fraction"] - fraction) / (r0["valid_fraction"] - r1["valid_fraction"])
            return float(r0["slope_deg"] + t * (r1["slope_deg"] - r0["slope_deg"]))
    return float("nan")


def noise_by_subtraction(first: np.ndarray, second: np.ndarray) -> float:
    """Measurement noise by the subtraction method (ISO 25178-604): the rms of the
    difference of two measurements of one surface, after removing its mean, over
    ``sqrt(2)``; NaN samples left out."""
    d = np.asarray(first, dtype=np.float64) - np.asarray(second, dtype=np.float64)
    d = d[np.isfinite(d)]
    if d.size < 2:
        return float("nan")
    d -= d.mean()
    return float(np.sqrt(np.mean(d * d)) / math.sqrt(2))
