"""Measure: height from interferometer frames and the instrument's settings alone.

No truth enters here.  Phase-shifting frames give the phase of each pixel modulo
``2 pi``, which is unwrapped inside connected regions (:func:`~._phase.unwrap_phase`):
a height step of more than a quarter of the effective wavelength cannot be told from
one shorter by a multiple of ``lambda_eff / 2`` (the 2-pi ambiguity), and regions that
do not touch keep unrelated offsets.  Coherence-scanning frames give absolute heights in
the scanner's frame (the envelope peak), optionally refined by the fringe phase.
Comparing with a truth (piston alignment, errors) is :func:`~._phase.height_error`'s
job, a separate step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.grid import GridCoordinates
from ..core.errors import InputError
from ._phase import retrieve_csi, retrieve_psi

__all__ = ["ALGORITHMS", "Measurement", "measure_frames"]

#: Algorithm names accepted by :func:`measure_frames` (by mode).
ALGORITHMS = {"psi": ("auto", "4step", "5step", "hariharan", "lsq"),
              "csi": ("auto", "envelope", "envelope+phase")}


@dataclass
class Measurement(GridCoordinates):
    """A measured height map.

    Attributes
    ----------
    height : (H, W) float64, mm
        NaN where not measured.  PSI: ``z_ref`` plus the unwrapped phase (relative:
        one unknown multiple of ``lambda_eff / 2`` per connected region).  CSI: absolute
        in the scanner's frame.
    valid : (H, W) bool
    modulation : (H, W) float64
        Fringe contrast (PSI) or envelope peak over mean (CSI).
    labels : (H, W) int32
        Connected measured regions (0 = not measured).
    pixel : float, mm;  origin : (x, y) of pixel [0, 0]'s centre, mm
    meta : dict
        Algorithm, effective wavelength, thresholds, counts of saturated and
        low-modulation pixels.
    """

    height: np.ndarray
    valid: np.ndarray
    modulation: np.ndarray
    labels: np.ndarray
    pixel: float
    origin: tuple
    meta: dict = field(default_factory=dict)

    @property
    def shape(self):
        return self.height.shape


def measure_frames(frames, *, algorithm: str = "auto", min_modulation: float = 0.05,
                   unwrap_quality: str = "modulation") -> Measurement:
    """Height from frames and their settings (no truth).

    Parameters
    ----------
    frames : Frames
        Anything with the attributes of :class:`render_inspect.instruments.Frames`:
        ``frames`` (N, H, W) 0..1, ``mode``, ``effective_wavelength_nm``,
        ``phase_steps_rad`` (PSI), ``scan_positions_mm``, ``z_ref``, ``pixel``,
        ``origin``.
    algorithm : str
        PSI: ``"4step"``, ``"5step"`` (= ``"hariharan"``, Schwider-Hariharan), ``"lsq"``
        (any steps) or ``"auto"`` (by the number of frames).  CSI: ``"envelope"`` (peak of
        the fringe envelope; ``"auto"``) or ``"envelope+phase"`` (refined by the fringe
        phase at the effective wavelength).
    min_modulation : float
        Pixels with a lower fringe contrast (PSI) or envelope peak over mean (CSI) are
        not measured.
    unwrap_quality : {"modulation", "reliability"}
        PSI unwrapping order (see :func:`~._phase.retrieve_psi`).

    Returns
    -------
    Measurement
        Pixels that reach full scale in any frame (saturated) are not measured.
    """
    mode = str(getattr(frames, "mode", ""))
    if mode not in ALGORITHMS:
        raise InputError(f"frames.mode must be 'psi' or 'csi', got {mode!r}")
    if algorithm not in ALGORITHMS[mode]:
        raise InputError(f"algorithm for {mode.upper()} frames must be one of "
                         f"{ALGORITHMS[mode]}, got {algorithm!r}")
    stack = np.asarray(frames.frames)
    if stack.ndim != 3:
        raise InputError(f"frames.frames must be an (N, H, W) stack, got shape {stack.shape}")
    lam_eff = float(frames.effective_wavelength_nm)
    saturated = np.max(stack, axis=0) >= 1.0
    valid = ~saturated & np.all(np.isfinite(stack), axis=0)
    if mode == "psi":
        alg = {"hariharan": "5step"}.get(algorithm, algorithm)
        res = retrieve_psi(stack, wavelength_nm=lam_eff, steps_rad=frames.phase_steps_rad,
                           algorithm=alg, valid=valid, min_modulation=min_modulation,
                           quality=unwrap_quality)
        height = res.height + float(frames.z_ref)
        name = res.meta["algorithm"]
        if name == "5step":
            name = "5step (Schwider-Hariharan)"
    else:
        refine = "phase" if algorithm == "envelope+phase" else "envelope"
        res = retrieve_csi(stack, frames.scan_positions_mm, wavelength_nm=lam_eff, valid=valid,
                           refine=refine, min_modulation=min_modulation)
        height = res.height
        name = "envelope+phase" if refine == "phase" else "envelope"
    meta = {"mode": mode, "algorithm": name, "effective_wavelength_nm": lam_eff,
            "min_modulation": float(min_modulation), "frames": int(stack.shape[0]),
            "saturated_pixels": int(saturated.sum()),
            "valid_fraction": float(res.valid.mean()), "regions": int(res.labels.max())}
    return Measurement(height=np.where(res.valid, height, np.nan), valid=res.valid,
                       modulation=res.modulation, labels=res.labels, pixel=float(frames.pixel),
                       origin=tuple(float(v) for v in frames.origin), meta=meta)
