"""The ``psd`` term of a profile fit: what the amplitude of a random part of the cut shows in
one line.

A random part's realisation cannot be reproduced, only its power.  A measured profile is
the clean cut (the evaluations' prediction), the random parts and the camera's noise; the
random parts are independent of the surface, so their powers add.  Each profile (measured,
predicted, realisation) is reduced to its non-periodic part first: the least-squares fit of
its own feed harmonics (every multiple of its fundamental up to the Nyquist frequency, with
a parabola) is removed, so that the marks' power and the leakage of their peaks, many
decades above a few nanometres of random heights, do not mask the bands the random parts
fill.  What is left is averaged, as a Hann-windowed periodogram, in bands of log spatial
frequency, and compared in natural logarithms::

    measured band  <->  clean prediction's band + floor + sum_k G_k (value_k / start_k)^2

``floor``: the power the fixed random parts and the camera's noise add (realisations less
the clean prediction, averaged); ``G_k``: the power a fitted random part adds at its start
value (its realisations alone), scaled with the square of its amplitude (the power of a
random part that enters linearly).  A band of ``m`` periodogram cells of a random profile
holds a Gamma-distributed mean of ``m_eff`` independent exponential cells (adjacent cells
of a Hann window are correlated: ``m_eff`` < ``m``), so its logarithm scatters by
``sqrt(trigamma(m_eff))`` about ``ln P + digamma(m_eff) - ln m_eff``: the residual of a band
is its logarithm less the prediction's and that bias, in that scatter (no scale chosen by
hand).

What a line sees of a random part: a slide's or the spindle's following-error noise is a
function of time, and the radial line on a turned part is cut once a revolution, so along
the line each feed period is cut at one instant and carries one sample of the noise (its
correlation time, milliseconds, is far below a revolution): the heights are steps of
independent offsets, one per period, whose 1-D spectrum is sigma^2 T sinc^2(k T) (T the
period along the line), most of it below the marks' fundamental and none at its multiples,
so removing the harmonics leaves it whole.  A random field of the surface seen along a line
gives its 1-D marginal spectrum; the realisations simulated through the forward model
measure exactly what the line and the instrument see, so no closed form enters the fit.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["PSD_BANDS", "band_edges", "psd_bands", "effective_cells",
           "psd_residuals", "band_residuals", "profile_band_power", "amplitude_scan",
           "predicted_bands", "nonperiodic"]

#: bands of log spatial frequency of the ``psd`` term
PSD_BANDS = 12
#: lowest band edge, cycles per window (the parabola removed takes the lowest cells)
PSD_LOW_CYCLES = 1.5
#: highest band edge, cycles per sample
PSD_HIGH = 0.45
#: bands where the clean prediction's non-periodic power exceeds this many times the random
#: parts' expected power are left out (there the spectrum is the cut's, not the random
#: parts')
CLEAN_ABOVE = 3.0

# (``target`` and ``pred`` below are a profile's target and prediction,
# :class:`~render_inspect.fit.ProfileTarget` and ``ProfilePrediction``: typed Any here because
# their module imports this one)


def _filled(d):
    d = np.asarray(d, dtype=np.float64).ravel()
    ok = np.isfinite(d)
    i = np.arange(d.size)
    return np.interp(i, i[ok], d[ok]) if not ok.all() else d


def nonperiodic(d: np.ndarray, spacing: float, k0: float | None) -> np.ndarray:
    """``d`` less the least-squares fit of a parabola and of the harmonics 1, 2, ... of
    ``k0`` (cycles/mm) below the Nyquist frequency (none without ``k0``)."""
    f = _filled(d)
    n = f.size
    t = np.linspace(-1.0, 1.0, n)
    cols = [np.ones(n), t, t * t]
    if k0:
        x = np.arange(n) * spacing
        for h in range(1, int(0.5 / (spacing * k0)) + 1):
            cols += [np.cos(2 * math.pi * h * k0 * x), np.sin(2 * math.pi * h * k0 * x)]
    a = np.array(cols).T
    c, *_ = np.linalg.lstsq(a, f, rcond=None)
    return f - a @ c


def band_edges(n: int, spacing: float, bands: int = PSD_BANDS) -> np.ndarray:
    """The bands' edges (cycles/mm) for a window of ``n`` samples."""
    return np.geomspace(PSD_LOW_CYCLES / (n * spacing), PSD_HIGH / spacing, bands + 1)


def _periodogram(r, spacing):
    n = r.size
    w = np.hanning(n)
    p = 2.0 * np.abs(np.fft.rfft(r * w)) ** 2 * spacing / float(np.sum(w * w))
    return np.fft.rfftfreq(n, spacing), p


def psd_bands(d: np.ndarray, spacing: float, k0: float | None,
              edges: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(power, cells): the mean one-sided PSD (mm^3) of the non-periodic part of ``d``
    (:func:`nonperiodic`) in each band, NaN for a band without a cell; the cells in each."""
    k, p = _periodogram(nonperiodic(d, spacing, k0), spacing)
    power = np.full(edges.size - 1, np.nan)
    cells = np.zeros(edges.size - 1, dtype=int)
    for b in range(edges.size - 1):
        sel = (k >= edges[b]) & (k < edges[b + 1])
        cells[b] = int(sel.sum())
        if cells[b]:
            power[b] = float(np.mean(p[sel]))
    return power, cells


def effective_cells(m: int) -> float:
    """The number of independent exponential cells a mean of ``m`` adjacent cells of a
    Hann-windowed periodogram is worth (correlation of the powers of neighbours 4/9, of
    cells two apart 1/36)."""
    if m <= 0:
        return 0.0
    var = m + 2 * max(m - 1, 0) * (4.0 / 9.0) + 2 * max(m - 2, 0) / 36.0
    return m * m / var


def profile_band_power(target: Any, z: np.ndarray, k0: float | None) -> np.ndarray:
    """The ``psd`` bands of a profile ``z`` (mm, the window) read around fundamental ``k0``
    with ``target``'s edges."""
    return psd_bands(z, target.spacing, k0, target.psd_edges)[0]


def predicted_bands(pred_bands: np.ndarray, target: Any,
                    values: Sequence[float] | np.ndarray | None = None) -> np.ndarray:
    """A clean prediction's bands with the floor and the fitted random parts' power at
    ``values`` added."""
    p = pred_bands + (target.psd_floor if target.psd_floor is not None else 0.0)
    for i, v0, g in target.psd_scaled:
        v = v0 if values is None else float(values[i])
        p = p + g * (v / v0) ** 2
    return p


def psd_residuals(pred: Any, target: Any) -> np.ndarray:
    """The ``psd`` term's residuals of a prediction (its ``psd``: the predicted bands)."""
    return band_residuals(pred.psd, target)


def band_residuals(bands: np.ndarray, target: Any) -> np.ndarray:
    """ln(measured band) - ln(predicted ``bands``) less the Gamma mean's bias, over its
    scatter, for the bands in use."""
    use = target.psd_use
    with np.errstate(divide="ignore", invalid="ignore"):
        lr = (np.log(np.maximum(target.psd[use], 1e-300))
              - np.log(np.maximum(bands[use], 1e-300)) - target.psd_bias[use])
    return lr / target.psd_sigma[use]


def amplitude_scan(pred: Any, target: Any, values: Sequence[float] | np.ndarray, index: int, *,
                   points: int = 400) -> dict:
    """The ``psd`` term's chi-square (the sum of its residuals' soft-L1 loss, d^2 near 0)
    along the amplitude of the fitted random part ``index``, the other values held at
    ``values``: the amplitude only scales the power the term adds, so the scan needs no
    evaluation.  Returns ``{"best":
    the amplitude of least chi-square, "upper_2se": where it has risen by 4 above it,
    "chi2_at_zero_rise": its rise at amplitude 0}`` (None where out of the scan's range,
    up to 20 times the start or the value)."""
    vals = np.array(values, dtype=np.float64)
    start = next(v0 for i, v0, _ in target.psd_scaled if i == index)
    raw = pred.psd - predicted_bands(np.zeros_like(pred.psd), target, vals)
    top = 20.0 * max(start, float(vals[index]))
    grid = np.linspace(0.0, top, points + 1)
    loss = []
    for v in grid:
        vals[index] = v
        d = band_residuals(predicted_bands(raw, target, vals), target)
        # the fit's own loss (soft-L1: d^2 near 0), so that the scan's least is the fit's
        loss.append(float(np.sum(2.0 * (np.sqrt(1.0 + d * d) - 1.0))))
    chi2 = np.array(loss)
    j = int(np.argmin(chi2))
    above = np.flatnonzero((grid > grid[j]) & (chi2 >= chi2[j] + 4.0))
    return {"best": float(grid[j]),
            "upper_2se": None if not above.size else float(grid[above[0]]),
            "chi2_at_zero_rise": float(chi2[0] - chi2[j])}
