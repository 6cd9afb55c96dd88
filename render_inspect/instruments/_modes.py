"""The two measurement modes of the interference microscope: phase-shifting (PSI) frames,
taken at the focus the instrument finds itself (:func:`~._focus.autofocus`) or at a
position the user sets, and coherence-scanning (CSI) frames; each the imaging model's
intensities (:mod:`._imaging`) exposed on the camera, returned as
:class:`~render_inspect.core.Frames` with the instrument's settings and no truth."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from ..core import cancel
from ..core.errors import InputError, MemoryBudgetError, check_range
from ..core.frames import Frames
from ..core.units import NM_TO_MM
from . import _imaging
from ._camera import expose
from ._focus import autofocus
from ._microscope import Disturbances, Microscope
from ._sources import led

__all__ = ["MAX_CSI_FRAMES", "SCAN_COVER_ENVELOPES", "check_scan_covers", "csi_frames", "psi_frames",
           "scan_needed"]

#: CSI scans with more frames than this are refused.
MAX_CSI_FRAMES = 4096


def _check_seed(seed):
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    return int(seed)


#: The simulation's own estimate of where light returns (for its summaries, never for
#: measuring): the object beam alone is at least this fraction of a mirror's.
LIGHT_FRACTION = 0.05


def _frames(stack, info, mic, *, mode, pixel, origin, delta, scan, z_ref, index, seed, lam_eff,
            settings):
    src = mic.source
    # the camera records every pixel: which ones hold fringes is the measurement's to
    # decide, from the frames (the simulation's light estimate stays with its truth)
    return Frames(frames=stack, valid=np.ones(stack.shape[1:], dtype=bool),
                  pixel=float(pixel), origin=(float(origin[0]), float(origin[1])), mode=mode,
                  wavelength_nm=src.wavelength_nm, numerical_aperture=mic.na,
                  phase_steps=delta, scan_positions=scan, z_ref=z_ref,
                  bandwidth_nm=src.bandwidth_nm or None, objective=mic.objective.name,
                  intensity_index=int(index), subsamples=int(settings["model"]["subsamples"]),
                  seed=int(seed), noise=bool(mic.camera.noise), effective_wavelength_nm=lam_eff,
                  settings=settings)


def _settings(mic, dist, info, s, crop, extra):
    d = {"microscope": mic.describe(), "disturbances": dist.describe(),
         "model": {"subsamples": int(s), "crop_pixels": int(crop),
                   "axial_bins": info["axial_bins"],
                   "axial_step_per_mm": info["axial_step_per_mm"],
                   "undersampled_fraction": info["undersampled_fraction"],
                   "approximations": "Kirchhoff (foil) 3-D linear filter; geometric object "
                                     "intensity; scalar, no multiple scattering"}}
    d.update(extra)
    return d


def _exposed_frames(h, normals, mic, dist, zact, *, pixel, subsamples, crop, kz_tolerance, seed,
                    diagnostics):
    """The camera frames at the reference mirror's positions ``zact``: the interference
    intensity (with the reference's own figure) exposed on the camera.  Returns
    (frames, imaging info, camera info)."""
    s = int(subsamples)
    shape = (h.shape[0] // max(s, 1) - 2 * int(crop), h.shape[1] // max(s, 1) - 2 * int(crop))
    ref = dist.reference_figure(shape, pixel) if shape[0] > 0 and shape[1] > 0 else None
    inten, info = _imaging.interference_intensity(h, normals, pixel=pixel, subsamples=subsamples,
                                         microscope=mic, z_positions=zact, crop=crop,
                                         reference_figure=ref, kz_tolerance=kz_tolerance)
    if diagnostics is not None:
        diagnostics.update(info)
    cancel.check()  # a stop asked for during the intensity ends the run here
    frames, cam = expose(inten, mic.camera, seed=seed, inplace=True)
    return frames, info, cam


def psi_frames(heights: np.ndarray, normals: np.ndarray | None = None, *, pixel: float, subsamples: int = 1,
               microscope: Microscope | None = None, steps: int = 5,
               step_rad: float = math.pi / 2, z_ref: float | None = None,
               disturbances: Disturbances | None = None, seed: int = 0,
               origin: Sequence[float] = (0.0, 0.0), crop: int = 0, kz_tolerance: float = 0.5,
               diagnostics: dict | None = None) -> Frames:
    """Phase-shifting (PSI) frames of a surface.

    The phase shifter moves the scanner by ``-delta_k / K_eff`` for a nominal phase step
    ``delta_k = k step_rad`` (calibrated on a flat mirror, i.e. at the effective
    wavelength); the disturbances change the actual steps.

    Parameters
    ----------
    heights, normals, pixel, subsamples, crop, kz_tolerance
        See :func:`~._imaging.interference_intensity`.
    microscope : Microscope, optional
    steps : int
        Number of frames (>= 3).
    step_rad : float
        Nominal phase step, rad (0 < step < 2 pi).
    z_ref : float, optional
        Scanner position of the first frame, mm (default: the focus the instrument finds
        itself, :func:`~._focus.autofocus`; the settings record how).
    disturbances : Disturbances, optional
    seed : int
        Seed of the camera's temporal noise and of the vibration phase.
    origin : (float, float)
        x, y of the centre of output pixel [0, 0], mm.
    diagnostics : dict, optional
        Filled with the model's by-products: ``light`` ((H', W') float32, the object beam
        alone, B), ``axial_bins``, ``undersampled_fraction`` ...

    Returns
    -------
    Frames
    """
    mic = Microscope() if microscope is None else microscope
    dist = Disturbances() if disturbances is None else disturbances
    seed = _check_seed(seed)
    if int(steps) != steps or steps < 3:
        raise InputError(f"steps must be an integer >= 3, got {steps!r}")
    check_range("step_rad", step_rad, 0, 2 * math.pi, lo_open=True, hi_open=True)
    h = np.asarray(heights, dtype=np.float64)
    if z_ref is None:
        z_ref, focus = autofocus(h, normals, pixel=pixel, subsamples=subsamples, microscope=mic,
                                 crop=crop)
    else:
        focus = {"method": "set by the user", "z_mm": float(z_ref)}
    lam_eff = mic.effective_wavelength_nm()
    k_eff = 4 * math.pi / (lam_eff * NM_TO_MM)
    delta = step_rad * np.arange(int(steps))
    actual = delta * (1.0 + dist.step_error + dist.step_nonlinearity * delta / (2 * math.pi))
    nominal_z = z_ref - delta / k_eff
    zact = dist.positions(z_ref - actual / k_eff, seed=seed, origin_mm=z_ref, scale=False)
    frames, info, cam = _exposed_frames(h, normals, mic, dist, zact, pixel=pixel,
                                        subsamples=subsamples, crop=crop,
                                        kz_tolerance=kz_tolerance, seed=seed,
                                        diagnostics=diagnostics)
    return _frames(frames, info, mic, mode="psi", pixel=pixel, origin=origin, delta=delta,
                   scan=nominal_z, z_ref=float(z_ref), index=0, seed=seed, lam_eff=lam_eff,
                   settings=_settings(mic, dist, info, int(subsamples), crop,
                                      {"camera_exposure": cam, "focus": focus}))


#: Coherence envelopes (the envelope's standard deviation along the scan, ``1 / sigma_k``)
#: a scan must reach beyond the lowest and the highest height, so that each pixel's
#: envelope peak and its samples above half maximum (1.18 of them) lie inside the scan;
#: assumed (the default scan takes 4.5).
SCAN_COVER_ENVELOPES = 2.5


def scan_needed(h_min: float, h_max: float, mic: Microscope, *,
                scan_step_nm: float | None = None) -> dict:
    """The scan a coherence-scanning measurement of heights ``h_min`` .. ``h_max`` (mm)
    needs: ``span_nm`` (the heights' range plus :data:`SCAN_COVER_ENVELOPES` envelopes
    either side), ``step_nm`` and ``frames`` (at that step)."""
    lam_eff = mic.effective_wavelength_nm()
    step_nm = lam_eff / 8 if scan_step_nm is None else float(scan_step_nm)
    sigma = mic.coherence_sigma()
    env = SCAN_COVER_ENVELOPES / sigma if sigma > 0 else lam_eff * NM_TO_MM
    span = (h_max - h_min) + 2 * env
    return {"span_nm": span / NM_TO_MM, "heights_nm": (h_max - h_min) / NM_TO_MM,
            "envelope_nm": env / NM_TO_MM, "step_nm": step_nm,
            "frames": int(math.ceil(span / NM_TO_MM / step_nm)) + 1}


def check_scan_covers(h_min: float, h_max: float, mic: Microscope, *,
                      scan_step_nm: float | None, frames: int) -> dict:
    """Refuse (:class:`InputError`, before any imaging) a scan of ``frames`` frames that
    cannot cover the heights ``h_min`` .. ``h_max`` (mm): every pixel would lie outside
    it and none be measured.  Returns :func:`scan_needed`'s numbers."""
    need = scan_needed(h_min, h_max, mic, scan_step_nm=scan_step_nm)
    have = (int(frames) - 1) * need["step_nm"]
    if have + 1e-9 < need["span_nm"]:
        raise InputError(
            f"render.interferometer.frames = {int(frames)} at scan_step_nm = {need['step_nm']:.4g} "
            f"scans {have:.0f} nm, but the heights in the field span {need['heights_nm']:.0f} nm and "
            f"the coherence envelope needs {need['envelope_nm']:.0f} nm either side: the scan "
            f"must cover at least {need['span_nm']:.0f} nm (frames >= {need['frames']}, or leave "
            f"frames unset to scan the heights' range)")
    return need


def csi_frames(heights: np.ndarray, normals: np.ndarray | None = None, *, pixel: float, subsamples: int = 1,
               microscope: Microscope | None = None, scan_step_nm: float | None = None,
               frames: int | None = None, scan_start: float | None = None,
               disturbances: Disturbances | None = None, seed: int = 0,
               origin: Sequence[float] = (0.0, 0.0), crop: int = 0, kz_tolerance: float = 0.5,
               diagnostics: dict | None = None) -> Frames:
    """Coherence-scanning (CSI) frames: the scanner moves focus and zero path difference
    through the surface, one frame per step.

    Parameters
    ----------
    heights, normals, pixel, subsamples, crop, kz_tolerance
        See :func:`~._imaging.interference_intensity`.
    microscope : Microscope, optional
        Default: the 20x objective with a white LED (600 nm, 120 nm FWHM).
    scan_step_nm : float, optional
        Scan step, nm (default ``lambda_eff / 8``: four frames per fringe).
    frames : int, optional
        Number of frames (default: the heights' range plus 4.5 coherence envelopes
        either side).
    scan_start : float, optional
        First scan position, mm (default: centred on the heights' range).
    disturbances : Disturbances, optional
        ``step_error`` scales the scan; vibration and reference figure apply.
    seed, origin, diagnostics
        See :func:`psi_frames`.

    Returns
    -------
    Frames
    """
    mic = Microscope(source=led(600.0, bandwidth_nm=120.0)) if microscope is None else microscope
    dist = Disturbances() if disturbances is None else disturbances
    seed = _check_seed(seed)
    h = np.asarray(heights, dtype=np.float64)
    fin = h[np.isfinite(h)]
    if fin.size == 0:
        raise InputError("heights are all NaN: no surface in the field")
    lam_eff = mic.effective_wavelength_nm()
    step = (lam_eff / 8 if scan_step_nm is None else float(scan_step_nm)) * NM_TO_MM
    check_range("scan_step_nm", step / NM_TO_MM, 1, 10000)
    sigma = mic.coherence_sigma()
    margin = 4.5 / sigma if sigma > 0 else 2 * lam_eff * NM_TO_MM
    lo, hi = float(fin.min()) - margin, float(fin.max()) + margin
    if frames is None:
        n = math.ceil((hi - lo) / step) + 1
    else:
        if int(frames) != frames or frames < 8:
            raise InputError(f"frames must be an integer >= 8, got {frames!r}")
        n = int(frames)
        if scan_start is None:  # centred: refuse a scan that cannot reach every height
            check_scan_covers(float(fin.min()), float(fin.max()), mic, scan_step_nm=scan_step_nm,
                              frames=n)
    if n > MAX_CSI_FRAMES:
        raise MemoryBudgetError(f"the CSI scan over {(hi - lo) / NM_TO_MM:.0f} nm at "
                                f"scan_step_nm = {step / NM_TO_MM:.4g} needs {n} frames "
                                f"(> {MAX_CSI_FRAMES}): raise "
                                f"scan_step_nm, set frames, or shrink the field of view")
    if scan_start is None:
        scan_start = 0.5 * (lo + hi) - 0.5 * (n - 1) * step
    nominal = float(scan_start) + step * np.arange(n)
    zact = dist.positions(nominal, seed=seed)
    fr, info, cam = _exposed_frames(h, normals, mic, dist, zact, pixel=pixel,
                                    subsamples=subsamples, crop=crop, kz_tolerance=kz_tolerance,
                                    seed=seed, diagnostics=diagnostics)
    mid = (n - 1) // 2
    return _frames(fr, info, mic, mode="csi", pixel=pixel, origin=origin, delta=np.empty(0),
                   scan=nominal, z_ref=float(nominal[mid]), index=mid, seed=seed, lam_eff=lam_eff,
                   settings=_settings(mic, dist, info, int(subsamples), crop,
                                      {"camera_exposure": cam, "scan_step_nm": step / NM_TO_MM}))
