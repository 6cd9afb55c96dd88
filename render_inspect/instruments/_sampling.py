"""How finely the imaging model samples the surface: from the pupil and the slopes
(:func:`~._microscope.recommended_subsamples`) and from the surface's own content.

The model takes the reflected field ``r exp(i K h)`` at ``s x s`` sub-samples per camera
pixel (spacing ``a = pixel / s``) and keeps what the pupil passes (spatial frequencies
up to ``f_cut = (NA + NA_ill) / lambda``).  Content of the surface at a frequency ``f``
finer than the sub-samples can carry folds back to ``|f - n / a|``; where that lands
inside the pupil it comes back as a false, coarse grating (a 0.3 um grating sampled at
0.293 um reads as a 12.5 um one), although physically its light leaves the pupil and
nothing returns.  Content folds into the pupil only from frequencies above both the
sub-samples' Nyquist frequency and ``1 / a - f_cut``, so the sub-sampling is chosen such
that the surface has (next to) no content there: the height map's spectrum (a DCT, i.e.
the map mirrored at its edges, its plane removed) gives the rms of the heights above any
frequency, and ``s`` is the smallest for which that rms is below
:data:`ALIAS_TOLERANCE_NM`.  A height map holds no content above its own Nyquist
frequency ``1 / (2 pixel_map)``, which bounds ``s`` (:func:`grid_subsamples`).  Where
``s`` is fixed by the user or capped, the content that still folds into the pupil is
reported (``aliased_rms_nm``): the under-sampling diagnostic.

Sampling the heights more finely, not averaging them, is what makes this right: the
field is a nonlinear function of the height, and the mean of ``exp(i K h)`` over an area
is not ``exp(i K mean(h))``.  The linear interpolation of the mesh between the map's
points adds content of its own above the map's Nyquist frequency; it is not counted.
"""

from __future__ import annotations

import math

import numpy as np
from ..core.lazy import lazy_module

from ..core.units import MM_TO_NM
from ._microscope import Microscope

#: SciPy, imported on first use (render_inspect.core.lazy)
sfft = lazy_module("scipy.fft")

__all__ = ["ALIAS_TOLERANCE_NM", "SurfaceSpectrum", "alias_onset", "grid_subsamples",
           "pupil_cutoff", "content_subsamples"]

#: Rms (nm) of the surface's content that may fold into the pupil: a quarter of the
#: camera's noise floor on a flat (0.37 nm, docs/instrument.md); assumed.
ALIAS_TOLERANCE_NM = 0.1


def pupil_cutoff(microscope: Microscope) -> float:
    """``f_cut = k_hi (NA + NA_ill) / (2 pi)`` (cycles/mm), ``k_hi`` at the 99th
    percentile of the source's power (as :func:`~._microscope.recommended_subsamples`)."""
    k, w = microscope.source.sample(dk=microscope._dk_fine())
    k_hi = float(k[min(int(np.searchsorted(np.cumsum(w), 0.99)), k.size - 1)])
    return k_hi * (microscope.na + microscope.na_ill) / (2 * math.pi)


def alias_onset(pixel: float, subsamples: int, microscope: Microscope) -> float:
    """The lowest frequency (cycles/mm) that folds into the pupil at ``subsamples`` per
    pixel side: above the sub-samples' Nyquist frequency ``1 / (2 a)`` and above
    ``1 / a - f_cut`` (``a = pixel / s``)."""
    inv_a = int(subsamples) / float(pixel)
    return max(0.5 * inv_a, inv_a - pupil_cutoff(microscope))


def grid_subsamples(pixel: float, grid_pixel: float, microscope: Microscope) -> int:
    """Sub-samples that leave nothing of a map with ``grid_pixel`` spacing to fold into
    the pupil: :func:`alias_onset` at or above the map's Nyquist frequency
    ``1 / (2 grid_pixel)``."""
    nyq = 0.5 / float(grid_pixel)
    need = min(2 * nyq, nyq + pupil_cutoff(microscope))
    return max(1, math.ceil(float(pixel) * need - 1e-9))


class SurfaceSpectrum:
    """The rms of a height map's content above any spatial frequency.

    Parameters
    ----------
    z : (ny, nx) array, mm (NaN = no surface: filled with the mean)
    pixel : float, mm
    """

    def __init__(self, z, pixel: float):
        z = np.asarray(z, dtype=np.float64)
        ok = np.isfinite(z)
        self.points = int(ok.sum())
        if self.points < 4:
            self.freq = np.zeros(1)
            self.above = np.zeros(1)
            return
        ny, nx = z.shape
        y, x = np.mgrid[0:ny, 0:nx]
        a = np.stack([np.ones(self.points), x[ok], y[ok]], axis=1)
        c = np.linalg.lstsq(a, z[ok], rcond=None)[0]
        r = np.where(ok, z - (c[0] + c[1] * x + c[2] * y), 0.0).astype(np.float32)
        coef = sfft.dctn(r, type=2, norm="ortho")
        fy = np.arange(ny) / (2 * ny * pixel)
        fx = np.arange(nx) / (2 * nx * pixel)
        f = np.hypot(fy[:, None], fx[None, :]).ravel()
        order = np.argsort(-f, kind="stable")  # ties in a fixed order on every machine
        p = (coef.ravel().astype(np.float64) ** 2)[order]
        self.freq = f[order]
        # rms over the map's points of the content at or above each frequency
        self.above = np.sqrt(np.cumsum(p) / (ny * nx))

    def rms_above(self, frequency: float) -> float:
        """Rms (mm) of the content at frequencies above ``frequency`` (cycles/mm)."""
        i = np.searchsorted(-self.freq, -float(frequency), side="left")
        return float(self.above[i - 1]) if i > 0 else 0.0


def content_subsamples(pixel: float, microscope: Microscope, spectrum: SurfaceSpectrum, *,
                       s_min: int, s_max: int,
                       tolerance_nm: float = ALIAS_TOLERANCE_NM) -> tuple[int, float]:
    """The smallest ``s`` in ``[s_min, s_max]`` for which the surface's content that folds
    into the pupil has an rms below ``tolerance_nm``, and that rms (nm) at the ``s``
    returned (``s_max`` when none is enough)."""
    s = max(1, int(s_min))
    while True:
        rms = spectrum.rms_above(alias_onset(pixel, s, microscope)) * MM_TO_NM
        if rms <= tolerance_nm or s >= s_max:
            return s, rms
        s += 1
