"""The misfit between a measured and a predicted height map, built so that the phase of
the feed marks and small registration errors do not dominate it.

Three terms, each a vector of residuals of fixed length:

* ``map``: the waviness of the two maps (each smoothed by an ISO 16610-61 Gaussian filter
  whose cut-off is five feed periods, so the feed marks themselves, whose phase is set by
  where the spiral began, are averaged out; the border of half a cut-off left out; then
  the form removed), compared point by point on a coarse grid.  Error motions, servo lags
  and the design's features live here.
* ``psd``: the areal power spectral density of the two maps (Hann window), averaged in
  bins of log spatial frequency and of direction, compared as log10 (decades).  Invariant
  to translation: registration and phase do not enter.
* ``harmonics``: the feed marks' fundamental spatial frequency (the strongest annulus of the
  spectrum above the waviness band, refined to a small fraction of a bin by the
  power-weighted centroid of the annulus: concentric marks put their power on a ring,
  straight ones on two points of it, and either way the centroid is the frequency) and
  the amplitudes of its first harmonics (the power in annuli around their multiples; a
  prediction's harmonics are read around its own fundamental, so the term varies with the
  feed over the whole bounds).  The
  frequency gives the feed per revolution, the amplitudes the cusp shape (tool nose radius,
  minimum chip thickness).

The random parts of the cut and the camera's noise are not in the predictions (their
expected value is): their power is added to the predicted PSD as a floor, their effect on
the harmonics as a gain, and the spread of their realisations widens the scales of the
``map`` and ``harmonics`` terms (:func:`set_noise_floor`) and gives the fit's second
standard error (:func:`~render_inspect.fit._uncertainty.realisation_shifts`).

Each term's residuals are normalised (``d = difference / sigma``) and enter through the
soft-L1 (pseudo-Huber) loss ``2 (sqrt(1 + d^2) - 1)`` (quadratic near 0, linear far out),
weighted by ``weight / n`` so that a term's weight does not depend on how many entries it
has.  The misfit is the sum over all entries.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
import math
from dataclasses import dataclass, field
from typing import Any, Literal, cast, overload

import numpy as np

from ..core.errors import InputError
from ._weights import check_weights
from ..core.units import MM_TO_NM, MM_TO_UM
from ..metrology import gaussian_filter, remove_form
from ._harmonics import harmonic_residuals

__all__ = ["MisfitSpec", "Target", "Prediction", "FORMS", "prepare_map", "psd_bins",
           "feed_peak", "harmonic_features", "make_target", "predict_features", "noise_floor",
           "set_noise_floor",
           "residual_vector", "harmonic_residuals", "soft_l1", "robust_weights", "radial_psd",
           "own_peak"]

#: form removal the user may choose (as ``analyze``)
FORMS = ("none", "plane", "poly2", "sphere")
#: PSD bins this many decades below the strongest are left out (the Hann window's leakage)
PSD_RANGE_DECADES = 5.0
TERMS = ("map", "psd", "harmonics")
#: the feed marks are looked for above this many cycles per window
PEAK_MIN_PERIODS = 6.0


@dataclass(frozen=True)
class MisfitSpec:
    """How measured and predicted maps are compared.

    Attributes
    ----------
    form : {"none", "plane", "poly2", "sphere"}
        Form removed from each map first (``none``: the mean only).
    weights : dict
        ``map``, ``psd``, ``harmonics``: the share of each term (0 leaves it out).
    harmonics : int
        Feed harmonics whose amplitudes are compared.
    cutoff_periods : float
        The waviness filter's cut-off in feed periods.
    psd_radial_bins, psd_angle_bins : int
        Bins of log spatial frequency and of direction (over 180 degrees).
    map_points : int
        At most this many points of the waviness map enter the ``map`` term.
    sigma_psd_decades, sigma_frequency, sigma_amplitude : float
        Scales of the robust transform: the log10 PSD (decades; at least the scatter of a
        periodogram averaged over the bin's cells, 1 / sqrt(cells)), the relative feed
        frequency, the harmonics' amplitudes relative to the measured fundamental.
    sigma_map_fraction, sigma_map_min_nm : float
        The ``map`` term's scale: this fraction of the measured waviness rms, at least
        ``sigma_map_min_nm``.
    """

    form: str = "plane"
    weights: dict = field(default_factory=lambda: {"map": 1.0, "psd": 1.0, "harmonics": 1.0})
    harmonics: int = 3
    cutoff_periods: float = 5.0
    psd_radial_bins: int = 16
    psd_angle_bins: int = 6
    map_points: int = 2500
    sigma_psd_decades: float = 0.1
    sigma_frequency: float = 1e-3
    sigma_amplitude: float = 0.01
    sigma_map_fraction: float = 0.005
    sigma_map_min_nm: float = 0.02

    def __post_init__(self):
        if self.form not in FORMS:
            raise InputError(f"--form must be one of {', '.join(FORMS)}, received {self.form!r}")
        check_weights(self.weights, TERMS)
        if not 1 <= int(self.harmonics) <= 10:
            raise InputError(f"harmonics must be in [1, 10], received {self.harmonics!r}")

    def to_dict(self) -> dict:
        return {"form": self.form, "weights": {k: float(self.weights.get(k, 0.0)) for k in TERMS},
                "harmonics": int(self.harmonics), "cutoff_periods": self.cutoff_periods,
                "psd_bins": [self.psd_radial_bins, self.psd_angle_bins],
                "map_points": self.map_points,
                "sigma": {"psd_decades": self.sigma_psd_decades,
                          "frequency": self.sigma_frequency,
                          "amplitude": self.sigma_amplitude,
                          "map_fraction": self.sigma_map_fraction,
                          "map_min_nm": self.sigma_map_min_nm},
                "robust": "soft-L1"}


# ------------------------------------------------------------------------ maps
def prepare_map(z: np.ndarray, *, pixel: Sequence[float], form: str,
                origin: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
    """``z`` (mm, NaN = not measured) with its form removed (``none``: its mean)."""
    z = np.asarray(z, dtype=np.float64)
    ok = np.isfinite(z)
    if ok.sum() < 16:
        raise InputError(f"the map has {int(ok.sum())} valid points; at least 16 are needed")
    method = {"poly2": "polynomial"}.get(form, form)
    if method == "none":
        return np.where(ok, z - np.mean(z[ok]), np.nan)
    res, _ = remove_form(z, pixel=pixel, method=method, degree=2, origin=origin)
    return res


def _hann2(shape) -> np.ndarray:
    ny, nx = shape
    return np.outer(np.hanning(ny), np.hanning(nx))


def _filled(z) -> tuple[np.ndarray, np.ndarray]:
    ok = np.isfinite(z)
    zz = np.where(ok, z, 0.0)
    if ok.any():
        zz = np.where(ok, zz - zz[ok].mean(), 0.0)
    return zz, ok


def _periodogram(z, pixel):
    """Hann-windowed areal PSD (mm^4 per unit, one-sided in no direction) and the
    frequency grids (cycles/mm)."""
    px, py = pixel
    zz, ok = _filled(z)
    w = _hann2(z.shape) * ok
    f = np.fft.fftshift(np.fft.fft2(zz * w))
    norm = max(float(np.sum(w ** 2)), 1e-300)
    p = (np.abs(f) ** 2) * px * py / norm
    ky = np.fft.fftshift(np.fft.fftfreq(z.shape[0], py))
    kx = np.fft.fftshift(np.fft.fftfreq(z.shape[1], px))
    return p, kx, ky


@overload
def psd_bins(z: np.ndarray, *, pixel: Sequence[float], k_range: Sequence[float], radial_bins: int,
             angle_bins: int, counts: Literal[False] = False) -> np.ndarray: ...
@overload
def psd_bins(z: np.ndarray, *, pixel: Sequence[float], k_range: Sequence[float], radial_bins: int,
             angle_bins: int, counts: Literal[True]) -> tuple[np.ndarray, np.ndarray]: ...


def psd_bins(z: np.ndarray, *, pixel: Sequence[float], k_range: Sequence[float], radial_bins: int,
             angle_bins: int, counts: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """The mean areal PSD (mm^4) in bins of log |k| (``k_range`` = (k_min, k_max),
    cycles/mm) and of direction (0-180 degrees); NaN for empty bins.  With ``counts``
    also the number of frequency cells in each bin."""
    p, kx, ky = _periodogram(z, pixel)
    kxx, kyy = np.meshgrid(kx, ky)
    kr = np.hypot(kxx, kyy)
    ang = np.mod(np.arctan2(kyy, kxx), math.pi)
    # each cell shares its power between the two radial bins whose centres (in log |k|)
    # it lies between, linearly: a peak that moves (a feed that changes) moves the binned
    # spectrum smoothly, not in steps at the bins' edges
    lk0, lk1 = math.log(k_range[0]), math.log(k_range[1])
    width = (lk1 - lk0) / radial_bins
    with np.errstate(divide="ignore"):
        pos = (np.log(np.where(kr > 0, kr, np.nan)) - lk0) / width - 0.5
    inside = np.isfinite(pos) & (pos >= -0.5) & (pos < radial_bins - 0.5)
    lo = np.floor(pos[inside]).astype(int)
    frac = pos[inside] - lo
    ai = np.minimum((ang[inside] / math.pi * angle_bins).astype(int), angle_bins - 1)
    pw = p[inside]
    n = np.zeros(radial_bins * angle_bins)
    s = np.zeros(radial_bins * angle_bins)
    for b, wt in ((lo, 1.0 - frac), (lo + 1, frac)):
        ok = (b >= 0) & (b < radial_bins)
        idx = b[ok] * angle_bins + ai[ok]
        n += np.bincount(idx, weights=wt[ok], minlength=radial_bins * angle_bins)
        s += np.bincount(idx, weights=wt[ok] * pw[ok], minlength=radial_bins * angle_bins)
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = np.where(n > 0.5, s / np.maximum(n, 1e-300), np.nan)
    return (mean, n) if counts else mean


def _log10(p) -> np.ndarray:
    p = np.asarray(p, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.log10(np.where(p > 0, p, np.nan))


def radial_psd(z: np.ndarray, *, pixel: Sequence[float], bins: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """(k, PSD): the isotropic (radially averaged) areal PSD on log-spaced bins, for
    figures; k in cycles/mm, PSD in nm^2 mm^2."""
    p, kx, ky = _periodogram(z, pixel)
    kxx, kyy = np.meshgrid(kx, ky)
    kr = np.hypot(kxx, kyy)
    kmin = 1.0 / (min(z.shape[0] * pixel[1], z.shape[1] * pixel[0]))
    kmax = 0.5 / max(pixel)
    edges = np.geomspace(kmin, kmax, bins + 1)
    ri = np.digitize(kr, edges) - 1
    use = (ri >= 0) & (ri < bins)
    n = np.bincount(ri[use], minlength=bins)
    s = np.bincount(ri[use], weights=p[use], minlength=bins)
    k = np.sqrt(edges[1:] * edges[:-1])
    with np.errstate(divide="ignore", invalid="ignore"):
        psd = np.where(n > 0, s / np.maximum(n, 1), np.nan) * MM_TO_NM ** 2
    return k, psd


def _ring_grid(z, pixel):
    """(p, |k|, cell): the Hann-windowed periodogram, each cell's |k| (cycles/mm) and the
    area of one frequency cell (cycles^2/mm^2); the sum of ``p * cell`` is the map's
    (windowed) mean square."""
    p, kx, ky = _periodogram(z, pixel)
    kr = np.hypot(*np.meshgrid(kx, ky))
    cell = 1.0 / (z.shape[1] * pixel[0] * z.shape[0] * pixel[1])
    return p, kr, cell


def _ring(p, kr, cell, k0: float, half: float):
    """(power, centroid |k|) of the spectrum in the annulus |k - k0| <= half, less the
    floor (the median density of the two flanking annuli of the same width)."""
    inner = np.abs(kr - k0) <= half
    flank = (np.abs(kr - k0) > half) & (np.abs(kr - k0) <= 3 * half) & (kr > 0)
    floor = float(np.median(p[flank])) if flank.any() else 0.0
    w = np.maximum(p[inner] - floor, 0.0)
    power = float(np.sum(w) * cell)
    centroid = float(np.sum(w * kr[inner]) / np.sum(w)) if np.sum(w) > 0 else float("nan")
    return power, centroid


def feed_peak(z: np.ndarray, *, pixel: Sequence[float], k_min: float, ring: float = 0.1) -> float | None:
    """The feed marks' fundamental |k| (cycles/mm): the strongest annulus of the spectrum
    above ``k_min``, refined by the power-weighted centroid of the annulus of relative
    half-width ``ring`` around it (robust to curved marks: the power of concentric marks
    lies on a ring, that of straight marks on two points of it).  None when no annulus
    stands out (5 x its flanks)."""
    p, kr, cell = _ring_grid(z, pixel)
    dk = math.sqrt(cell) if cell > 0 else 1.0
    k_max = float(kr.max())
    edges = np.arange(k_min, k_max, dk)
    if edges.size < 4:
        return None
    idx = np.digitize(kr.ravel(), edges) - 1
    use = (idx >= 0) & (idx < edges.size - 1)
    prof = np.bincount(idx[use], weights=p.ravel()[use], minlength=edges.size - 1)
    cnt = np.bincount(idx[use], minlength=edges.size - 1)
    dens = np.where(cnt > 0, prof / np.maximum(cnt, 1), 0.0)
    i = int(np.argmax(dens))
    k0 = 0.5 * (edges[i] + edges[i + 1])
    half = max(ring * k0, 1.5 * dk)
    power, centroid = _ring(p, kr, cell, k0, half)
    flank = (np.abs(kr - k0) > half) & (np.abs(kr - k0) <= 3 * half)
    if not flank.any() or not power > 0 or \
            dens[i] < 5 * float(np.median(p[flank])):
        return None
    # once more around the refined centre
    power, centroid = _ring(p, kr, cell, centroid, half)
    return centroid if np.isfinite(centroid) else None


def harmonic_features(z: np.ndarray, *, pixel: Sequence[float], k0: float, n: int,
                      ring: float = 0.1) -> tuple[float | None, np.ndarray]:
    """(fundamental centroid |k|, amplitudes (mm) of harmonics 1..n): the spectrum's
    power in fixed annuli around m ``k0`` (half-width ``ring`` m ``k0``, at most k0 / 2.5)
    less the flanks' floor; a sinusoid of amplitude A carries A^2 / 2."""
    p, kr, cell = _ring_grid(z, pixel)
    amps, first = [], float("nan")
    for m in range(1, n + 1):
        half = min(ring * m * k0, k0 / 2.5)
        power, centroid = _ring(p, kr, cell, m * k0, half)
        if m == 1:
            first = centroid
        amps.append(math.sqrt(2.0 * max(power, 0.0)))
    return first, np.array(amps)


def waviness(z: np.ndarray, *, pixel: tuple[float, float], cutoff: float | None, form: str = "plane",
             origin: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
    """The map smoothed by the Gaussian filter of ``cutoff`` (mm), with the border of half
    a cut-off left out (there the filter would be one-sided and the feed marks' phase would
    leak in), then its form removed (after the filter: a plane fitted through the marks
    themselves would tilt with their phase); without ``cutoff`` the map with its form
    removed."""
    if cutoff is not None:
        z = gaussian_filter(z, pixel=pixel, cutoff=cutoff, min_weight=0.3, edges="cut")
    return prepare_map(z, pixel=pixel, form=form, origin=origin)


# ------------------------------------------------------------------ target and residuals
@dataclass
class Target:
    """The measured map and its features, computed once per fit."""

    height: np.ndarray          # mm, form removed, NaN = not measured
    pixel: tuple
    origin: tuple
    spec: MisfitSpec
    k_range: tuple              # PSD bins (cycles/mm)
    psd: np.ndarray             # log10 PSD per bin
    psd_use: np.ndarray         # bins that enter the misfit
    psd_sigma: np.ndarray       # each bin's scale (decades)
    peak: float | None          # feed fundamental |k|, cycles/mm (annuli centre)
    centroid: float | None      # the fundamental's centroid in its annulus, cycles/mm
    amplitudes: np.ndarray      # mm
    cutoff: float | None        # waviness filter, mm
    wavy: np.ndarray            # the measured waviness (mm)
    points: tuple               # (rows, cols) of the map term's points
    sigma_map: float            # mm
    psd_floor: np.ndarray | None = None   # the random parts' and noise's power per bin (mm^4)
    psd_scaled: list = field(default_factory=list)  # (index, start, floor) of fitted random parts
    sigma_frequency: float | None = None  # relative; None: the spec's
    sigma_amplitudes: np.ndarray | None = None  # mm per harmonic; None: the spec's
    scatter: dict = field(default_factory=dict)  # what the random parts' realisations vary by
    draws: list = field(default_factory=list)  # Predictions (measured=True) of the realisations
    amplitude_gain: np.ndarray | None = None  # measured / noise-free harmonic amplitudes

    def summary(self) -> dict:
        per = None if self.centroid is None else 1.0 / self.centroid
        return {"feed_period_mm": per,
                "harmonic_amplitudes_nm": [float(a) * MM_TO_NM for a in self.amplitudes],
                "waviness_cutoff_mm": self.cutoff, "map_points": int(len(self.points[0])),
                "psd_bins": int(self.psd_use.sum()), "psd_k_range": list(self.k_range),
                "sigma_map_nm": self.sigma_map * MM_TO_NM,
                "sigma_frequency": self.sigma_frequency or self.spec.sigma_frequency,
                "sigma_amplitudes_nm": None if self.sigma_amplitudes is None else
                [float(a) * MM_TO_NM for a in self.sigma_amplitudes],
                "random_parts_scatter": self.scatter}


def make_target(z: np.ndarray, *, pixel: Sequence[float], origin: Sequence[float], spec: MisfitSpec) -> Target:
    """The measured map's features (see the module docstring)."""
    pixel = (float(pixel[0]), float(pixel[1]))
    h = prepare_map(z, pixel=pixel, form=spec.form, origin=origin)
    ny, nx = h.shape
    length = min(ny * pixel[1], nx * pixel[0])
    k_lo = 2.0 / length
    k_hi = 0.45 / max(pixel)
    if k_hi <= 2 * k_lo:
        raise InputError(f"the fit window ({nx} x {ny} pixels) is too small for a spectrum; "
                         f"use a larger window")
    psd, cells = psd_bins(h, pixel=pixel, k_range=(k_lo, k_hi), radial_bins=spec.psd_radial_bins,
                          angle_bins=spec.psd_angle_bins, counts=True)
    psd = _log10(psd)
    # the scatter of a periodogram averaged over n cells (about n / 4 independent ones
    # under the Hann window): 0.434 / sqrt(n / 4) decades
    psd_sigma = np.maximum(spec.sigma_psd_decades, 1.0 / np.sqrt(np.maximum(cells, 1)))
    # the marks are looked for on the map less its waviness (a Gaussian filter of a tenth
    # of the window): the window's leakage of a curved form would otherwise outshine them
    # in a large window; a window must hold ten feed periods, so the search starts a
    # little below ten cycles per window
    high = h - gaussian_filter(h, pixel=pixel, cutoff=length / 10.0, min_weight=0.3)
    peak = feed_peak(high, pixel=pixel, k_min=PEAK_MIN_PERIODS / length)
    centroid = None
    if peak is not None:
        centroid, amps = harmonic_features(h, pixel=pixel, k0=peak, n=spec.harmonics)
        period = 1.0 / peak
        cutoff = spec.cutoff_periods * period
        if cutoff > length / 2:
            raise InputError(
                f"the fit window ({length:.4g} mm) spans {length / period:.1f} feed periods "
                f"({period * MM_TO_UM:.4g} um); the waviness comparison needs at least "
                f"{2 * spec.cutoff_periods:g}: use a larger --window")
    else:
        amps = np.zeros(spec.harmonics)
        cutoff = None
    wavy = waviness(z, pixel=pixel, cutoff=cutoff, form=spec.form, origin=origin)
    ok = np.isfinite(wavy)
    stride = max(1, int(math.ceil(math.sqrt(ok.sum() / max(spec.map_points, 1)))))
    if cutoff is not None:
        stride = max(stride, int(cutoff / (2 * max(pixel))))
    rows, cols = np.nonzero(ok[::stride, ::stride])
    rows, cols = rows * stride, cols * stride
    rms = float(np.sqrt(np.mean(wavy[ok] ** 2))) if ok.any() else 0.0
    sigma_map = max(spec.sigma_map_fraction * rms, spec.sigma_map_min_nm / MM_TO_NM)
    # bins more than PSD_RANGE_DECADES below the strongest hold the window's leakage of the
    # marks (which moves with their phase), not the surface's own spectrum
    use = np.isfinite(psd) & (psd >= np.nanmax(psd) - PSD_RANGE_DECADES)
    return Target(h, pixel, tuple(origin), spec, (k_lo, k_hi), psd, use, psd_sigma,
                  peak, centroid, amps, cutoff, wavy, (rows, cols), sigma_map)


@dataclass
class Prediction:
    """A predicted map's features (what :func:`residual_vector` compares)."""

    height: np.ndarray
    wavy: np.ndarray
    psd: np.ndarray
    centroid: float | None
    amplitudes: np.ndarray


def predict_features(z: np.ndarray, target: Target, values: Sequence[float] | np.ndarray | None = None,
                     *, measured: bool = False) -> Prediction:
    """The features of a predicted map ``z`` (mm) made at parameter ``values`` (needed
    when a random part's amplitude is fitted: its floor scales with it).  ``measured``:
    the features of a map that holds its random parts and noise (a realisation), as the
    measured map's are taken: no floor, no gain."""
    spec = target.spec
    h = prepare_map(z, pixel=target.pixel, form=spec.form, origin=target.origin)
    psd = psd_bins(h, pixel=target.pixel, k_range=target.k_range,
                   radial_bins=spec.psd_radial_bins, angle_bins=spec.psd_angle_bins)
    if target.psd_floor is not None and not measured:
        psd = psd + target.psd_floor
    for i, v0, floor in (() if measured else target.psd_scaled):
        psd = psd + floor * (float(cast("Sequence[float]", values)[i]) / v0) ** 2
    psd = _log10(psd)
    centroid = None
    amps = np.zeros(spec.harmonics)
    if target.peak is not None:
        # the prediction's own fundamental: its harmonics are read around it, so that a
        # prediction whose marks lie far from the measured ones (a feed far off) still has
        # a frequency and amplitudes that move with the parameters (a gradient over the
        # whole bounds, not only within the annulus around the measured fundamental)
        k0 = own_peak(h, target) or target.peak
        centroid, amps = harmonic_features(h, pixel=target.pixel, k0=k0, n=spec.harmonics)
        if target.amplitude_gain is not None and not measured:
            amps = amps * target.amplitude_gain
    wavy = waviness(z, pixel=target.pixel, cutoff=target.cutoff, form=spec.form,
                    origin=target.origin)
    return Prediction(h, wavy, psd, centroid, amps)


def own_peak(h: np.ndarray, target: Target) -> float | None:
    """The feed marks' fundamental |k| (cycles/mm) of a map with its form removed, looked
    for as the measured one is (:func:`make_target`); None where none stands out."""
    ny, nx = h.shape
    length = min(ny * target.pixel[1], nx * target.pixel[0])
    high = h - gaussian_filter(h, pixel=target.pixel, cutoff=length / 10.0, min_weight=0.3)
    return feed_peak(high, pixel=target.pixel, k_min=PEAK_MIN_PERIODS / length)


def _mean_psd(maps, target: Target):
    """The PSD per bin (mm^4) of maps, averaged over them."""
    spec = target.spec
    kw: dict[str, Any] = dict(pixel=target.pixel, k_range=target.k_range, radial_bins=spec.psd_radial_bins,
              angle_bins=spec.psd_angle_bins)
    return np.mean([psd_bins(prepare_map(z, pixel=target.pixel, form=spec.form,
                                         origin=target.origin), **kw) for z in maps], axis=0)


def _own_harmonics(z, target: Target):
    """(centroid, amplitudes) of a map's feed harmonics read around its own fundamental
    (the measured one where none stands out): maps made at other values than the truth
    (the realisations at the start) keep their harmonics."""
    h = prepare_map(z, pixel=target.pixel, form=target.spec.form, origin=target.origin)
    k0 = cast(float, own_peak(h, target) or target.peak)  # (called where target.peak is set)
    return harmonic_features(h, pixel=target.pixel, k0=k0, n=target.spec.harmonics)


def _mean_power(maps, target: Target):
    """The feed harmonics' power (mm^2), averaged over maps."""
    return np.mean([_own_harmonics(z, target)[1] ** 2 for z in maps], axis=0)


def noise_floor(target: Target, noisy: np.ndarray | Sequence[np.ndarray],
                clean: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(floor, clean PSD): the power per PSD bin (mm^4) that the random parts add: the PSD
    of predictions with them (``noisy``: one map or several realisations, averaged) less
    that of the same prediction without them (``clean``), and the clean prediction's own
    PSD per bin.  The evaluations predict without the random parts (their expected value)
    and add this floor to their spectra: the random parts are independent of the surface,
    so powers add."""
    noisy = [cast(np.ndarray, noisy)] if np.ndim(noisy) == 2 else list(noisy)
    a = _mean_psd(noisy, target)
    b = _mean_psd([clean], target)
    return np.where(np.isfinite(a - b), np.maximum(a - b, 0.0), 0.0), b


def set_noise_floor(target: Target, noisy: np.ndarray | Sequence[np.ndarray], clean: np.ndarray, *,
                    above: float = 3.0,
                    scaled: Iterable[tuple[int, float, np.ndarray | Sequence[np.ndarray]]] = ()) -> None:
    """Give ``target`` the random parts' floor (:func:`noise_floor`) and leave out of the
    ``psd`` term the bins where the clean prediction is below ``above`` times the floor:
    there the spectrum is the camera's noise and the random parts' (whose realisation is
    not the measured one, and whose print-through of the fringes depends on the surface).

    ``scaled``: (index, start, maps) of random parts whose amplitude is fitted: their
    floor (from ``maps``, realisations with that part alone at ``start``) enters each
    prediction's spectrum scaled by (value / start)^2 (the power of a linear random
    part grows with its amplitude squared)."""
    floor, clean_psd = noise_floor(target, noisy, clean)
    target.psd_floor = floor
    keep = np.isfinite(clean_psd) & (clean_psd > above * floor)
    target.psd_use = target.psd_use & keep
    target.psd_scaled = [(int(i), float(v0), noise_floor(target, maps, clean)[0])
                         for i, v0, maps in scaled]
    # the noise also lowers the measured harmonics (fringe-locked errors of the phase
    # steps): the clean predictions' amplitudes are scaled by the same ratio
    noisy = [cast(np.ndarray, noisy)] if np.ndim(noisy) == 2 else list(noisy)
    if target.peak is not None:
        p_noisy = _mean_power(noisy, target)
        p_clean = _mean_power([clean], target)
        with np.errstate(divide="ignore", invalid="ignore"):
            gain = np.where(p_clean > 0, np.sqrt(p_noisy / p_clean), 1.0)
        target.amplitude_gain = np.clip(np.nan_to_num(gain, nan=1.0), 0.5, 2.0)
    if len(noisy) > 1:
        _set_scatter(target, noisy, clean)


def _set_scatter(target: Target, noisy, clean) -> None:
    """Widen the scales of the ``map`` and ``harmonics`` terms to what the realisations
    ``noisy`` of the random parts (and the camera's noise) differ by from the clean
    prediction: the measured map holds a realisation the clean prediction cannot
    reproduce, so a residual of that size is expected at the true values."""
    spec = target.spec
    r, c = target.points
    w0 = waviness(clean, pixel=target.pixel, cutoff=target.cutoff, form=spec.form,
                  origin=target.origin)[r, c]
    diffs = np.concatenate([waviness(z, pixel=target.pixel, cutoff=target.cutoff,
                                     form=spec.form, origin=target.origin)[r, c] - w0
                            for z in noisy])
    diffs = diffs[np.isfinite(diffs)]
    scatter: dict[str, Any] = {"draws": len(noisy)}
    if diffs.size:
        s_map = float(np.sqrt(np.mean(diffs ** 2)))
        scatter["waviness_rms_nm"] = s_map * MM_TO_NM
        target.sigma_map = max(target.sigma_map, s_map)
    if target.peak is not None:
        feats = [_own_harmonics(z, target) for z in noisy]
        k = np.array([f[0] for f in feats], dtype=np.float64)
        a = np.array([f[1] for f in feats], dtype=np.float64)
        if np.all(np.isfinite(k)) and target.centroid:
            s_f = float(np.std(k, ddof=1) / np.mean(k))
            scatter["frequency_relative"] = s_f
            target.sigma_frequency = max(spec.sigma_frequency, s_f)
        s_a = np.std(a, axis=0, ddof=1)
        scatter["amplitudes_nm"] = [float(v) * MM_TO_NM for v in s_a]
        floor = spec.sigma_amplitude * max(float(target.amplitudes[0]), 1e-12)
        target.sigma_amplitudes = np.maximum(np.nan_to_num(s_a), floor)
    target.scatter = scatter
    target.draws = [predict_features(z, target, measured=True) for z in noisy]


def soft_l1(d: np.ndarray) -> np.ndarray:
    """The soft-L1 (pseudo-Huber) loss of normalised residuals: 2 (sqrt(1 + d^2) - 1)
    (d^2 near 0, 2 |d| far out)."""
    d = np.asarray(d, dtype=np.float64)
    return 2.0 * (np.sqrt(1.0 + d * d) - 1.0)


def robust_weights(d: np.ndarray) -> np.ndarray:
    """Square roots of the iteratively re-weighted least-squares weights of the soft-L1
    loss at ``d``: (1 + d^2)^(-1/4) (a least-squares fit of ``sqrt(w) d`` with these held
    has the soft-L1 fit as its fixed point)."""
    d = np.asarray(d, dtype=np.float64)
    return (1.0 + d * d) ** -0.25


def residual_vector(pred: Prediction, target: Target) -> tuple[np.ndarray, np.ndarray, dict]:
    """The normalised residuals ``d`` (fixed length for a target), each entry's term weight
    ``a`` (``sqrt(weight / n)`` of its term) and each term's share of the misfit
    ``sum a^2 soft_l1(d)``."""
    spec = target.spec
    ds, As, terms = [], [], {}
    w = spec.weights

    def add(name, d):
        d = np.where(np.isfinite(d), d, 0.0)
        a = np.full(d.size, math.sqrt(w[name] / max(d.size, 1)))
        ds.append(d)
        As.append(a)
        terms[name] = float(np.sum(a * a * soft_l1(d)))

    if w.get("map", 0) > 0:
        r, c = target.points
        add("map", (pred.wavy[r, c] - target.wavy[r, c]) / target.sigma_map)
    if w.get("psd", 0) > 0:
        use = target.psd_use
        add("psd", (pred.psd[use] - target.psd[use]) / target.psd_sigma[use])
    if w.get("harmonics", 0) > 0 and target.peak is not None:
        add("harmonics", harmonic_residuals(target, pred, spec))
    if not ds:
        return np.zeros(1), np.zeros(1), terms
    return np.concatenate(ds), np.concatenate(As), terms
