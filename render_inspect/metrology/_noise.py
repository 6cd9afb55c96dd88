"""Which pixels hold fringes: the frames' own noise level, estimated from the frames, and
the signal a pixel needs above it to be measured (what instrument software does with a
"minimum modulation" and a noise threshold).

Nothing but the frames is read: the noise comes from the part of each pixel's signal
that the fringe model cannot explain.

* **Phase shifting** (N >= 4 frames).  Per pixel, the frames are fitted with
  ``a + c cos(delta_k) - d sin(delta_k)`` (three unknowns); the residual of the fit,
  ``|P I|^2 / (N - 3)`` with ``P`` the projection onto the fit's null space, is an
  unbiased estimate of the frame noise variance.  With only N - 3 degrees of freedom per
  pixel it is pooled: pixels are grouped by their mean intensity ``a`` (shot noise grows
  with it), each group's median residual, corrected by the median of the chi-square
  distribution, gives the noise there, and every pixel gets the noise of its intensity.
  The modulation amplitude ``b = |c + i d|`` of a pixel without fringes is Rayleigh
  distributed with scale ``sigma_b = sigma sqrt((|w_c|^2 + |w_d|^2) / 2)`` (``w`` the
  fit's weights); a pixel holds fringes when ``b >= kappa sigma_b`` with
  ``kappa = sqrt(2 ln(1 / p))`` for the false-alarm probability ``p`` per pixel.  Three
  frames leave no residual: the noise cannot be told from the fringes, and only the
  modulation floor applies.
* **Coherence scanning.**  Each pixel's noise is the robust spread (1.4826 times the
  median absolute value) of its mean-removed signal along the scan, where the fringes
  fill only the frames near the envelope peak; the envelope of noise alone is Rayleigh
  distributed per frame, so a pixel holds fringes when its envelope peak exceeds ``sigma
  sqrt(2 ln(N / p))`` (the largest of N frames).

The same noise gives each pixel's height noise (one standard deviation):

* **Phase shifting.**  Noise of scale ``sigma_b`` in each component of ``b e^{i phi}``
  moves the phase by ``sigma_b / b`` rad (for ``b >> sigma_b``), the height by
  ``lambda / (4 pi)`` times that (:func:`psi_height_noise`).
* **Coherence scanning.**  The envelope peak, located by a least-squares Gaussian of
  ``s`` samples' standard deviation and peak ``A`` in noise ``sigma`` per sample, moves by
  ``sqrt(2 s / sqrt(pi)) sigma / A`` samples (the Cramer-Rao bound of a Gaussian's
  centre); with the fringe phase refining it, by the phase noise of the demodulated sum
  of ``n`` samples, ``sigma sqrt(n) / |sum|`` rad (:func:`csi_height_noise`).

Model misfit (a miscalibrated phase shifter, vibration) adds to the residual and makes
the estimate conservative: it raises the threshold, it never lets noise pass.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.units import NM_TO_MM

__all__ = ["FALSE_ALARM", "psi_noise", "csi_noise_threshold", "noise_sigmas",
           "psi_height_noise", "csi_height_noise"]

#: Probability that a pixel holding noise alone passes as fringes (per pixel); assumed:
#: about one such pixel in a 1024 x 1024 field (1e-8 .. 1e-3 are plausible choices).
FALSE_ALARM = 1e-6  # not a unit conversion
#: Intensity groups of the pooled phase-shifting noise estimate, and the fewest pixels
#: a group holds.
_GROUPS = 24
_MIN_GROUP = 64


def noise_sigmas(false_alarm: float, samples: int = 1) -> float:
    """``kappa``: the threshold, in units of the Rayleigh scale, that noise alone exceeds
    with probability ``false_alarm`` in the largest of ``samples`` independent samples."""
    return math.sqrt(2 * math.log(max(int(samples), 1) / float(false_alarm)))


def _chi2_median_ratio(dof: int) -> float:
    """Median of chi-square(dof) / dof."""
    from scipy.stats import chi2

    return float(chi2.ppf(0.5, dof) / dof)


def psi_noise(frames: np.ndarray, steps_rad: np.ndarray, mean: np.ndarray | None = None,
              weights: tuple[np.ndarray, np.ndarray] | None = None
              ) -> tuple[np.ndarray | None, dict]:
    """Noise of phase-shifting frames, from the frames alone.

    Parameters
    ----------
    frames : (N, H, W) array
    steps_rad : (N,) array
        The phase shifts applied.
    mean : (H, W) array, optional
        The pixels' background ``a`` (default the frames' mean).
    weights : (w_c, w_d), optional
        The frames' weights in the two components of ``b`` of the algorithm used
        (default the least-squares fit's).

    Returns
    -------
    sigma_b : (H, W) float64 or None
        Rayleigh scale of the modulation amplitude ``b`` of a pixel holding noise alone
        (None with three frames: no residual to estimate it from).
    info : dict
        ``frame_noise`` (median noise of one frame, in the frames' units), ``dof``,
        ``method``.
    """
    f = np.asarray(frames)
    n = f.shape[0]
    steps = np.asarray(steps_rad, dtype=np.float64)
    m = np.stack([np.ones(n), np.cos(steps), -np.sin(steps)], axis=1)
    pinv = np.linalg.pinv(m)
    dof = n - int(np.linalg.matrix_rank(m))
    if dof < 1:
        return None, {"method": "none (three frames leave no residual)", "dof": 0,
                      "frame_noise": None}
    proj = np.eye(n) - m @ pinv
    flat = f.reshape(n, -1).astype(np.float64)
    res = proj @ flat
    var = np.sum(res * res, axis=0) / dof
    a = (flat.mean(axis=0) if mean is None else np.asarray(mean, dtype=np.float64).ravel())
    corr = _chi2_median_ratio(dof)
    ok = np.isfinite(var) & np.isfinite(a)
    groups = max(1, min(_GROUPS, int(ok.sum()) // _MIN_GROUP))
    if groups <= 1 or not ok.any():
        sig2 = np.full(var.shape, float(np.median(var[ok])) / corr if ok.any() else 0.0)
    else:
        order = np.argsort(a[ok], kind="stable")  # tied intensities grouped alike everywhere
        av, vv = a[ok][order], var[ok][order]
        parts = np.array_split(np.arange(av.size), groups)
        centres = np.array([float(np.median(av[p])) for p in parts])
        levels = np.array([float(np.median(vv[p])) / corr for p in parts])
        # noise grows with the intensity (shot noise): a running maximum keeps a group
        # of few bright pixels from an accidentally low estimate
        levels = np.maximum.accumulate(levels)
        sig2 = np.interp(a, centres, levels)
    wc, wd = (pinv[1], pinv[2]) if weights is None else (np.asarray(w, float) for w in weights)
    scale = math.sqrt(0.5 * (float(wc @ wc) + float(wd @ wd)))
    sigma_b = np.sqrt(np.maximum(sig2, 0.0)) * scale
    info = {"method": "residual of the fringe fit, pooled by intensity", "dof": int(dof),
            "frame_noise": float(np.sqrt(np.median(sig2)))}
    return sigma_b.reshape(f.shape[1:]), info


def csi_noise_threshold(ac: np.ndarray, *, false_alarm: float = FALSE_ALARM
                        ) -> tuple[np.ndarray, np.ndarray]:
    """Envelope peak a coherence-scanning pixel needs to hold fringes.

    Parameters
    ----------
    ac : (N, P) array
        The pixels' mean-removed signals along the scan.

    Returns
    -------
    threshold : (P,) float64
        ``sigma sqrt(2 ln(N / p))`` per pixel.
    sigma : (P,) float64
        The pixel's noise: ``1.4826 median |signal|`` (the fringes fill a few frames of
        the scan, the median reads the noise beside them).
    """
    n = ac.shape[0]
    sigma = 1.4826 * np.median(np.abs(ac), axis=0)
    return sigma * noise_sigmas(false_alarm, n), sigma


def psi_height_noise(sigma_b: np.ndarray | None, b: np.ndarray, *, wavelength_nm: float,
                     valid: np.ndarray | None = None) -> np.ndarray | None:
    """Height noise (mm, one standard deviation) of each phase-shifting pixel:
    ``lambda / (4 pi) * sigma_b / b`` (the phase noise ``sigma_b / b`` of a modulation
    ``b`` in component noise ``sigma_b``); NaN outside ``valid``; None without a noise
    estimate (three frames)."""
    if sigma_b is None:
        return None
    b = np.asarray(b, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        ph = np.where(b > 0, np.asarray(sigma_b, np.float64) / np.where(b > 0, b, 1.0), np.nan)
    h = ph * float(wavelength_nm) * NM_TO_MM / (4 * math.pi)
    if valid is not None:
        h = np.where(valid, h, np.nan)
    return h


def csi_height_noise(sigma: np.ndarray, peak: np.ndarray, *, width_samples: float | np.ndarray,
                     step_mm: float, wavelength_nm: float,
                     refine: str = "envelope", phase_sum: np.ndarray | None = None,
                     window_samples: np.ndarray | None = None) -> np.ndarray:
    """Height noise (mm, one standard deviation) of coherence-scanning pixels.

    ``sigma`` (P,): each pixel's noise per frame; ``peak`` (P,): its envelope peak;
    ``width_samples``: the envelope's Gaussian standard deviation in scan steps;
    ``refine`` "phase" uses the demodulated sum ``phase_sum`` (P,) of
    ``window_samples`` (P,) frames instead (the fringe phase sets the height)."""
    sigma = np.asarray(sigma, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        if refine == "phase" and phase_sum is not None:
            n = np.maximum(np.asarray(window_samples, np.float64), 1.0)
            dph = sigma * np.sqrt(n) / np.asarray(phase_sum, np.float64)
            return dph * float(wavelength_nm) * NM_TO_MM / (4 * math.pi)
        s = max(float(width_samples), 0.5)
        dk = np.sqrt(2.0 * s / math.sqrt(math.pi)) * sigma / np.asarray(peak, np.float64)
    return dk * float(step_mm)
