"""Measure: height from interferometer frames and the instrument's settings alone.

No truth enters here.  Phase-shifting frames give the phase of each pixel modulo
``2 pi``, which is unwrapped inside connected regions (:func:`~._phase.unwrap_phase`):
a height step of more than a quarter of the effective wavelength cannot be told from
one shorter by a multiple of ``lambda_eff / 2`` (the 2-pi ambiguity), and regions that
do not touch keep unrelated offsets.  Coherence-scanning frames give absolute heights in
the scanner's frame (the envelope peak), optionally refined by the fringe phase.
Comparing with a truth (piston alignment, errors) is
:func:`~._phase.evaluate_measurement`'s job, a separate step.
"""

from __future__ import annotations

import numpy as np

from ..core.errors import InputError, check_range
from ..core.frames import Frames
from ._noise import FALSE_ALARM
from ._phase import PhaseResult, retrieve_csi, retrieve_psi

__all__ = ["ALGORITHMS", "measure_frames"]

#: Algorithm names accepted by :func:`measure_frames` (by mode).
ALGORITHMS = {"psi": ("auto", "4step", "5step", "hariharan", "lsq"),
              "csi": ("auto", "envelope", "envelope+phase")}


def measure_frames(frames: Frames, *, algorithm: str = "auto", csi_refine: str | None = None,
                   min_modulation: float = 0.05, unwrap_quality: str = "modulation",
                   false_alarm: float | None = FALSE_ALARM) -> PhaseResult:
    """What the instrument reports: height from its frames and settings alone.

    Parameters
    ----------
    frames : Frames
        :class:`~render_inspect.core.Frames` (an interferometer's recording): ``frames``
        (N, H, W) 0..1, ``valid``, ``mode``, ``wavelength_nm``,
        ``effective_wavelength_nm`` (the NA-corrected fringe wavelength; default
        ``wavelength_nm``), ``phase_steps`` (PSI, rad), ``scan_positions`` (CSI, mm),
        ``z_ref`` (mm).  Phase convention: ``I_k = a + b cos(4 pi (h - z_k) /
        lambda_eff)`` with ``z_k = z_ref - phase_steps[k] lambda_eff / (4 pi)`` (PSI) or
        ``scan_positions[k]`` (CSI).  Nothing else is read: no true height.
    algorithm : str
        PSI: ``"4step"``, ``"5step"`` (= ``"hariharan"``, Schwider-Hariharan), ``"lsq"``
        (any steps) or ``"auto"`` (by the number of frames).  CSI: ``"envelope"`` (peak of
        the fringe envelope; ``"auto"``) or ``"envelope+phase"`` (refined by the fringe
        phase at the effective wavelength).
    csi_refine : {"envelope", "phase"}, optional
        The older way to choose ``"envelope"`` / ``"envelope+phase"`` for CSI.
    min_modulation : float
        Pixels with a lower fringe contrast (PSI) or envelope peak over mean (CSI) are
        not measured.
    unwrap_quality : {"modulation", "reliability"}
        PSI unwrapping order (see :func:`~._phase.retrieve_psi`).
    false_alarm : float or None
        Pixels whose fringes do not rise above the noise the frames show
        (:mod:`~._noise`) are not measured; this is the chance that a pixel holding
        noise alone passes (default 1e-6); None leaves the test out.

    Validity is decided from the frames alone: saturated pixels, fringes below the
    frames' own noise, and fringe contrast below ``min_modulation``.  ``frames.valid``
    (a simulator's estimate of where light returns, or a file's mask) is not read.

    Returns
    -------
    PhaseResult
        ``height`` (mm, NaN where not measured).  PSI: ``z_ref`` plus the unwrapped phase,
        each connected region carrying its own unknown multiple of ``lambda_eff / 2``;
        CSI: absolute in the scanner's frame.  Pixels that reach full scale in any frame
        (saturated) are not measured.  ``meta``: ``mode``, ``algorithm``,
        ``wavelength_nm``, ``effective_wavelength_nm``, ``light_fraction`` (pixels
        whose fringes rise above the noise), ``noise`` (the frames' noise and the
        threshold), ``saturated_pixels``, ``regions``, ``min_modulation``.
    """
    mode = str(getattr(frames, "mode", ""))
    if mode not in ALGORITHMS:
        raise InputError(f"frames.mode must be 'psi' or 'csi', got {mode!r}")
    if mode == "csi" and csi_refine is not None:
        if csi_refine not in ("envelope", "phase"):
            raise InputError(f"csi_refine must be 'envelope' or 'phase', got {csi_refine!r}")
        if algorithm == "auto":
            algorithm = "envelope+phase" if csi_refine == "phase" else "envelope"
    if algorithm not in ALGORITHMS[mode]:
        raise InputError(f"algorithm for {mode.upper()} frames must be one of "
                         f"{ALGORITHMS[mode]}, got {algorithm!r}")
    check_range("min_modulation", min_modulation, 0.0, 1.0)
    stack = np.asarray(frames.frames)
    if stack.ndim != 3:
        raise InputError(f"frames.frames must be an (N, H, W) stack, got shape {stack.shape}")
    if false_alarm is not None:
        check_range("false_alarm", false_alarm, 0.0, 0.5, lo_open=True)
    lam_eff = float(getattr(frames, "effective_wavelength_nm", None) or frames.wavelength_nm)
    # validity from the frames alone: saturated or non-finite pixels, then (in the
    # retrieval) fringes that do not rise above the frames' own noise or the
    # modulation floor.  ``frames.valid`` is never read: the same frames give the same
    # map whatever else the file holds.
    saturated = np.max(stack, axis=0) >= 1.0
    valid = ~saturated & np.all(np.isfinite(stack), axis=0)
    if mode == "psi":
        alg = {"hariharan": "5step"}.get(algorithm, algorithm)
        try:
            res = retrieve_psi(stack, wavelength_nm=lam_eff, steps_rad=frames.phase_steps,
                               algorithm=alg, valid=valid, min_modulation=min_modulation,
                               quality=unwrap_quality, false_alarm=false_alarm)
        except InputError as err:  # named as the user asked for it
            if alg == algorithm:
                raise
            raise InputError(str(err).replace(repr(alg), f"{algorithm!r} ({alg!r})")) from None
        res.height = res.height + float(frames.z_ref)
        name = res.meta["algorithm"]
    else:
        refine = "phase" if algorithm == "envelope+phase" else "envelope"
        res = retrieve_csi(stack, frames.scan_positions, wavelength_nm=lam_eff, valid=valid,
                           refine=refine, min_modulation=min_modulation,
                           false_alarm=false_alarm)
        name = "envelope+phase" if refine == "phase" else "envelope"
    res.meta.update({"mode": mode, "algorithm": name,
                     "wavelength_nm": float(frames.wavelength_nm),
                     "effective_wavelength_nm": lam_eff,
                     "light_fraction": float(res.meta.get("signal_fraction", 1.0)),
                     "saturated_pixels": int(saturated.sum()),
                     "min_modulation": float(min_modulation),
                     "regions": int(res.labels.max())})
    return res
