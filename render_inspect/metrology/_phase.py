"""Heights from interferometer frames: phase shifting (PSI) and coherence scanning (CSI).

The forward model these functions invert (docs/instrument.md, docs/report.md)::

    OPD_k = 2 (h - z_ref,k)                                   (mm, normal incidence)
    I_k   = a + b g(OPD_k) cos(2 pi OPD_k / lambda + delta_k)

PSI: z_ref is fixed, the phase shifts ``delta_k`` are known (``steps_rad``), g = 1.  The
wrapped phase ``phi = 4 pi (h - z_ref) / lambda`` comes from the 4-step or the 5-step
(Hariharan et al. 1987 [1]_) formula or, for any other set of steps, from a per-pixel
least-squares fit; it is unwrapped in 2-D inside the valid mask (quality-guided flood
fill, :mod:`._unwrap`) and converted to height ``h = phi lambda / (4 pi)``.  An
interferometer measures relative height only: the unwrapped height is defined up to a
constant (one per connected valid region); an evaluation against a known truth
(:func:`evaluate_measurement`, :func:`height_error`) removes it by aligning the mean over
the valid pixels with the truth.

CSI: ``delta_k = 0`` and the reference scans, ``z_ref,k = scan_positions[k]``; the
envelope g peaks where ``z_ref = h``.  The envelope is the modulus of the analytic signal
(Hilbert transform along the scan) of the frames with their mean removed; its peak is
located to a fraction of a scan step by a weighted least-squares Gaussian
(log-parabola) fit over the samples above half maximum.  Optionally the phase of the
fringes at the peak refines it.

Every length is in mm; wavelengths are in nm where the name says so
(``wavelength_nm``); phases in rad.

References
----------
.. [1] P. Hariharan, B. F. Oreb, T. Eiju, "Digital phase-shifting interferometry: a simple
       error-compensating phase calculation algorithm," Applied Optics 26(13), 2504-2506
       (1987). :DOI:`10.1364/AO.26.002504`
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.errors import InputError, check_range
from ..core.progress import report
from ..core.units import MM_TO_NM, NM_TO_MM
# unwrapping (importable from here as before)
from ._noise import (FALSE_ALARM, csi_height_noise, csi_noise_threshold, noise_sigmas,
                     psi_height_noise, psi_noise)
from ._unwrap import _check_valid, _wrap, phase_quality, unwrap_phase

__all__ = ["wrapped_phase", "unwrap_phase", "phase_quality", "height_from_phase",
           "retrieve_psi", "retrieve_csi", "height_error", "PhaseResult",
           "evaluate_measurement"]

_ALGORITHMS = ("auto", "4step", "5step", "lsq")


@dataclass
class PhaseResult:
    """What phase retrieval returns.

    Attributes
    ----------
    height : (H, W) float64, mm
        Measured height (NaN outside ``valid``), relative: defined up to a constant per
        connected valid region (``labels``).
    valid : (H, W) bool
        Pixels with a measurement (light returned and enough fringe modulation).
    wrapped : (H, W) float64, rad
        Wrapped phase in (-pi, pi] (PSI) or the fringe phase at the envelope peak (CSI).
    modulation : (H, W) float64
        Fringe contrast b / a (PSI) or the envelope peak over the mean (CSI).
    labels : (H, W) int32
        Connected valid regions (0 = invalid, 1, 2, ...), each unwrapped on its own.
    meta : dict
        Algorithm, wavelength and settings (provenance).
    height_noise : (H, W) float64, mm, or None
        Each pixel's height noise (one standard deviation) estimated from the frames'
        own noise (:func:`~._noise.psi_height_noise`, :func:`~._noise.csi_height_noise`);
        None where the frames cannot tell it (three PSI frames).
    """

    height: np.ndarray
    valid: np.ndarray
    wrapped: np.ndarray
    modulation: np.ndarray
    labels: np.ndarray
    meta: dict = field(default_factory=dict)
    height_noise: np.ndarray | None = None


# --------------------------------------------------------------------------------------
# input checks
def _check_frames(frames, *, min_frames=3) -> np.ndarray:
    f = np.asarray(frames)
    # float32 stacks stay float32 (a 1024^2 x 256 CSI stack is 1 GiB; float64 would double it)
    f = f if f.dtype == np.float32 else f.astype(np.float64)
    if f.ndim != 3:
        raise InputError(f"frames must be an (N, H, W) array of N interferogram frames, "
                         f"got shape {f.shape}")
    if f.shape[0] < min_frames:
        raise InputError(f"frames must hold at least {min_frames} frames (N >= {min_frames}), "
                         f"got N = {f.shape[0]}")
    return f


# --------------------------------------------------------------------------------------
# PSI: wrapped phase
def wrapped_phase(frames: np.ndarray, *, steps_rad: np.ndarray | None = None,
                  algorithm: str = "auto") -> tuple[np.ndarray, np.ndarray]:
    """Wrapped phase of the zero-shift frame from phase-shifted frames.

    Parameters
    ----------
    frames : (N, H, W) array
        Intensities ``I_k = a + b cos(phi + delta_k)``.
    steps_rad : (N,) array, optional
        The phase shifts ``delta_k`` (rad) the instrument applied (nominal values: the
        algorithm assumes them).  Default ``k pi / 2``.  The 4- and 5-step formulas need
        equal steps of +pi/2 or -pi/2 (either sign; any offset).
    algorithm : {"auto", "4step", "5step", "lsq"}
        "4step": ``phi = atan2(I4 - I2, I1 - I3)`` (for +pi/2 steps from 0).
        "5step": Hariharan, ``phi = atan2(2 (I2 - I4), 2 I3 - I5 - I1)`` (for steps
        -pi .. pi), insensitive to a linear step error to first order.
        "lsq": least-squares fit of a, b cos phi, b sin phi for any known steps.
        "auto": 4step for N = 4, 5step for N = 5, else lsq.

    Returns
    -------
    phase : (H, W) float64, rad in (-pi, pi]
        ``phi`` such that ``I_k = a + b cos(phi + delta_k)``.
    modulation : (H, W) float64
        Fringe contrast ``b / a`` (0 where ``a <= 0``).
    """
    phase, b, a, _ = _phase_terms(frames, steps_rad=steps_rad, algorithm=algorithm)
    with np.errstate(divide="ignore", invalid="ignore"):
        mod = np.where(a > 0, b / np.where(a > 0, a, 1.0), 0.0)
    return phase, mod


def _phase_terms(frames, *, steps_rad=None, algorithm: str = "auto"):
    """(phase, b, a, (w_c, w_d)): the wrapped phase, the modulation amplitude, the
    background and the weights of the frames in the two components of ``b`` (for its
    noise, :func:`~._noise.psi_noise`)."""
    f = _check_frames(frames)
    n = f.shape[0]
    if algorithm not in _ALGORITHMS:
        raise InputError(f"algorithm must be one of {_ALGORITHMS}, got {algorithm!r}")
    steps = (np.arange(n) * np.pi / 2) if steps_rad is None else np.asarray(steps_rad, dtype=np.float64)
    if steps.shape != (n,):
        raise InputError(f"steps_rad must have one phase shift per frame ({n}), got shape {steps.shape}")
    if not np.all(np.isfinite(steps)):
        raise InputError(f"steps_rad must be finite, got {steps.tolist()}")
    if algorithm == "auto":
        algorithm = {4: "4step", 5: "5step"}.get(n, "lsq")
    a = f.mean(axis=0)
    if algorithm in ("4step", "5step"):
        need = 4 if algorithm == "4step" else 5
        if n != need:
            raise InputError(f"algorithm {algorithm!r} needs N = {need} frames, got N = {n}")
        d = np.diff(steps)
        s = 1.0 if d[0] > 0 else -1.0
        if not np.allclose(d, s * np.pi / 2, atol=1e-6):
            raise InputError(f"algorithm {algorithm!r} needs equal steps of +pi/2 or -pi/2, got "
                             f"steps_rad = {np.round(steps, 6).tolist()}; use algorithm='lsq'")
        if algorithm == "4step":
            i1, i2, i3, i4 = f
            num, den = s * (i4 - i2), i1 - i3
            b = 0.5 * np.hypot(num, den)
            psi = np.arctan2(num, den)
            delta_ref = steps[0]
            weights = (0.5 * np.array([1.0, 0, -1, 0]), 0.5 * s * np.array([0.0, -1, 0, 1]))
        else:
            i1, i2, i3, i4, i5 = f
            num, den = s * 2 * (i2 - i4), 2 * i3 - i5 - i1
            b = 0.25 * np.hypot(num, den)
            # the background of the 5-step set (frames 1 and 5 are the same phase): the
            # plain mean would be biased by b cos(phi) / 5
            a = (i1 + 2 * (i2 + i3 + i4) + i5) / 8
            psi = np.arctan2(num, den)
            delta_ref = steps[2]
            weights = (0.25 * np.array([-1.0, 0, 2, 0, -1]), 0.5 * s * np.array([0.0, 1, 0, -1, 0]))
        phase = _wrap(psi - delta_ref)
    else:
        m = np.stack([np.ones(n), np.cos(steps), -np.sin(steps)], axis=1)
        if np.linalg.matrix_rank(m) < 3:
            raise InputError(f"steps_rad do not determine the phase (need 3 distinct shifts mod "
                             f"2 pi), got {np.round(steps, 6).tolist()}")
        pinv = np.linalg.pinv(m)
        coef = pinv @ f.reshape(n, -1)
        a = coef[0].reshape(f.shape[1:])
        c, d = coef[1].reshape(f.shape[1:]), coef[2].reshape(f.shape[1:])
        b = np.hypot(c, d)
        phase = np.arctan2(d, c)
        weights = (pinv[1], pinv[2])
    return phase, b, a, weights


def height_from_phase(unwrapped: np.ndarray, *, wavelength_nm: float) -> np.ndarray:
    """Height (mm) from the unwrapped phase: ``h = phi lambda / (4 pi)`` (double pass,
    OPD = 2 h at normal incidence)."""
    check_range("wavelength_nm", wavelength_nm, 100, 2000)
    lam_mm = float(wavelength_nm) * NM_TO_MM
    return np.asarray(unwrapped, dtype=np.float64) * lam_mm / (4 * np.pi)


# --------------------------------------------------------------------------------------
# the two measurement modes
def retrieve_psi(frames: np.ndarray, *, wavelength_nm: float, steps_rad: np.ndarray | None = None,
                 algorithm: str = "auto",
                 valid: np.ndarray | None = None, min_modulation: float = 0.05,
                 quality: str = "modulation",
                 false_alarm: float | None = FALSE_ALARM) -> PhaseResult:
    """Height from phase-shifting frames: wrapped phase, 2-D unwrapping, height.

    Parameters
    ----------
    frames : (N, H, W) array
        Intensities, frame k taken with phase shift ``steps_rad[k]``.
    wavelength_nm : float
        Source wavelength, nm (100..2000).
    steps_rad : (N,) array, optional
        Nominal phase shifts, rad; default ``k pi / 2``.
    algorithm : {"auto", "4step", "5step", "lsq"}
        See :func:`wrapped_phase`.
    valid : (H, W) bool, optional
        Pixels to measure at most (a mask of the caller's; default all).
    min_modulation : float
        Pixels whose fringe contrast ``b / a`` is below this are invalid (0..1).
    false_alarm : float or None
        Pixels whose modulation amplitude does not rise above the frames' own noise
        (:func:`~._noise.psi_noise`: the chance that noise alone passes is
        ``false_alarm`` per pixel) are invalid; None leaves this test out.
    quality : {"modulation", "reliability"}
        Unwrapping order: by fringe contrast (it drops where a pixel spans a large part of
        a fringe, i.e. where the phase is unreliable; fewer slips on undersampled turning
        marks) or by the second-difference reliability of :func:`phase_quality`.

    Returns
    -------
    PhaseResult
        ``height`` in mm relative to the zero-phase reference, up to a constant per
        connected region; ``height`` is NaN where ``valid`` is False.
    """
    check_range("min_modulation", min_modulation, 0.0, 1.0)
    f = _check_frames(frames)
    v = _check_valid(valid, f.shape[1:])
    if quality not in ("modulation", "reliability"):
        raise InputError(f"quality must be 'modulation' or 'reliability', got {quality!r}")
    phase, b, a, weights = _phase_terms(f, steps_rad=steps_rad, algorithm=algorithm)
    with np.errstate(divide="ignore", invalid="ignore"):
        mod = np.where(a > 0, b / np.where(a > 0, a, 1.0), 0.0)
    n = f.shape[0]
    steps = (np.arange(n) * np.pi / 2) if steps_rad is None else np.asarray(steps_rad, float)
    signal = np.ones(mod.shape, dtype=bool)
    noise: dict[str, Any] = {"method": "not tested", "frame_noise": None, "threshold_sigmas": None}
    sigma_b = None
    if false_alarm is not None:
        check_range("false_alarm", false_alarm, 0.0, 0.5, lo_open=True)
    sigma_b, noise_est = psi_noise(f, steps, a, weights)
    if false_alarm is not None:
        noise = noise_est
        kappa = noise_sigmas(false_alarm)
        noise["threshold_sigmas"] = kappa
        noise["false_alarm"] = float(false_alarm)
        if sigma_b is not None:
            signal = b >= kappa * sigma_b
    v &= np.isfinite(phase) & signal & (mod >= min_modulation)
    un, labels = unwrap_phase(phase, valid=v, quality=mod if quality == "modulation" else None)
    h = height_from_phase(un, wavelength_nm=wavelength_nm)
    alg = algorithm if algorithm != "auto" else {4: "4step", 5: "5step"}.get(n, "lsq")
    hn = psi_height_noise(sigma_b, b, wavelength_nm=wavelength_nm, valid=v)
    meta: dict[str, Any] = {"mode": "psi", "algorithm": alg, "frames": int(n), "wavelength_nm": float(wavelength_nm),
            "min_modulation": float(min_modulation),
            "unwrap": f"quality-guided flood fill ({quality})",
            "regions": int(labels.max()), "noise": noise,
            "signal_fraction": float(np.mean(signal & np.isfinite(phase)))}
    meta["noise"]["height_noise_rms_nm"] = _rms_nm(hn, v)
    return PhaseResult(h, v, phase, mod, labels, meta, height_noise=hn)


def retrieve_csi(frames: np.ndarray, scan_positions: np.ndarray, *, wavelength_nm: float,
                 valid: np.ndarray | None = None,
                 refine: str = "envelope", min_modulation: float = 0.05,
                 chunk_pixels: int = 65536,
                 false_alarm: float | None = FALSE_ALARM) -> PhaseResult:
    """Height from a coherence-scanning (white-light) stack: envelope peak per pixel.

    Parameters
    ----------
    frames : (N, H, W) array
        Intensity at each scan position.
    scan_positions : (N,) array, mm
        Reference position ``z_ref`` of each frame (OPD = 2 (h - z_ref)); equally spaced,
        increasing or decreasing.
    wavelength_nm : float
        Mean (centre) wavelength, nm; used for the phase refinement.
    valid : (H, W) bool, optional
        Pixels to measure at most (a mask of the caller's; default all).
    refine : {"envelope", "phase"}
        "envelope": the envelope peak (weighted least-squares Gaussian fit over the
        samples above half maximum).  "phase": the
        fringe phase at the peak picks the nearest height consistent with it (resolution
        of PSI; a "ghost step" of lambda/2 appears where the envelope is off by more than
        lambda/4).
    min_modulation : float
        Pixels whose envelope peak over the mean intensity is below this are invalid.
    false_alarm : float or None
        Pixels whose envelope peak does not rise above their own noise
        (:func:`~._noise.csi_noise_threshold`: the chance that noise alone passes is
        ``false_alarm`` per pixel) are invalid; None leaves this test out.
    chunk_pixels : int
        Pixels processed at a time (memory bound: N x chunk complex numbers).

    Returns
    -------
    PhaseResult
        ``height`` in mm, absolute in the scan's frame (no unwrapping needed).
    """
    from scipy.signal import hilbert

    f = _check_frames(frames, min_frames=5)
    n, hgt, wid = f.shape
    z = np.asarray(scan_positions, dtype=np.float64)
    if z.shape != (n,):
        raise InputError(f"scan_positions must have one position per frame ({n}), got shape {z.shape}")
    dz = np.diff(z)
    step = float(np.mean(dz))
    if not (np.all(np.isfinite(z)) and step != 0 and np.allclose(dz, step, rtol=1e-3, atol=0)):
        raise InputError("scan_positions must be equally spaced and strictly monotone (mm), got "
                         f"steps from {dz.min():.3g} to {dz.max():.3g} mm")
    if refine not in ("envelope", "phase"):
        raise InputError(f"refine must be 'envelope' or 'phase', got {refine!r}")
    check_range("wavelength_nm", wavelength_nm, 100, 2000)
    check_range("min_modulation", min_modulation, 0.0, None)
    if false_alarm is not None:
        check_range("false_alarm", false_alarm, 0.0, 0.5, lo_open=True)
    v = _check_valid(valid, (hgt, wid))
    lam = float(wavelength_nm) * NM_TO_MM
    flat = f.reshape(n, -1)
    npx = flat.shape[1]
    height = np.full(npx, np.nan)
    wrapped = np.full(npx, np.nan)
    mod = np.zeros(npx)
    ok = np.zeros(npx, dtype=bool)
    signal = np.ones(npx, dtype=bool)
    sigma = np.zeros(npx)
    hnoise = np.full(npx, np.nan)
    carrier = np.exp(-np.sign(step) * 1j * 4 * np.pi * z / lam)[:, None]
    k = np.arange(n)[:, None]
    for s0 in range(0, npx, max(int(chunk_pixels), 1)):
        report(s0, npx)  # (the progress, and a stop asked by a signal, between chunks)
        blk = flat[:, s0:s0 + chunk_pixels]
        mean = blk.mean(axis=0)
        ac = blk - mean
        ana = hilbert(ac, axis=0)
        env = np.abs(ana)
        kmax = np.argmax(env, axis=0)
        cols = np.arange(blk.shape[1])
        peak = env[kmax, cols]
        # Gaussian envelope: fit a parabola to log(envelope) over the samples within about
        # the half-width at half maximum of the peak (weighted by envelope^2: noise-robust;
        # exact for a Gaussian envelope)
        half = np.median(np.sum(env >= 0.5 * peak[None, :], axis=0))
        w = int(np.clip(np.round(half / 2), 1, max(1, (n - 1) // 2)))
        km = np.clip(kmax, w, n - 1 - w)
        j = np.arange(-w, w + 1)[:, None]
        ej = env[km[None, :] + j, cols[None, :]]
        yj = np.log(np.maximum(ej, 1e-300))
        wt = ej * ej
        m0, m1, m2, m3, m4 = (np.sum(wt * j ** q, axis=0) for q in range(5))
        t0, t1, t2 = (np.sum(wt * yj * j ** q, axis=0) for q in range(3))
        mat = np.stack([np.stack([m0, m1, m2], -1), np.stack([m1, m2, m3], -1),
                        np.stack([m2, m3, m4], -1)], -2)
        rhs = np.stack([t0, t1, t2], -1)
        good = np.abs(np.linalg.det(mat)) > 1e-300
        coef = np.zeros_like(rhs)
        coef[good] = np.linalg.solve(mat[good], rhs[good][..., None])[..., 0]
        c1, c2 = coef[:, 1], coef[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            off = np.where(c2 < 0, -c1 / (2 * c2), 0.0)
        off = np.clip(np.nan_to_num(off), -w, w)
        interior = (kmax >= 1) & (kmax <= n - 2) & good
        zpk = z[0] + (km + off) * step
        with np.errstate(divide="ignore", invalid="ignore"):
            m = np.where(mean > 0, peak / np.where(mean > 0, mean, 1.0), 0.0)
        # fringe phase at the peak: the analytic signal is b g e^{-i sgn 4 pi (h - z)/lambda}
        # (sgn = sign of the scan step); demodulate it with the carrier over +-2 fringes
        win = np.abs(k - (km + off)[None, :]) * abs(step) <= lam
        cpx = np.sum(np.where(win, ana * carrier, 0.0), axis=0)
        ph = -np.angle(cpx) if step > 0 else np.angle(cpx)  # = 4 pi h / lambda (mod 2 pi)
        if refine == "phase":
            d = _wrap(ph - 4 * np.pi * zpk / lam)
            hz = zpk + d * lam / (4 * np.pi)
        else:
            hz = zpk
        sl = slice(s0, s0 + blk.shape[1])
        height[sl] = hz
        wrapped[sl] = ph
        mod[sl] = m
        thr, sig = csi_noise_threshold(ac, false_alarm=false_alarm or FALSE_ALARM)
        hnoise[sl] = csi_height_noise(sig, peak, width_samples=half / 2.3548,
                                      step_mm=abs(step), wavelength_nm=wavelength_nm,
                                      refine=refine, phase_sum=np.abs(cpx),
                                      window_samples=np.sum(win, axis=0))
        if false_alarm is not None:
            sigma[sl] = sig
            signal[sl] = peak >= thr
        ok[sl] = interior & signal[sl] & (m >= min_modulation)
    ok = ok.reshape(hgt, wid) & v
    height = np.where(ok, height.reshape(hgt, wid), np.nan)
    labels = _label(ok)
    meta: dict[str, Any] = {"mode": "csi", "algorithm": f"hilbert envelope peak ({refine})", "frames": int(n),
            "scan_step_mm": abs(step), "wavelength_nm": float(wavelength_nm),
            "min_modulation": float(min_modulation), "regions": int(labels.max()),
            "noise": {"method": "robust spread of each pixel's signal along the scan"
                      if false_alarm is not None else "not tested",
                      "frame_noise": float(np.median(sigma)) if false_alarm is not None
                      else None,
                      "threshold_sigmas": noise_sigmas(false_alarm, n)
                      if false_alarm is not None else None,
                      "false_alarm": false_alarm},
            "signal_fraction": float(np.mean(signal))}
    hn = np.where(ok, hnoise.reshape(hgt, wid), np.nan)
    meta["noise"]["height_noise_rms_nm"] = _rms_nm(hn, ok)
    return PhaseResult(height, ok, wrapped.reshape(hgt, wid), mod.reshape(hgt, wid), labels, meta,
                       height_noise=hn)


def _rms_nm(noise, valid) -> float | None:
    """rms (nm) of a per-pixel noise map (mm) over the valid pixels; None when unknown."""
    if noise is None:
        return None
    n = np.asarray(noise)[np.asarray(valid, bool) & np.isfinite(noise)]
    return float(np.sqrt(np.mean(n * n)) * MM_TO_NM) if n.size else None


def _label(mask) -> np.ndarray:
    from scipy import ndimage

    lab, _ = ndimage.label(mask)
    return lab.astype(np.int32)


# --------------------------------------------------------------------------------------
# error against the truth
def height_error(measured: np.ndarray, truth: np.ndarray, *, valid: np.ndarray | None = None,
                 labels: np.ndarray | None = None, piston: str = "mean") -> tuple[np.ndarray, dict]:
    """Error of a measured height map against the true one, over the valid pixels.

    An interferometer measures relative height: before comparing, the measured map is
    shifted so that its mean over the valid pixels equals the truth's (``piston="mean"``;
    one shift per connected region when ``labels`` is given, because separate regions
    have unrelated offsets), or not at all (``piston="none"``).

    Parameters
    ----------
    measured, truth : (H, W) arrays, mm
    valid : (H, W) bool, optional
        Pixels to compare (default: where both are finite).
    labels : (H, W) int, optional
        Connected regions (:attr:`PhaseResult.labels`).
    piston : {"mean", "none"}

    Returns
    -------
    aligned : (H, W) float64, mm
        The measured map after piston alignment (NaN outside ``valid``).
    metrics : dict
        ``rms_nm``, ``pv_nm``, ``mean_nm`` (after alignment), ``piston_nm`` (the shift
        applied, of the largest region), ``valid_fraction``, ``valid_pixels``, ``piston``.
    """
    m = np.asarray(measured, dtype=np.float64)
    t = np.asarray(truth, dtype=np.float64)
    if m.shape != t.shape or m.ndim != 2:
        raise InputError(f"measured and truth must be 2-D arrays of one shape, got {m.shape} and {t.shape}")
    if piston not in ("mean", "none"):
        raise InputError(f"piston must be 'mean' or 'none', got {piston!r}")
    v = (np.ones(m.shape, bool) if valid is None else _check_valid(valid, m.shape))
    v &= np.isfinite(m) & np.isfinite(t)
    aligned = np.full(m.shape, np.nan)
    shift_main = 0.0
    if v.any():
        if piston == "none":
            aligned[v] = m[v]
        else:
            lab = _label(v) if labels is None else np.where(v, np.asarray(labels), 0)
            ids, counts = np.unique(lab[v], return_counts=True)
            for i in ids:
                sel = lab == i
                shift = float(np.mean(m[sel] - t[sel]))
                aligned[sel] = m[sel] - shift
            big = ids[np.argmax(counts)]
            shift_main = float(np.mean(m[lab == big] - t[lab == big]))
    e = (aligned - t)[v] * MM_TO_NM
    metrics = {"rms_nm": float(np.sqrt(np.mean(e * e))) if e.size else float("nan"),
               "pv_nm": float(e.max() - e.min()) if e.size else float("nan"),
               "mean_nm": float(e.mean()) if e.size else float("nan"),
               "piston_nm": shift_main * MM_TO_NM,
               "valid_fraction": float(v.mean()),
               "valid_pixels": int(v.sum()),
               "piston": piston}
    return aligned, metrics


# --------------------------------------------------------------------------------------
# measuring frames (no truth), then evaluating against a truth
def evaluate_measurement(result: PhaseResult, truth: np.ndarray, *,
                         piston: str = "mean") -> tuple[PhaseResult, dict]:
    """Compare a measurement with the true height (an evaluation step, apart from
    measuring): the measured map is aligned to the truth by one constant per connected
    region (:func:`height_error`), since an interferometer measures relative height.

    Returns
    -------
    aligned : PhaseResult
        A copy of ``result`` with ``height`` aligned (NaN where not measured).
    metrics : dict
        ``mode``, ``algorithm``, ``rms_nm``, ``pv_nm`` (of measured - true over the valid
        pixels), ``mean_nm``, ``piston_nm``, ``valid_fraction`` (measured pixels / all
        pixels), ``light_fraction`` (pixels where light returned), ``valid_pixels``,
        ``wavelength_nm``, ``regions``, ``piston``.
    """
    truth = np.asarray(truth, dtype=np.float64)
    aligned, err = height_error(result.height, truth, valid=result.valid, labels=result.labels,
                                piston=piston)
    valid = result.valid & np.isfinite(aligned)
    out = PhaseResult(np.where(valid, aligned, np.nan), valid, result.wrapped, result.modulation,
                      result.labels, dict(result.meta))
    out.meta["piston"] = f"{piston} over valid pixels of each region, aligned to the true height"
    metrics = {"mode": result.meta.get("mode"), "algorithm": result.meta.get("algorithm"),
               "wavelength_nm": result.meta.get("wavelength_nm"), **err,
               "light_fraction": result.meta.get("light_fraction"),
               "regions": int(result.meta.get("regions", 0))}
    return out, metrics
