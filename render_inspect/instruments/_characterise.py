"""The virtual instrument's own metrological characteristics, in the
style of ISO 25178-600 / -604, from calibration artefacts imaged through the model and
measured from their frames:

* a sinusoid sweep -> the instrument transfer function (ITF), against the model's linear
  ITF and the textbook pupil overlap;
* steps -> the step response (10-90 % edge width, PSI) and the batwing (CSI);
* a sphere -> fringe contrast and drop-out against slope, and the slope at which half
  the pixels drop out;
* a flat -> measurement noise (subtraction of two measurements) and flatness deviation.

The artefacts are exact analytic surfaces (their heights and normals at the sub-samples,
what the ray tracer returns for them), so every number is the instrument's own.
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import replace

import numpy as np

from ..core import cancel
from ..core.errors import InputError
from ..core.units import NM_TO_MM, NM_TO_UM, UM_TO_MM
from ..metrology import (
    areal_parameters,
    batwing,
    dropout_slope,
    edge_width,
    measure_frames,
    noise_by_subtraction,
    pupil_overlap,
    remove_form,
    sinusoid_amplitude,
    slope_table,
)
from . import _artefacts as artefacts
from ._microscope import Microscope, recommended_subsamples
from ._modes import csi_frames, psi_frames
from ._sampling import pupil_cutoff
from ._interferometer import (InterferometerConfig, disturbances_from_config,
                              microscope_from_config)
from ._objectives import OBJECTIVES

__all__ = ["characterise_instrument", "BATWING_STEPS_NM", "ITF_FRACTIONS"]

_NM = NM_TO_MM
_UM = UM_TO_MM
#: Step heights of the batwing study, nm.
BATWING_STEPS_NM = (50.0, 100.0, 200.0, 1000.0, 5000.0)
#: ITF sweep, as fractions of the textbook cut-off frequency; beyond 1 nothing may come
#: back (a grating whose first order leaves the pupil), whatever the camera's sampling.
ITF_FRACTIONS = (0.02, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.95, 1.05, 1.5, 2.0,
                 3.0)


def _measure(h, n, *, pixel, s, mic, dist, mode, seed, algorithm="auto", **kw):
    cancel.check()  # a stop asked by a signal is honoured between measurements
    fn = psi_frames if mode == "psi" else csi_frames
    fr = fn(h, n, pixel=pixel, subsamples=s, microscope=mic, disturbances=dist, seed=seed, **kw)
    return fr, measure_frames(fr, algorithm=algorithm)


def _quiet(mic: Microscope) -> Microscope:
    """The same microscope with a noise-free camera (for transfer measurements)."""
    return replace(mic, camera=replace(mic.camera, noise=False))


def _itf(mic, dist, *, mode, pixel, fine, quick):
    na, na_ill = mic.na, mic.na_ill
    lam_nm = mic.source.wavelength_nm
    fc = (na + na_ill) / (lam_nm * _NM)  # textbook cut-off, cycles/mm
    amp = lam_nm * _NM / 40  # K a ~ 0.3 rad: the linear regime
    alg = "auto" if mode == "psi" else "envelope+phase"
    quiet = _quiet(mic)
    fracs = ITF_FRACTIONS[::2] + (0.95, 2.0) if quick else ITF_FRACTIONS
    rows = []
    for frac in sorted(set(fracs)):
        f = frac * fc
        period = 1 / f
        row = {"frequency_per_mm": f, "period_um": period / _UM}
        for key, p in (("itf_optics", fine), ("itf_instrument", pixel)):
            nper = max(2, math.ceil(max(32 * p, 16 * _UM) / period))
            n = max(16, round(nper * period / p))
            per = n * p / nper  # an integer number of periods in the (periodic) field
            # sampled finely enough that the grating itself cannot fold into the pupil
            s = max(recommended_subsamples(p, quiet, max_slope=2 * math.pi * amp / per),
                    math.ceil(p * (pupil_cutoff(quiet) + 1 / per) * (1 + 1e-6)))
            h, nrm = artefacts.sinusoid((4, n), p, s, period=per, amplitude=amp)
            _, m = _measure(h, nrm, pixel=p, s=s, mic=quiet, dist=dist, mode=mode, seed=0,
                            algorithm=alg)
            x = p * np.arange(n)
            prof = np.nanmean(m.height, axis=0)
            if 1 / per <= 0.5 / p:
                row[key] = sinusoid_amplitude(prof, x, per) / amp
            else:
                # above the camera's Nyquist frequency there is no transfer function: the
                # camera cannot sample the grating.  What comes back is kept apart, as the
                # amplitude of the aliased pattern (the camera's alias of what the optics
                # pass; none beyond the cut-off)
                d = prof[np.isfinite(prof)]
                d = d - d.mean()
                row[key] = None
                row[key.replace("itf_", "aliased_")] = (
                    float(math.sqrt(2 * np.mean(d * d))) / amp if d.size else None)
        row["itf_model"] = float(mic.itf(f))
        row["itf_textbook"] = float(pupil_overlap(f, numerical_aperture=na, illumination_na=na_ill,
                                                  wavelength_nm=lam_nm))
        rows.append(row)
    opt = [(r["frequency_per_mm"], r["itf_optics"]) for r in rows]
    half = float("nan")
    for (f0, a0), (f1, a1) in itertools.pairwise(opt):
        if a0 >= 0.5 > a1:
            half = f0 + (a0 - 0.5) / (a0 - a1) * (f1 - f0)
            break
    beyond = [r["itf_instrument"] if r["itf_instrument"] is not None
              else r.get("aliased_instrument") for r in rows if r["frequency_per_mm"] > fc]
    beyond = [b for b in beyond if b is not None]
    nyq = 0.5 / pixel
    return {"amplitude_nm": amp / _NM, "cutoff_per_mm": fc, "cutoff_period_um": 1 / fc / _UM,
            "beyond_cutoff_max": max(beyond) if beyond else None,
            "half_transfer_per_mm": half, "camera_nyquist_per_mm": nyq,
            "instrument_transfer_up_to_per_mm": min(nyq, fc),
            "instrument_note": (f"the transfer function at the camera pixel stops at the camera's "
                                f"Nyquist frequency ({nyq:.4g} /mm): above it the camera cannot "
                                f"sample a grating, and what comes back (aliased_instrument) is "
                                f"an alias, not a transfer value")
            if nyq < fc * max(ITF_FRACTIONS) else None,
            "fine_pixel_um": fine / _UM, "algorithm": alg, "table": rows}


def _steps(mic, dist, *, csi_mic, fine, quick):
    out = {}
    # PSI, small step (linear regime): the edge-spread width
    quiet = _quiet(mic)
    n = 512
    h, nrm = artefacts.step((4, n), fine, height=20 * _NM)
    _, m = _measure(h, nrm, pixel=fine, s=1, mic=quiet, dist=dist, mode="psi", seed=0)
    x = fine * np.arange(n)
    prof = np.nanmean(m.height, axis=0)
    edge = n // 4
    w = round(3 * _UM / fine)
    out["psi_edge_width_10_90_um"] = edge_width(prof[edge - w:edge + w], x[edge - w:edge + w]) / _UM
    out["psi_profile"] = {"x_um": ((x[edge - w:edge + w] - x[edge]) / _UM).tolist(),
                          "height_nm": ((prof[edge - w:edge + w] - np.nanmedian(prof[:edge // 2]))
                                        / _NM).tolist()}
    # CSI: the batwing against step height
    cq = _quiet(csi_mic)
    rows, profiles = [], {}
    for st in (BATWING_STEPS_NM[1], BATWING_STEPS_NM[-1]) if quick else BATWING_STEPS_NM:
        h, nrm = artefacts.step((4, n), fine, height=st * _NM)
        _, m = _measure(h, nrm, pixel=fine, s=1, mic=cq, dist=dist, mode="csi", seed=0,
                        algorithm="envelope")
        err = (np.nanmean(m.height, axis=0) - h[0]) / _NM
        err -= np.nanmedian(err)
        lobes = batwing(err, x, edge=x[edge] - fine / 2, side_length=3 * _UM, exclude=fine)
        rows.append({"step_nm": st, "batwing_pv_nm": lobes.peak_to_valley,
                     "batwing_height_nm": lobes.height, "batwing_width_um": lobes.width / _UM,
                     "batwing_low_side_nm": lobes.low,
                     "batwing_low_side_width_um": lobes.low_width / _UM,
                     "batwing_high_side_nm": lobes.high,
                     "batwing_high_side_width_um": lobes.high_width / _UM,
                     "valid_fraction": float(m.valid.mean())})
        profiles[f"{st:g} nm"] = ((x[edge - w:edge + w] - x[edge]) / _UM, err[edge - w:edge + w])
    lam_c = csi_mic.source.wavelength_nm
    bw_nm = csi_mic.source.bandwidth_nm
    out["csi"] = {"source_nm": [lam_c, bw_nm],
                  "coherence_length_um": (lam_c ** 2 / bw_nm * NM_TO_UM) if bw_nm else None,
                  "table": rows}
    return out, profiles


#: Pixels imaged around the sphere's field and cropped.
_SPHERE_MARGIN = 8


def _sphere(mic, dist, *, pixel, n, seed):
    # measured by coherence scanning: every pixel is seen in its own focus, so the
    # contrast and drop-out depend on the slope alone, not on defocus across the sphere
    alpha_lim = 0.5 * (math.asin(mic.na) + math.asin(mic.na_ill))
    r_edge = 0.5 * n * pixel
    radius = r_edge / math.sin(min(1.25 * alpha_lim, 1.2))
    s = min(recommended_subsamples(pixel, mic), 8)
    # imaged with a margin of pixels around the field, cropped after imaging (as the
    # renderer does): the model's field is periodic, and the sphere's steep opposite
    # borders must not meet
    h, nrm = artefacts.sphere((n + 2 * _SPHERE_MARGIN, n + 2 * _SPHERE_MARGIN), pixel, s,
                              radius=radius)
    fr, m = _measure(h, nrm, pixel=pixel, s=s, mic=mic, dist=dist, mode="csi", seed=seed,
                     algorithm="envelope", crop=_SPHERE_MARGIN)
    x = pixel * np.arange(n)
    xc = x.mean()  # the artefact's centre (the sub-samples are centred on the pixels)
    r = np.hypot(x[None, :] - xc, x[:, None] - xc)
    # the disc inscribed in the field (slopes up to 1.25 times the limit); corners left out
    slope = np.where(r <= r_edge, np.arcsin(np.clip(r / radius, 0, 1)), np.nan)
    truth = radius * (np.sqrt(np.maximum(1 - (r / radius) ** 2, 0)) - 1)
    # one offset, from the gentle slopes (a few wrong envelope peaks near the slope limit
    # must not shift the whole map)
    d = m.height - truth
    gentle = m.valid & np.isfinite(d) & (slope < 0.5 * alpha_lim)
    err = (d - (np.median(d[gentle]) if gentle.any() else 0.0)) / _NM
    rows = slope_table(slope, m.valid, m.modulation, bin_rad=math.radians(0.5), error=err)
    for row in rows:
        row["error_rms_nm"] = row.pop("error_rms")
    return {"radius_mm": radius, "subsamples": s, "pixel_um": pixel / _UM, "mode": "csi",
            "frames": int(fr.frames.shape[0]),
            "dropout_50_deg": dropout_slope(rows), "slope_limit_deg": math.degrees(alpha_lim),
            "table": rows}


def _flat(mic, dist, *, mode, pixel, n, seed):
    h, nrm = artefacts.flat((n, n), pixel)
    _, a = _measure(h, nrm, pixel=pixel, s=1, mic=mic, dist=dist, mode=mode, seed=seed)
    _, b = _measure(h, nrm, pixel=pixel, s=1, mic=mic, dist=dist, mode=mode, seed=seed + 1)
    noise = noise_by_subtraction(a.height, b.height)
    flat, _ = remove_form(a.height, pixel=pixel, method="plane")
    par = areal_parameters(flat, pixel=pixel)
    return {"noise_nm": noise / _NM, "flatness_Sq_nm": par["Sq"] / _NM,
            "flatness_Sz_nm": par["Sz"] / _NM, "valid_fraction": float(a.valid.mean()),
            "seeds": [seed, seed + 1]}, (a.height - b.height) / _NM


def characterise_instrument(icfg: InterferometerConfig, *, quick: bool = False, seed: int = 0) -> tuple[dict, dict]:
    """Characterise the instrument of ``[render.interferometer]``.

    Returns
    -------
    metrics : dict
        ``objective``, ``mode``, ``itf`` (cut-off, half-transfer frequency, table),
        ``step`` (PSI edge width; CSI batwing table), ``slope`` (instrument at its
        pixel and optics alone: drop-out slope, table), ``flat`` (noise, flatness).
    curves : dict
        What the figures show besides the metrics: ``step_profiles`` (the CSI batwing
        profiles: label -> (x um, error nm)) and ``flat_difference`` (nm map of two
        measurements of the flat subtracted).
    """
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    mic = microscope_from_config(icfg)
    dist = disturbances_from_config(icfg)
    mode = icfg.mode
    pixel = float(icfg.pixel if icfg.pixel is not None else OBJECTIVES[icfg.objective].pixel)
    lam_c = mic.source.wavelength_nm * _NM
    fine = min(pixel, lam_c / (8 * (mic.na + mic.na_ill)))
    csi_mic = mic if mode == "csi" else microscope_from_config(
        icfg.model_copy(update={"mode": "csi", "wavelength_nm": None, "bandwidth_nm": None,
                                "spectrum": None}))
    timing = {}
    t = time.perf_counter()
    itf = _itf(mic, dist, mode=mode, pixel=pixel, fine=fine, quick=quick)
    timing["itf"] = time.perf_counter() - t
    t = time.perf_counter()
    step, profiles = _steps(mic, dist, csi_mic=csi_mic, fine=fine, quick=quick)
    timing["step"] = time.perf_counter() - t
    t = time.perf_counter()
    n = 64 if quick else 128
    slope = {"instrument": _sphere(csi_mic, dist, pixel=pixel, n=n, seed=seed),
             "optics": _sphere(csi_mic, dist, pixel=fine, n=n, seed=seed)}
    timing["slope"] = time.perf_counter() - t
    t = time.perf_counter()
    flat, diff = _flat(mic, dist, mode=mode, pixel=pixel, n=n, seed=seed)
    timing["flat"] = time.perf_counter() - t
    obj = mic.objective
    metrics = {"objective": obj.describe(), "mode": mode, "source": mic.source.describe(),
               "illumination_na": mic.na_ill,
               "effective_wavelength_nm": mic.effective_wavelength_nm(),
               "itf": itf, "step": step, "slope": slope, "flat": flat, "seed": int(seed),
               "pixel_mm": pixel, "timing_s": timing}
    return metrics, {"step_profiles": profiles, "flat_difference": diff}
