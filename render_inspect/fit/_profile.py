"""The misfit between a measured and a predicted profile (a slice across turning marks).

A profile fit compares three terms, each a vector of normalised residuals of fixed length,
through the same soft-L1 loss as the areal fit (:mod:`._features`):

* ``harmonics``: the marks' fundamental spatial frequency (the peak of the profile's
  Hann-windowed power spectrum, found on a 16-times zero-padded transform and refined by a
  parabola through the log power at its top: smooth in the feed, not stepped by the
  transform's bins) and the amplitudes of its first harmonics (the windowed transform
  evaluated at exactly 1, 2, 3 times the fundamental; a prediction's harmonics are read
  around its own fundamental, so the term moves with the feed over the whole bounds).  The
  frequency gives the feed per revolution, the amplitudes the cusp's shape (the nose
  radius);
* ``params``: ISO 21920-2's Ra, Rq and Rt (log ratios) of each profile, the parabola
  fitted over the window taken as the mean line (a window of a few feed periods is shorter
  than the standard's lambda_c);
* ``profile``: the profile itself, point by point, after the measured one is registered
  along the line to the prediction (the shift with the largest correlation within half a
  period either way, refined to a fraction of a sample (the features at the nearest whole
  one): the marks' phase, set by where the
  spiral began and where the slice was taken, is not fitted).

With a random part's amplitude free, a fourth term, ``psd``, compares the profile's
non-periodic spectrum with the prediction's plus the random parts' power
(:mod:`._profile_psd`).

The camera's noise (and any random part of the cut) is not in the predictions: its effect
is measured on a few realisations, which widen the terms' scales and give the random parts'
standard error (:func:`set_profile_noise_floor`, :func:`profile_realisation_shifts`).
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.units import MM_TO_NM, MM_TO_UM
from ._features import harmonic_residuals, soft_l1
from ._profile_psd import (CLEAN_ABOVE, band_edges, effective_cells, predicted_bands,
                           profile_band_power, psd_bands, psd_residuals)
from ._weights import check_weights

__all__ = ["set_profile_psd", "ProfileSpec", "ProfileTarget", "ProfilePrediction", "make_profile_target",
           "predict_profile_features", "profile_residual_vector", "set_profile_noise_floor",
           "profile_realisation_shifts", "profile_fundamental", "PROFILE_TERMS"]

PROFILE_TERMS = ("profile", "params", "harmonics", "psd")
#: the marks are looked for above this many cycles per window
PROFILE_MIN_PERIODS = 3.0
#: zero padding of the spectrum that locates the fundamental
PAD = 16


@dataclass(frozen=True)
class ProfileSpec:
    """How measured and predicted profiles are compared.

    ``weights``: ``profile``, ``params``, ``harmonics`` (0 leaves a term out);
    ``harmonics``: the harmonics whose amplitudes are compared; the scales:
    ``sigma_frequency`` (relative), ``sigma_amplitude`` (of the measured fundamental),
    ``sigma_params`` (relative, Ra and Rq; Rt three times that: its extremes depend on
    where the samples fall on the cusps' tips), ``sigma_profile_fraction`` (of
    the measured profile's rms)."""

    weights: dict = field(default_factory=lambda: {"profile": 1.0, "params": 1.0,
                                                   "harmonics": 1.0, "psd": 1.0})
    harmonics: int = 3
    sigma_frequency: float = 2e-3
    sigma_amplitude: float = 0.01
    sigma_params: float = 0.02
    sigma_profile_fraction: float = 0.05

    def __post_init__(self):
        check_weights(self.weights, PROFILE_TERMS, of=" for a profile")

    def to_dict(self) -> dict:
        return {"kind": "profile",
                "weights": {k: float(self.weights.get(k, 0.0)) for k in PROFILE_TERMS},
                "harmonics": int(self.harmonics), "form": "parabola over the window",
                "sigma": {"frequency": self.sigma_frequency, "amplitude": self.sigma_amplitude,
                          "params": self.sigma_params,
                          "profile_fraction": self.sigma_profile_fraction},
                "robust": "soft-L1"}


def _detrend(z):
    """``z`` less the least-squares parabola over its measured points (NaN kept)."""
    z = np.asarray(z, dtype=np.float64).ravel()
    ok = np.isfinite(z)
    if ok.sum() < 16:
        raise InputError(f"the profile has {int(ok.sum())} measured points in the fitted "
                         f"window; at least 16 are needed")
    t = np.linspace(-1.0, 1.0, z.size)
    c = np.polyfit(t[ok], z[ok], 2)
    return z - np.polyval(c, t)


def _filled(d):
    ok = np.isfinite(d)
    i = np.arange(d.size)
    return np.interp(i, i[ok], d[ok])


def profile_fundamental(d: np.ndarray, spacing: float) -> float | None:
    """The marks' fundamental frequency (cycles/mm) of a detrended profile ``d``: the
    strongest peak above :data:`PROFILE_MIN_PERIODS` cycles per window of the Hann-windowed,
    zero-padded spectrum, refined by a parabola through the log power at its top; None
    when no peak stands out (10 x the spectrum's median)."""
    f = _filled(d)
    n = f.size
    w = np.hanning(n)
    nfft = PAD * (1 << int(math.ceil(math.log2(n))))
    p = np.abs(np.fft.rfft((f - f.mean()) * w, nfft)) ** 2
    k = np.fft.rfftfreq(nfft, spacing)
    use = k >= PROFILE_MIN_PERIODS / (n * spacing)
    if not use.any():
        return None
    pu = np.where(use, p, 0.0)
    i = int(np.argmax(pu))
    if pu[i] <= 0 or pu[i] < 10 * float(np.median(p[use])) or i + 1 >= p.size:
        return None
    a, b, c = np.log(np.maximum(p[i - 1:i + 2], 1e-300))
    den = a - 2 * b + c
    off = 0.5 * (a - c) / den if den < 0 else 0.0
    return float(k[i] + np.clip(off, -1, 1) * (k[1] - k[0]))


def _harmonics(d, spacing: float, k0: float, n: int) -> np.ndarray:
    """Amplitudes (mm) of the harmonics 1..n of ``k0`` (cycles/mm): the Hann-windowed
    transform evaluated at each multiple, scaled so that a sine of amplitude A reads A."""
    f = _filled(d)
    f = f - f.mean()
    w = np.hanning(f.size)
    x = np.arange(f.size) * spacing
    out = []
    for h in range(1, n + 1):
        e = np.exp(-2j * math.pi * h * k0 * x)
        out.append(2.0 * abs(np.sum(f * w * e)) / np.sum(w))
    return np.array(out)


def _params(d) -> np.ndarray:
    """(Ra, Rq, Rt) of a detrended profile (mm)."""
    v = d[np.isfinite(d)]
    v = v - v.mean()
    return np.array([float(np.mean(np.abs(v))), float(np.sqrt(np.mean(v * v))),
                     float(v.max() - v.min())])


@dataclass
class ProfileTarget:
    """The measured profile's features (what :func:`profile_residual_vector` compares).

    ``z``: the measured window less its parabola (mm, NaN = not measured); ``lag``: the
    samples the predicted profile reaches beyond the window on each side (the registration's
    room)."""

    z: np.ndarray
    spacing: float
    spec: ProfileSpec
    lag: int
    peak: float | None
    centroid: float | None
    amplitudes: np.ndarray
    params: np.ndarray
    sigma_profile: float
    sigma_frequency: float | None = None
    sigma_amplitudes: np.ndarray | None = None
    sigma_params: np.ndarray | None = None
    scatter: dict = field(default_factory=dict)
    draws: list = field(default_factory=list)
    kind: str = "profile"
    # the ``psd`` term (a fitted random part's amplitude; :mod:`._profile_psd`): band
    # edges (cycles/mm), the measured bands (mm^3), which are used, the floor, the fitted
    # parts' power at their start (index, start, bands), the Gamma bias and scatter (ln)
    psd_edges: np.ndarray | None = None
    psd: np.ndarray | None = None
    psd_use: np.ndarray | None = None
    psd_floor: np.ndarray | None = None
    psd_scaled: list = field(default_factory=list)
    psd_bias: np.ndarray | None = None
    psd_sigma: np.ndarray | None = None

    @property
    def height(self) -> np.ndarray:
        return self.z

    def summary(self) -> dict:
        per = None if not self.centroid else 1.0 / self.centroid
        return {"kind": "profile", "feed_period_mm": per,
                "harmonic_amplitudes_nm": [float(a) * MM_TO_NM for a in self.amplitudes],
                "Ra_nm": float(self.params[0]) * MM_TO_NM,
                "Rq_nm": float(self.params[1]) * MM_TO_NM,
                "Rt_nm": float(self.params[2]) * MM_TO_NM,
                "points": int(np.isfinite(self.z).sum()), "spacing_mm": self.spacing,
                "registration_room_samples": int(self.lag),
                "sigma_profile_nm": self.sigma_profile * MM_TO_NM,
                "sigma_frequency": self.sigma_frequency or self.spec.sigma_frequency,
                "sigma_amplitudes_nm": None if self.sigma_amplitudes is None else
                [float(a) * MM_TO_NM for a in self.sigma_amplitudes],
                "random_parts_scatter": self.scatter}


@dataclass
class ProfilePrediction:
    """A predicted profile's features; ``height``: the registered prediction over the
    window (mm), ``shift``: the registration (samples, the prediction's offset)."""

    height: np.ndarray
    full: np.ndarray
    centroid: float | None
    amplitudes: np.ndarray
    params: np.ndarray
    shift: float = 0.0
    psd: np.ndarray | None = None


def make_profile_target(z: np.ndarray, *, spacing: float, lag: int,
                        spec: ProfileSpec) -> ProfileTarget:
    """The features of the measured window ``z`` (mm)."""
    d = _detrend(z)
    k0 = profile_fundamental(d, spacing)
    if k0 is not None:
        amps = _harmonics(d, spacing, k0, spec.harmonics)
    else:
        amps = np.zeros(spec.harmonics)
    prm = _params(d)
    sigma = max(spec.sigma_profile_fraction * float(prm[1]), 0.02 / MM_TO_NM)
    return ProfileTarget(d, float(spacing), spec, int(lag), k0, k0, amps, prm, sigma)


def _register(p, target: ProfileTarget) -> tuple[np.ndarray, np.ndarray, float]:
    """The part of the longer predicted profile ``p`` (window + ``lag`` samples each side)
    that best matches the measured window: (the registered prediction at the fractional
    shift and at the nearest whole one, detrended, on the window's samples; the shift in
    samples)."""
    m = target.z
    n = m.size
    lag = target.lag
    pf = _filled(p)
    ok = np.isfinite(m)
    mm = np.where(ok, m, 0.0)
    period = (1.0 / target.centroid / target.spacing) if target.centroid else lag
    reach = int(min(lag, max(1, math.ceil(0.6 * period))))
    lags = np.arange(lag - reach, lag + reach + 1)
    scores: Any = []
    for s in lags:
        seg = pf[s:s + n]
        seg = seg - np.polyval(np.polyfit(np.arange(n), seg, 2), np.arange(n))
        scores.append(float(np.sum(seg[ok] * mm[ok])))
    scores = np.array(scores)
    j = int(np.argmax(scores))
    off = 0.0
    if 0 < j < len(scores) - 1:
        a, b, c = scores[j - 1:j + 2]
        den = a - 2 * b + c
        off = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) if den < 0 else 0.0
    # the profile compared point by point at the fractional shift; the features (Ra, Rt,
    # the harmonics) at the whole one: interpolation rounds the cusps' tips, which the
    # instrument samples as they fall
    start = int(lags[j])
    whole = np.where(ok, pf[start:start + n], np.nan)
    fine = np.where(ok, np.interp(start + off + np.arange(n), np.arange(pf.size), pf), np.nan)
    return _detrend(fine), _detrend(whole), float(start + off - lag)


def predict_profile_features(z: np.ndarray, target: ProfileTarget,
                             values: Sequence[float] | np.ndarray | None = None, *,
                             measured: bool = False) -> ProfilePrediction:
    """The features of a predicted profile ``z`` (mm; the window and ``target.lag``
    samples either side; a (1, n) array is accepted).  ``measured``: a realisation taken
    as a measurement (its window only, unregistered)."""
    z = np.asarray(z, dtype=np.float64).ravel()
    spec = target.spec
    lag = target.lag
    n = target.z.size
    if z.size != n + 2 * lag:
        raise InputError(f"the predicted profile has {z.size} points; the fit expects "
                         f"{n + 2 * lag}")
    if np.isfinite(z).sum() < 0.5 * z.size:
        raise InputError(f"the virtual instrument measured {int(np.isfinite(z).sum())} of "
                         f"{z.size} points along the line")
    if measured:
        win = np.where(np.isfinite(target.z), _filled(z)[lag:lag + n], np.nan)
        h, shift = _detrend(win), 0.0
        whole = h
    else:
        h, whole, shift = _register(z, target)
    # the spectrum and the parameters of the registered prediction: over the window at
    # the measured marks' phase (a window of a few periods that is not a whole number of
    # them reads Ra, Rt and the windowed amplitudes a little differently at another phase)
    own = whole
    k0 = profile_fundamental(own, target.spacing)
    if k0 is None:
        k0 = target.peak
    amps = (_harmonics(own, target.spacing, k0, spec.harmonics) if k0 is not None
            else np.zeros(spec.harmonics))
    psd = None
    if target.psd_edges is not None:
        psd = profile_band_power(target, own, k0)
        if not measured:
            psd = predicted_bands(psd, target, values)
    return ProfilePrediction(h, z, k0, amps, _params(own), shift, psd)


def profile_residual_vector(pred: ProfilePrediction,
                            target: ProfileTarget) -> tuple[np.ndarray, np.ndarray, dict]:
    """(d, a, terms): normalised residuals, each entry's term weight, each term's share of
    the misfit (as :func:`~render_inspect.fit.residual_vector`)."""
    spec = target.spec
    w = spec.weights
    ds, As, terms = [], [], {}

    def add(name, d):
        d = np.where(np.isfinite(d), d, 0.0)
        a = np.full(d.size, math.sqrt(w[name] / max(d.size, 1)))
        ds.append(d)
        As.append(a)
        terms[name] = float(np.sum(a * a * soft_l1(d)))

    if w.get("profile", 0) > 0:
        ok = np.isfinite(target.z)
        add("profile", (pred.height[ok] - target.z[ok]) / target.sigma_profile)
    if w.get("params", 0) > 0:
        sp = target.sigma_params
        if sp is None:
            sp = spec.sigma_params * np.array([1.0, 1.0, 3.0])
        with np.errstate(divide="ignore", invalid="ignore"):
            lr = np.log(np.maximum(pred.params, 1e-300) / np.maximum(target.params, 1e-300))
        add("params", lr / sp)
    if w.get("harmonics", 0) > 0 and target.peak is not None:
        add("harmonics", harmonic_residuals(target, pred, spec))
    if (w.get("psd", 0) > 0 and target.psd_use is not None and pred.psd is not None
            and target.psd_use.any()):
        add("psd", psd_residuals(pred, target))
    if not ds:
        return np.zeros(1), np.zeros(1), terms
    return np.concatenate(ds), np.concatenate(As), terms


def set_profile_noise_floor(target: ProfileTarget, noisy: Sequence[np.ndarray],
                            clean: np.ndarray) -> None:
    """Widen the terms' scales to what realisations ``noisy`` of the camera's noise (and
    the random parts) differ by from the ``clean`` prediction, and keep the realisations'
    features (``target.draws``) for the random parts' standard error."""
    noisy = [np.asarray(z, dtype=np.float64).ravel() for z in noisy]
    if len(noisy) < 2:
        return
    c = predict_profile_features(clean, target, measured=True)
    feats = [predict_profile_features(z, target, measured=True) for z in noisy]
    diffs = np.concatenate([f.height - c.height for f in feats])
    diffs = diffs[np.isfinite(diffs)]
    scatter: dict[str, Any] = {"draws": len(noisy)}
    if diffs.size:
        s = float(np.sqrt(np.mean(diffs ** 2)))
        scatter["profile_rms_nm"] = s * MM_TO_NM
        target.sigma_profile = max(target.sigma_profile, s)
    spec = target.spec
    ks = np.array([f.centroid if f.centroid is not None else np.nan for f in feats])
    if target.peak is not None and np.all(np.isfinite(ks)):
        s_f = float(np.std(ks, ddof=1) / np.mean(ks))
        scatter["frequency_relative"] = s_f
        target.sigma_frequency = max(spec.sigma_frequency, s_f)
        a = np.array([f.amplitudes for f in feats])
        s_a = np.std(a, axis=0, ddof=1)
        scatter["amplitudes_nm"] = [float(v) * MM_TO_NM for v in s_a]
        floor = spec.sigma_amplitude * max(float(target.amplitudes[0]), 1e-12)
        target.sigma_amplitudes = np.maximum(np.nan_to_num(s_a), floor)
    lp = np.log(np.maximum(np.array([f.params for f in feats]), 1e-300))
    s_p = np.std(lp, axis=0, ddof=1)
    scatter["params_relative"] = [float(v) for v in s_p]
    target.sigma_params = np.maximum(s_p, spec.sigma_params * np.array([1.0, 1.0, 3.0]))
    target.scatter = scatter
    target.draws = feats


def profile_realisation_shifts(pred: ProfilePrediction, target: ProfileTarget) -> np.ndarray:
    """(R, m): how the normalised residuals of ``pred`` change when the measured profile's
    features are replaced by those of each realisation (``target.draws``), less their
    mean (an empty array without two realisations)."""
    feats = target.draws
    if len(feats) < 2:
        return np.zeros((0, 0))
    has_peak = target.peak is not None and all(f.centroid is not None for f in feats)

    def as_target(z, centroid, amplitudes, params, psd=None):
        return replace(target, z=z, centroid=centroid if has_peak else target.centroid,
                       amplitudes=amplitudes, params=params,
                       psd=target.psd if psd is None else psd)

    with_psd = target.psd is not None and all(f.psd is not None for f in feats)
    # (the bands' geometric mean: its logarithm is a single band's expected one)
    mean = as_target(np.mean([f.height for f in feats], axis=0),
                     float(np.mean([f.centroid for f in feats])) if has_peak else None,
                     np.mean([f.amplitudes for f in feats], axis=0),
                     np.exp(np.mean([np.log(np.maximum(f.params, 1e-300)) for f in feats],
                                    axis=0)),
                     np.exp(np.mean([np.log(np.maximum(f.psd, 1e-300)) for f in feats],
                                    axis=0)) if with_psd else None)
    # the prediction registered once (against the measured window), compared with each
    base = profile_residual_vector(pred, mean)[0]
    return np.array([profile_residual_vector(pred, as_target(
        f.height, f.centroid, f.amplitudes, f.params, f.psd if with_psd else None))[0] - base
                     for f in feats])


def period_text(k: float | None) -> str:
    return "none" if not k else f"{1.0 / k * MM_TO_UM:.4g} um"


#: relative difference of the two halves' periods beyond which the feed varies along the
#: window (the marks are not one periodic family); the halves of a real slice's window of
#: constant feed differ by up to a few per cent (uneven scallops)
HALVES_SPREAD = 0.05


def profile_family(d: np.ndarray, spacing: float, *, axis_at_mm: float | None = None) -> dict:
    """Whether a detrended profile ``d`` (mm) carries one periodic family of marks: the
    period of each half of it (:func:`profile_fundamental`) and whether the window holds
    the line's closest point to the spindle axis (``axis_at_mm``, from the window's start;
    None: the line does not pass the axis there): a turned part's marks are mirror images
    about that point, two families for a model of one.  (A periodic profile of symmetric
    cusps is mirror-symmetric about each cusp, so the mirror is told from the line's
    geometry, not from the heights.)  Returns ``{"periods_mm": [first half, second half],
    "spread": relative, "mirror_at_mm", "one_family": bool, "reason": text}``."""
    f = _filled(np.asarray(d, dtype=np.float64).ravel())
    n = f.size
    half = n // 2
    periods = []
    for part in (f[:half], f[half:]):
        k = profile_fundamental(_detrend(part), spacing) if part.size >= 32 else None
        periods.append(None if k is None else 1.0 / k)
    good = [p for p in periods if p is not None]
    spread = abs(good[0] - good[1]) / float(np.mean(good)) if len(good) == 2 else None
    mirror = axis_at_mm if axis_at_mm is not None and 0 <= axis_at_mm <= n * spacing else None
    reasons = []
    if mirror is not None:
        reasons.append(f"the window holds the line's closest point to the spindle axis "
                       f"({mirror:.4g} mm from its start): the marks either side are mirror "
                       f"images, two families of marks")
    if spread is not None and spread > HALVES_SPREAD:
        reasons.append(f"the marks' period changes from {good[0] * MM_TO_UM:.4g} um to "
                       f"{good[1] * MM_TO_UM:.4g} um along the window (a feed that varies "
                       f"with the radius; the model cuts one feed)")
    return {"periods_mm": periods, "spread": spread,
            "mirror_at_mm": None if mirror is None else float(mirror),
            "one_family": not reasons, "reason": "; ".join(reasons)}


def set_profile_psd(target: ProfileTarget, clean: np.ndarray, noisy: Sequence[np.ndarray],
                    scaled: Sequence[tuple[int, float, Sequence[np.ndarray]]] = (), *,
                    draws: int = 1) -> dict:
    """Give the profile ``target`` its ``psd`` term: the measured bands, the floor (the
    mean bands of ``noisy``, realisations with the fixed random parts and the camera's
    noise (profiles, mm, as the evaluations return them), less the ``clean`` prediction's),
    and for each fitted random part ``(index, start, [its realisations alone])`` the power
    it adds at its start value.  Bands without cells, and bands where the clean
    prediction's non-periodic power exceeds :data:`CLEAN_ABOVE` times the random parts'
    expected power, are left out.  Returns what was set, for ``fit.json`` (with each fitted
    part's share of the expected power in the bands used: ``seen``)."""
    from scipy.special import digamma, polygamma

    def bands(z: np.ndarray) -> np.ndarray:
        psd = predict_profile_features(z, target, measured=True).psd
        assert psd is not None  # the target's band edges are set above
        return psd

    n = target.z.size
    target.psd_edges = band_edges(n, target.spacing)
    target.psd, cells = psd_bands(target.z, target.spacing, target.peak, target.psd_edges)
    c = bands(clean)
    floor = np.zeros_like(c)
    if len(noisy):
        floor = np.maximum(_band_mean([bands(z) for z in noisy]) - c, 0.0)
    target.psd_floor = np.nan_to_num(floor)
    target.psd_scaled = []
    expected = target.psd_floor.copy()
    for i, v0, maps in scaled:
        g = np.nan_to_num(np.maximum(_band_mean([bands(z) for z in maps]) - c, 0.0))
        target.psd_scaled.append((int(i), float(v0), g))
        expected = expected + g
    m_eff = np.array([effective_cells(int(m)) for m in cells])
    use = (cells > 0) & np.isfinite(target.psd) & (target.psd > 0) & np.isfinite(c)
    use &= ~(c > CLEAN_ABOVE * expected)
    target.psd_use = use
    safe = np.maximum(m_eff, 1e-9)
    target.psd_bias = np.where(cells > 0, digamma(safe) - np.log(safe), 0.0)
    # the floor and the parts' power are themselves means over a few realisations: their
    # scatter widens the scale
    sig2 = polygamma(1, safe) * (1.0 + 1.0 / max(int(draws), 1))
    total = np.where(use, np.nan_to_num(c) + expected, 0.0)
    seen, share = {}, np.zeros_like(total)
    for i, v0, g in target.psd_scaled:
        part = np.where(use, g / np.maximum(total, 1e-300), 0.0)
        seen[int(i)] = float(np.max(part))
        share = share + part
    # a part drawn along the cut's time (or its distance) is sampled once a revolution
    # along the line: the window holds one independent value per period, not one per
    # periodogram cell, and its bands are aliases of those few values.  The cells its
    # power fills are worth at most (periods - 3) / 2 (the parabola removed), so their
    # scale widens by the ratio
    worth = float(np.sum(np.where(use, m_eff * share, 0.0)))
    periods = n * target.spacing * target.peak if target.peak else math.inf
    line_cells = max((periods - 3.0) / 2.0, 1.0)
    inflation = max(1.0, worth / line_cells) if np.isfinite(line_cells) else 1.0
    target.psd_sigma = np.where(cells > 0, np.sqrt(sig2 * inflation), np.inf)
    return {"bands": int(use.sum()), "edges_per_mm": [float(v) for v in target.psd_edges],
            "cells": [int(m) for m in cells], "used": [bool(u) for u in use],
            "seen": seen, "periods_in_window": periods,
            "scale_widened_by": math.sqrt(inflation)}


def _band_mean(rows: list) -> np.ndarray:
    """Each band's mean over the simulated profiles where it is not NaN, NaN where it is
    NaN in all (``np.nanmean``'s numbers, without its warning for such a band)."""
    a = np.asarray(rows, dtype=np.float64)
    seen = ~np.isnan(a)
    count = seen.sum(axis=0)
    total = np.where(seen, a, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)
