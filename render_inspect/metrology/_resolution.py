"""Whether the difference of two measurements is above their noise.

Two measurements of two surfaces carry two independent realisations of the camera's
noise.  Each measurement estimates its own height noise per pixel from its frames
(:attr:`~._phase.PhaseResult.height_noise`); the difference ``a - b`` then carries
``sqrt(n_a^2 + n_b^2)`` per pixel, and its rms over the pixels both measured is the
difference's noise floor::

    floor = sqrt(mean(n_a^2 + n_b^2))

A measured difference of rms ``D`` holds ``D^2 ~ S^2 + floor^2`` (signal and noise are
independent), so its part above the noise is ``S ~ sqrt(max(D^2 - floor^2, 0))``.  The
difference is called *resolved* when that part is at least as large as the noise
itself, ``S >= floor`` (``D >= sqrt(2) floor``): below it, two measurements of the same
surface would differ by about as much.  The rule is assumed, not taken from a standard;
a repeated measurement (:func:`repeat_statistics`, an MSA-style repeatability study)
measures the spread directly instead of estimating it.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import math

import numpy as np

from ..core.units import MM_TO_NM

__all__ = ["RESOLVED_RATIO", "difference_noise", "resolution", "repeat_statistics",
           "measurement_seeds"]

#: A difference is resolved when its rms is at least this many times its noise floor
#: (its part above the noise at least as large as the noise); assumed.
RESOLVED_RATIO = math.sqrt(2.0)


def measurement_seeds(seed: int, count: int, *, repeat: int = 0) -> list[int]:
    """Camera-noise seeds of ``count`` measurements (of repeat ``repeat``): independent
    streams spawned from the scene's ``seed`` (:class:`numpy.random.SeedSequence`), so
    no two measurements share one noise realisation; the same seed gives the same seeds."""
    out = []
    for i in range(int(count)):
        ss = np.random.SeedSequence(int(seed), spawn_key=(int(repeat), i))
        out.append(int(ss.generate_state(1, dtype=np.uint32)[0]))
    return out


def difference_noise(noise_a: np.ndarray | None, noise_b: np.ndarray | None,
                     valid: np.ndarray | None = None) -> dict:
    """Noise floor of ``a - b`` from the two measurements' own per-pixel height noise
    (mm): ``{"floor_nm", "a_nm", "b_nm", "pixels"}`` (rms over the pixels both measured
    and ``valid``); floors are None when a measurement gives no noise estimate."""
    if noise_a is None or noise_b is None:
        return {"floor_nm": None, "a_nm": None, "b_nm": None, "pixels": 0,
                "method": "not estimated (a measurement gives no noise estimate)"}
    na = np.asarray(noise_a, dtype=np.float64)
    nb = np.asarray(noise_b, dtype=np.float64)
    ok = np.isfinite(na) & np.isfinite(nb)
    if valid is not None:
        ok &= np.asarray(valid, bool)
    if not ok.any():
        return {"floor_nm": None, "a_nm": None, "b_nm": None, "pixels": 0,
                "method": "not estimated (no pixel measured in both)"}
    a2, b2 = float(np.mean(na[ok] ** 2)), float(np.mean(nb[ok] ** 2))
    return {"floor_nm": math.sqrt(a2 + b2) * MM_TO_NM, "a_nm": math.sqrt(a2) * MM_TO_NM,
            "b_nm": math.sqrt(b2) * MM_TO_NM, "pixels": int(ok.sum()),
            "method": "each measurement's height noise from its own frames, added in "
                      "quadrature, rms over the pixels both measured"}


def resolution(rms_nm: Any, floor_nm: Any) -> dict:
    """Is a difference of rms ``rms_nm`` resolved above a noise floor ``floor_nm``?

    Returns ``{"resolved": bool or None, "verdict": "resolved" / "not resolved" /
    "unknown", "above_noise_nm", "ratio", "rule"}``."""
    rule = (f"resolved when the rms is at least {RESOLVED_RATIO:.3g} x the noise floor "
            f"(its part above the noise at least as large as the noise)")
    if rms_nm is None or floor_nm is None or not np.isfinite(rms_nm) or not floor_nm > 0:
        return {"resolved": None, "verdict": "unknown", "above_noise_nm": None, "ratio": None,
                "rule": rule}
    ratio = float(rms_nm) / float(floor_nm)
    ok = bool(ratio >= RESOLVED_RATIO)
    return {"resolved": ok, "verdict": "resolved" if ok else "not resolved",
            "above_noise_nm": math.sqrt(max(float(rms_nm) ** 2 - float(floor_nm) ** 2, 0.0)),
            "ratio": ratio, "rule": rule}


def repeat_statistics(differences_nm: np.ndarray, rms_nm: Sequence[float | None]) -> dict:
    """Repeatability of a difference over ``N`` repeated measurement pairs (an MSA-style
    study): ``differences_nm`` (N, ny, nx) levelled difference maps (nm, NaN = not
    measured), ``rms_nm`` their rms values.

    Returns ``repeats``, ``rms_nm`` (each repeat's), ``rms_mean_nm``, ``rms_std_nm``
    (sample standard deviation), ``pixel_repeatability_nm`` (rms over the pixels of each
    pixel's standard deviation across the repeats: the measured noise of one difference),
    ``mean_map_rms_nm`` (rms of the mean of the repeats), ``mean_map_floor_nm``
    (``pixel_repeatability / sqrt(N)``: the mean's noise) and the mean's
    :func:`resolution`."""
    d = np.asarray(differences_nm, dtype=np.float64)
    n = d.shape[0]
    r = [None if v is None else float(v) for v in rms_nm]
    vals = np.array([v for v in r if v is not None], dtype=np.float64)
    out = {"repeats": int(n), "rms_nm": r,
           "rms_mean_nm": float(vals.mean()) if vals.size else None,
           "rms_std_nm": float(vals.std(ddof=1)) if vals.size > 1 else None,
           "pixel_repeatability_nm": None, "mean_map_rms_nm": None, "mean_map_floor_nm": None}
    if n >= 2:
        all_ok = np.all(np.isfinite(d), axis=0)
        if all_ok.any():
            sd = np.std(d[:, all_ok], axis=0, ddof=1)
            rep = float(np.sqrt(np.mean(sd * sd)))
            mean_map = np.mean(d[:, all_ok], axis=0)
            out.update(pixel_repeatability_nm=rep,
                       mean_map_rms_nm=float(np.sqrt(np.mean(mean_map ** 2))),
                       mean_map_floor_nm=rep / math.sqrt(n), pixels=int(all_ok.sum()))
    out["mean_map"] = resolution(out["mean_map_rms_nm"], out["mean_map_floor_nm"])
    return out
