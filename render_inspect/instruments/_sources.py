"""Light sources of the interference microscope: their power spectra.

A source is a power spectral density over wavelength; the imaging model samples it in
wavenumber ``k = 2 pi / lambda`` (rad/mm), where the interference signal is a sum of
harmonics.  Three kinds:

* ``monochromatic``: a line (``bandwidth_nm = 0``, a laser) or a narrow Gaussian band
  (a filtered LED or lamp, FWHM ``bandwidth_nm``), the phase-shifting (PSI) source;
* ``led``: a Gaussian band of centre ``wavelength_nm`` and FWHM ``bandwidth_nm``
  (Gaussian in wavelength), the coherence-scanning (CSI) source;
* ``table``: a measured spectrum given as wavelength / relative power pairs, linearly
  interpolated between the given wavelengths and zero outside them.

Power per wavenumber follows from power per wavelength with the Jacobian
``|d lambda / d k| = 2 pi / k^2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core.errors import InputError, check_range
from ..core.units import NM_TO_MM

__all__ = ["FWHM_PER_SIGMA", "Source", "led", "monochromatic", "spectrum_table"]

#: Full width at half maximum of a Gaussian in units of its standard deviation.
FWHM_PER_SIGMA = 2.0 * math.sqrt(2.0 * math.log(2.0))
#: A Gaussian band is sampled over centre +- this many FWHM (3.5 sigma: 2e-4 of the power
#: lies beyond on each side, where the density is 2e-3 of the peak).
_GAUSS_SPAN_FWHM = 1.5


@dataclass(frozen=True)
class Source:
    """A light source: its power spectrum.

    Attributes
    ----------
    kind : {"monochromatic", "led", "table"}
    wavelength_nm : float
        Centre wavelength (the line, the Gaussian's centre, or for a table the wavelength
        of the power-weighted mean wavenumber), nm.
    bandwidth_nm : float
        Full width at half maximum, nm (0 for a line; for a table the FWHM of the
        Gaussian with the same rms width).
    table_nm : tuple of float, optional
        Wavelengths of a tabulated spectrum, nm (increasing).
    table_weight : tuple of float, optional
        Relative power per unit wavelength at ``table_nm``.
    """

    kind: str
    wavelength_nm: float
    bandwidth_nm: float = 0.0
    table_nm: tuple = ()
    table_weight: tuple = ()

    @property
    def is_line(self) -> bool:
        """True for a single spectral line (infinite coherence length)."""
        return self.kind != "table" and self.bandwidth_nm == 0.0

    def wavenumber_range(self) -> tuple[float, float]:
        """(k_min, k_max) of the sampled spectrum, rad/mm."""
        if self.kind == "table":
            lo, hi = self.table_nm[0], self.table_nm[-1]
        elif self.is_line:
            lo = hi = self.wavelength_nm
        else:
            lo = max(self.wavelength_nm - _GAUSS_SPAN_FWHM * self.bandwidth_nm,
                     0.25 * self.wavelength_nm)
            hi = self.wavelength_nm + _GAUSS_SPAN_FWHM * self.bandwidth_nm
        return 2 * math.pi / (hi * NM_TO_MM), 2 * math.pi / (lo * NM_TO_MM)

    def density_per_wavelength(self, wavelength_nm: ArrayLike) -> np.ndarray:
        """Relative power per unit wavelength (unnormalised) at ``wavelength_nm``."""
        lam = np.asarray(wavelength_nm, dtype=np.float64)
        if self.kind == "table":
            return np.interp(lam, self.table_nm, self.table_weight, left=0.0, right=0.0)
        if self.is_line:
            return np.where(lam == self.wavelength_nm, 1.0, 0.0)
        sigma = self.bandwidth_nm / FWHM_PER_SIGMA
        return np.exp(-0.5 * ((lam - self.wavelength_nm) / sigma) ** 2)

    def sample(self, *, dk: float) -> tuple[np.ndarray, np.ndarray]:
        """Wavenumber nodes and power weights of the spectrum.

        Parameters
        ----------
        dk : float
            Largest node spacing, rad/mm (a line gives one node whatever ``dk``).

        Returns
        -------
        k : (n,) float64, rad/mm
        weight : (n,) float64, power fractions summing to 1
        """
        if self.is_line:
            return np.array([2 * math.pi / (self.wavelength_nm * NM_TO_MM)]), np.ones(1)
        k_lo, k_hi = self.wavenumber_range()
        n = max(math.ceil((k_hi - k_lo) / float(dk)) + 1, 9)
        k = np.linspace(k_lo, k_hi, n)
        lam_nm = 2 * math.pi / k / NM_TO_MM
        w = self.density_per_wavelength(lam_nm) * (2 * math.pi / k ** 2)
        keep = w > 1e-9 * w.max()  # not a unit conversion: a relative floor
        k, w = k[keep], w[keep]
        return k, w / w.sum()

    def describe(self) -> dict:
        """Plain-number description (recorded in the frames' settings)."""
        d = {"kind": self.kind, "wavelength_nm": float(self.wavelength_nm),
             "bandwidth_nm": float(self.bandwidth_nm)}
        if self.kind == "table":
            d["table_nm"] = [float(v) for v in self.table_nm]
            d["table_weight"] = [float(v) for v in self.table_weight]
        return d


def monochromatic(wavelength_nm: float = 550.0, *, bandwidth_nm: float = 0.0) -> Source:
    """A quasi-monochromatic source: a line, or a narrow Gaussian band.

    Parameters
    ----------
    wavelength_nm : float
        Centre wavelength, nm (200..2000).
    bandwidth_nm : float
        FWHM, nm (0 = a single line; at most half the wavelength).
    """
    check_range("wavelength_nm", wavelength_nm, 200, 2000)
    check_range("bandwidth_nm", bandwidth_nm, 0, 0.5 * float(wavelength_nm))
    return Source("monochromatic", float(wavelength_nm), float(bandwidth_nm))


def led(wavelength_nm: float = 600.0, *, bandwidth_nm: float = 120.0) -> Source:
    """A broadband LED: Gaussian in wavelength.

    Parameters
    ----------
    wavelength_nm : float
        Centre wavelength, nm (200..2000).
    bandwidth_nm : float
        FWHM, nm (> 0, at most half the centre wavelength).
    """
    check_range("wavelength_nm", wavelength_nm, 200, 2000)
    check_range("bandwidth_nm", bandwidth_nm, 0, 0.5 * float(wavelength_nm), lo_open=True)
    return Source("led", float(wavelength_nm), float(bandwidth_nm))


def spectrum_problem(wavelength_nm: ArrayLike, weight: ArrayLike) -> str | None:
    """What is wrong with a tabulated spectrum (the same number of wavelengths and weights,
    at least one), in words ("must have weights >= 0 ..."), or None."""
    lam = np.asarray(wavelength_nm, dtype=np.float64).ravel()
    w = np.asarray(weight, dtype=np.float64).ravel()
    if not (np.all(np.isfinite(lam)) and lam.min() >= 200 and lam.max() <= 2000):
        return f"must have wavelengths in [200, 2000] nm, received {lam.min():g} .. {lam.max():g}"
    if lam.size > 1 and not np.all(np.diff(lam) > 0):
        return f"must have strictly increasing wavelengths, received {lam.tolist()}"
    if not (np.all(np.isfinite(w)) and w.min() >= 0 and w.max() > 0):
        return f"must have weights >= 0, not all zero, received {w.tolist()}"
    return None


def spectrum_table(wavelength_nm: ArrayLike, weight: ArrayLike) -> Source:
    """A tabulated spectrum (e.g. an LED's datasheet curve).

    Parameters
    ----------
    wavelength_nm : (n,) array
        Wavelengths, nm, strictly increasing, in 200..2000; n >= 2 (a single entry is a
        line).
    weight : (n,) array
        Relative power per unit wavelength, >= 0, not all zero.
    """
    lam = np.asarray(wavelength_nm, dtype=np.float64).ravel()
    w = np.asarray(weight, dtype=np.float64).ravel()
    if lam.shape != w.shape or lam.size < 1:
        raise InputError(f"spectrum table: wavelength_nm and weight must be 1-D arrays of one "
                         f"length >= 1, got {lam.shape} and {w.shape}")
    why = spectrum_problem(lam, w)
    if why is not None:
        raise InputError(f"spectrum table {why}")
    if lam.size == 1:
        return monochromatic(float(lam[0]))
    src = Source("table", 0.0, 0.0, tuple(lam.tolist()), tuple(w.tolist()))
    k, p = src.sample(dk=(2 * math.pi / (lam[0] * NM_TO_MM)
                          - 2 * math.pi / (lam[-1] * NM_TO_MM)) / 2000)
    k_mean = float(np.sum(k * p))
    lam_k = 2 * math.pi / k / NM_TO_MM
    lam_mean = 2 * math.pi / k_mean / NM_TO_MM
    rms = math.sqrt(float(np.sum(p * (lam_k - lam_mean) ** 2)))
    return Source("table", lam_mean, rms * FWHM_PER_SIGMA, src.table_nm, src.table_weight)
