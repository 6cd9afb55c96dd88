"""Autofocus: the scanner position the instrument focuses at before phase shifting,
found from its own signal.

A real interference microscope focuses by scanning its objective and looking for the
fringes: where their contrast is highest, the part is in focus and the zero path
difference lies on it.  Here the scanner steps through the height span of the field
(plus two coherence envelopes either side: the scan a real autofocus makes until it
sees fringes, started where the part is), and at each position the mean fringe amplitude
over the field is read from the imaging model on a binned camera (super-pixels of
``b x b`` camera pixels, at most :data:`AUTOFOCUS_PIXELS` across, as autofocus routines
bin the camera for speed; facets steeper than the binned sampling can carry are left
out, and the binning is made finer while they are most of the field).  The focus is the
position of the largest mean amplitude, refined by a parabola through it and its
neighbours.  No height of the part is used to
place it: where the field holds several heights, the focus lands where most of the
light's fringes are.

The amplitude is the model's noise-free interference term (the fringe amplitude a
phase-shifting set at that position would measure, without the camera's noise).
"""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError
from ..core.units import NM_TO_MM
from ._imaging import interference_intensity, normals_from_heights
from ._microscope import Microscope

__all__ = ["AUTOFOCUS_PIXELS", "autofocus"]

#: Largest number of (binned) camera pixels across the field the autofocus looks at (a
#: speed choice: on 256 x 256 pixel fields of a sphere, a grid with turning marks and
#: scallops the focus found at 48 is the one found at full resolution within 0.01 of the
#: depth of focus; at 24 a sphere's moves by half of it).
AUTOFOCUS_PIXELS = 48
#: Most scanner positions of the autofocus scan.
AUTOFOCUS_STEPS = 400


def _finite_range(h: np.ndarray) -> tuple[float, float]:
    """The smallest and largest finite height (NaN: no surface), without a copy of them."""
    lo = float(np.fmin.reduce(h, axis=None)) if h.size else math.nan
    hi = float(np.fmax.reduce(h, axis=None)) if h.size else math.nan
    if not (math.isfinite(lo) and math.isfinite(hi)):
        fin = h[np.isfinite(h)]  # (an infinite height, or none at all)
        if fin.size == 0:
            raise InputError("heights are all NaN: no surface in the field")
        lo, hi = float(fin.min()), float(fin.max())
    return lo, hi


def autofocus(heights: np.ndarray, normals: np.ndarray | None = None, *, pixel: float, subsamples: int = 1,
              microscope: Microscope | None = None, crop: int = 0) -> tuple[float, dict]:
    """The scanner position of best focus, from the fringe contrast on a coarse scan.

    Parameters
    ----------
    heights, normals, pixel, subsamples, crop
        The surface as :func:`~._imaging.interference_intensity` takes it.
    microscope : Microscope, optional

    Returns
    -------
    z : float
        Scanner position of the largest mean fringe amplitude, mm.
    info : dict
        ``method``, ``search_mm`` (the scan's first and last position), ``step_mm``,
        ``positions``, ``binning`` (camera pixels per side of a super-pixel),
        ``amplitude`` (the mean fringe amplitude at the focus, in units of a mirror's),
        ``found`` (False when no position showed fringes: the scan's centre is taken).
    """
    mic = Microscope() if microscope is None else microscope
    h = np.asarray(heights, dtype=np.float64)
    s = int(subsamples)
    h_lo, h_hi = _finite_range(h)
    hc, wc = h.shape[0] // s, h.shape[1] // s
    crop = int(crop)
    nrm = normals_from_heights(h, pixel / s) if normals is None else np.asarray(normals)
    k, w = mic.source.sample(dk=mic._dk_fine())
    k_hi = float(k[min(int(np.searchsorted(np.cumsum(w), 0.99)), k.size - 1)])
    b = math.ceil(max(hc - 2 * crop, wc - 2 * crop) / AUTOFOCUS_PIXELS)
    b = max(1, min(b, min(hc, wc) // 4))  # a narrow field keeps a few rows
    while True:
        # s sub-samples per super-pixel of b x b camera pixels: every b-th sub-sample.
        # Facets steeper than that sampling carries (more than pi of phase from one
        # sample to the next) are left out rather than folded into the pupil; the
        # binning is made finer while they are most of the field.
        hb, wb = hc // b, wc // b
        off = (b - 1) // 2
        hsub = h[:hb * b * s, :wb * b * s][off::b, off::b]
        nsub = nrm[:hb * b * s, :wb * b * s][off::b, off::b]
        # (the facets' slopes of these sub-samples alone: each is its own element's)
        with np.errstate(invalid="ignore", divide="ignore"):
            tsub = np.hypot(nsub[..., 0], nsub[..., 1]) / nsub[..., 2]
        steep = ~(tsub <= math.pi / (2 * k_hi * b * pixel / s))
        fin_b = np.isfinite(hsub)
        if b == 1 or (fin_b & ~steep).sum() >= 0.5 * fin_b.sum():
            break
        b = max(1, b // 2)
    if b > 1:
        hsub = np.where(steep, np.nan, hsub)
    cb = min(math.ceil(crop / b), (min(hb, wb) - 1) // 2)
    sigma = mic.coherence_sigma()
    env = 1.0 / sigma if sigma > 0 else 10 * mic.effective_wavelength_nm() * NM_TO_MM
    lo, hi = h_lo - 2 * env, h_hi + 2 * env
    step = max(0.5 * env, (hi - lo) / (AUTOFOCUS_STEPS - 1))
    n = int(math.floor((hi - lo) / step)) + 1
    z = lo + step * np.arange(n)
    _, info = interference_intensity(hsub, nsub, pixel=pixel * b, subsamples=s, microscope=mic,
                                     z_positions=z, crop=cb, return_field=True)
    amp = np.abs(info["field"]).reshape(n, -1).mean(axis=1)
    found = bool(np.isfinite(amp).all() and amp.max() > 0)
    if not found:
        best = 0.5 * (lo + hi)
    else:
        i = int(np.argmax(amp))
        best = float(z[i])
        if 0 < i < n - 1:
            a0, a1, a2 = amp[i - 1], amp[i], amp[i + 1]
            den = a0 - 2 * a1 + a2
            if den < 0:
                best += float(np.clip(0.5 * (a0 - a2) / den, -0.5, 0.5)) * step
    peak = float(amp.max()) if found else 0.0
    return best, {"method": "largest mean fringe amplitude on a coarse scan (binned camera)",
                  "search_mm": [float(z[0]), float(z[-1])], "step_mm": float(step),
                  "positions": int(n), "binning": int(b), "amplitude": peak,
                  "found": found, "z_mm": float(best)}
