"""Transfer function of the interference microscope (linear, Kirchhoff / foil model).

For a wavenumber ``k`` of the source, an illumination direction ``q_i`` (transverse
wave vector, ``|q_i| <= k NA_ill``, uniform over the condenser aperture: Koehler
illumination) and a collected direction ``q_o`` (``|q_o| <= k NA``, the objective pupil),
the surface couples the object spatial frequency ``Q = q_o - q_i`` with the axial
frequency ``K = k_zi + k_zo`` (``k_z = sqrt(k^2 - |q|^2)``).  In the Kirchhoff
(tangent-plane) approximation of a surface ``z = h(x)`` the angular spectrum of the
reflected field is ::

    A(q_o) = r / (2 k_zo) * Integral (K - Q . grad h) exp(i (K h - Q . x)) d^2x
           = r |K|^2 / (2 k_zo K) * Integral exp(i (K h - Q . x)) d^2x

(the second line by integrating the slope term by parts; ``|K|^2 = |Q|^2 + K^2``), so the
interference term of the image is the 3-D linear filter of Coupland et al. (2013) [1]_::

    X(x, z) = sum_K  exp(-i K z)  IFFT[ H(Q, K) FFT[ r exp(i K h) ] ](x)

with the transfer function ::

    H(Q, K) = sum_k S(k) Integral d^2q_i  rho(q_i) P(q_i + Q) |K|^2 / (2 k_zo K)
                                       delta(K - k_zi - k_zo)

(``S`` the source's power spectrum, ``rho`` the normalised illumination density,
``P`` the pupil).  A flat mirror gives ``H(0, K)`` a distribution of unit mass whose mean
``K_eff`` sets the fringe spacing ``lambda_eff = 4 pi / K_eff`` (the NA factor).

``H`` is rotationally symmetric in ``Q``.  It is tabulated as ``H[b, m]`` on axial bins
``K_b`` (spacing ``dK``, linear "cloud-in-cell" deposit) and radial frequencies
``Q_m = m dq``.  Binning replaces ``exp(i K zeta)`` (``zeta = z - h``) by its linear
interpolation between bins: an amplitude error of at most ``(dK zeta)^2 / 8`` and a phase
error of third order, so :func:`axial_step` picks ``dK`` from the range of ``zeta`` the
frames need.  For an ideal instrument the transfer function is set by the NA and the
source spectrum alone, as Mandal et al. (2014) [2]_ measured it.

References
----------
.. [1] J. M. Coupland, R. Mandal, K. Palodhi, R. K. Leach, "Coherence scanning
       interferometry: linear theory of surface measurement," Applied Optics 52(16),
       3662-3670 (2013).
.. [2] R. Mandal, J. Coupland, R. Leach, D. Mansfield, "Coherence scanning interferometry:
       measurement and correction of three-dimensional transfer and point-spread
       characteristics," Applied Optics 53(8), 1554-1563 (2014).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from ..core.errors import InputError, MemoryBudgetError
from ..core.units import MM_TO_NM
from . import _sources
from ._table_cache import cached_arrays

__all__ = [
    "MAX_AXIAL_BINS",
    "TransferFunction",
    "acceptance_table",
    "axial_step",
    "flat_moments",
    "linear_itf",
    "transfer_function",
    "unit_transfer_table",
]

#: More axial bins than this is refused (each costs two FFTs per image).
MAX_AXIAL_BINS = 2048
_N_Q = 2048  # radial samples of the tabulated transfer function


@lru_cache(maxsize=32)
def _illumination_points(na_ill: float, obscuration_na: float, n_grid: int):
    """Illumination directions (direction cosines) over the condenser disc, the fraction of
    each grid cell inside the (annular) disc, their sum, and the cell size."""
    if na_ill <= 0:
        return np.zeros((1, 2)), np.ones(1), 1.0, 0.0
    c = 2 * na_ill / n_grid
    g = -na_ill + c * (np.arange(n_grid) + 0.5)
    sx, sy = np.meshgrid(g, g)
    r = np.hypot(sx, sy)
    w = np.clip((na_ill - r) / c + 0.5, 0.0, 1.0)
    if obscuration_na > 0:
        w *= np.clip((r - obscuration_na) / c + 0.5, 0.0, 1.0)
    keep = w > 0
    pts = np.stack([sx[keep], sy[keep]], axis=1)
    w = w[keep]
    if w.sum() <= 0:
        raise InputError("the illumination aperture is fully obscured: lower central_obscuration")
    return pts, w, float(w.sum()), c


@lru_cache(maxsize=32)
def unit_transfer_table(na: float, na_ill: float, obscuration: float = 0.0, *,
                        n_u: int = 385, n_kappa: int = 512,
                        n_grid: int = 112) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The transfer function for unit wavenumber, ``G(u, kappa)``.

    ``u = |Q| / k`` and ``kappa = K / k``; for wavenumber ``k``,
    ``H_k(Q, K) dK = G(Q / k, K / k) d kappa``.

    Parameters
    ----------
    na, na_ill : float
        Objective and illumination numerical apertures (``na_ill = 0``: one on-axis
        plane wave, coherent illumination).
    obscuration : float
        Central obscuration of the pupil (fraction of its radius); it blocks the
        illumination and the collected light alike.

    Returns
    -------
    u : (n_u,) float64
        ``0 .. na + na_ill``.
    kappa : (n_kappa,) float64
        Axial grid (``sqrt(1 - na_ill^2) + sqrt(1 - na^2) .. 2``, one node of margin).
    G : (n_u, n_kappa) float64
        Mass per kappa node (linear deposit); ``G[0].sum() = 1`` when ``na_ill <= na``.

    Kept on disk between processes (:mod:`._table_cache`).
    """
    args = {"na": float(na), "na_ill": float(na_ill), "obscuration": float(obscuration),
            "n_u": int(n_u), "n_kappa": int(n_kappa), "n_grid": int(n_grid)}
    t = cached_arrays("unit_transfer_table", args, __file__,
                      lambda: dict(zip(("u", "kappa", "G"), _unit_transfer_table(**args))))
    return t["u"], t["kappa"], t["G"]


def _unit_transfer_table(*, na, na_ill, obscuration, n_u, n_kappa, n_grid):
    obs_na = obscuration * na
    pts, a, norm, c = _illumination_points(float(na_ill), float(obs_na), int(n_grid))
    u = np.linspace(0.0, na + na_ill, n_u)
    if c == 0.0:
        c = u[1] - u[0]  # soft pupil edge over one u step (coherent illumination)
    k_lo = math.sqrt(1 - na_ill ** 2) + math.sqrt(1 - na ** 2)
    dk = (2.0 - k_lo) / (n_kappa - 3)
    kappa = k_lo - dk + dk * np.arange(n_kappa)
    ci = np.sqrt(np.maximum(1.0 - np.sum(pts ** 2, axis=1), 0.0))
    G = np.zeros((n_u, n_kappa))
    for j, uj in enumerate(u):
        ox = pts[:, 0] + uj
        ro = np.hypot(ox, pts[:, 1])
        p = np.clip((na - ro) / c + 0.5, 0.0, 1.0)
        if obs_na > 0:
            p *= np.clip((ro - obs_na) / c + 0.5, 0.0, 1.0)
        m = p > 0
        if not m.any():
            continue
        co = np.sqrt(np.maximum(1.0 - ro[m] ** 2, 1e-12))
        kap = ci[m] + co
        beck = (uj * uj + kap * kap) / (2.0 * co * kap)
        # area of the illumination cell that also lies in the pupil (the minimum of the
        # two soft edges is exact where the edges are parallel, e.g. at Q = 0)
        mass = np.minimum(a[m], p[m]) / norm * beck
        pos = (kap - kappa[0]) / dk
        i0 = np.clip(np.floor(pos).astype(np.int64), 0, n_kappa - 2)
        t = np.clip(pos - i0, 0.0, 1.0)
        G[j] += np.bincount(i0, mass * (1 - t), minlength=n_kappa)
        G[j] += np.bincount(i0 + 1, mass * t, minlength=n_kappa)
    return u, kappa, G


@lru_cache(maxsize=32)
def acceptance_table(na: float, na_ill: float, obscuration: float = 0.0, *, n_alpha: int = 2049,
                     n_grid: int = 112) -> tuple[np.ndarray, np.ndarray]:
    """Fraction of the illumination that a tilted mirror facet reflects into the pupil.

    Geometric optics (specular reflection of each illumination direction about the
    facet normal); the intensity of the image of a tilted mirror is this fraction.

    Returns
    -------
    alpha : (n_alpha,) float64, facet tilt 0 .. pi/2, rad
    fraction : (n_alpha,) float64, 0..1

    Kept on disk between processes (:mod:`._table_cache`).
    """
    args = {"na": float(na), "na_ill": float(na_ill), "obscuration": float(obscuration),
            "n_alpha": int(n_alpha), "n_grid": int(n_grid)}
    t = cached_arrays("acceptance_table", args, __file__,
                      lambda: dict(zip(("alpha", "fraction"), _acceptance_table(**args))))
    return t["alpha"], t["fraction"]


def _acceptance_table(*, na, na_ill, obscuration, n_alpha, n_grid):
    obs_na = obscuration * na
    pts, a, norm, c = _illumination_points(float(na_ill), float(obs_na), int(n_grid))
    if c == 0.0:
        c = 1e-6
    ci = np.sqrt(np.maximum(1.0 - np.sum(pts ** 2, axis=1), 0.0))
    d = np.stack([pts[:, 0], pts[:, 1], -ci], axis=1)  # incident directions (down)
    alpha = np.linspace(0.0, math.pi / 2, n_alpha)
    frac = np.zeros(n_alpha)
    amin = np.minimum  # the cell area also inside the pupil (see unit_transfer_table)
    for j0 in range(0, n_alpha, 64):
        tilt = alpha[j0:j0 + 64, None]
        nx, nz = np.sin(tilt), np.cos(tilt)
        dn = d[None, :, 0] * nx + d[None, :, 2] * nz
        ox = d[None, :, 0] - 2.0 * dn * nx
        oz = d[None, :, 2] - 2.0 * dn * nz
        ro = np.hypot(ox, d[None, :, 1])
        p = np.clip((na - ro) / c + 0.5, 0.0, 1.0)  # soft pupil edge as in the table
        if obs_na > 0:
            p *= np.clip((ro - obs_na) / c + 0.5, 0.0, 1.0)
        ok = (dn < 0) & (oz > 0)
        frac[j0:j0 + 64] = np.sum(np.where(ok, amin(a[None, :], p), 0.0), axis=1) / norm
    return alpha, frac


def flat_moments(na: float, na_ill: float, obscuration: float, k: np.ndarray,
                 weight: np.ndarray) -> tuple[float, float]:
    """Mean and rms width of the axial frequency ``K`` for a flat mirror (``Q = 0``).

    Returns
    -------
    k_eff : float, rad/mm
        ``sum K H(0, K) / sum H(0, K)``: the fringe wavenumber (``lambda_eff = 4 pi / k_eff``).
    sigma_k : float, rad/mm
        Rms width of ``K`` (sets the coherence envelope of the signal).
    """
    _, kappa, G = unit_transfer_table(float(na), float(na_ill), float(obscuration))
    g0 = G[0]
    if g0.sum() <= 0:
        raise InputError("no light returns from a flat mirror: check numerical_aperture, "
                         "illumination_na and central_obscuration")
    m1 = float(np.sum(kappa * g0) / g0.sum())
    m2 = float(np.sum(kappa ** 2 * g0) / g0.sum())
    k1 = float(np.sum(k * weight))
    k2 = float(np.sum(k ** 2 * weight))
    k_eff = k1 * m1
    var = max(k2 * m2 - k_eff ** 2, 0.0)
    return k_eff, math.sqrt(var)


def axial_step(sigma_k: float, zeta_range: float, *, tolerance: float = 0.5) -> float:
    """Axial bin spacing ``dK`` (rad/mm) for frames that need ``|z - h| <= zeta_range``.

    Where the signal is strong (``|zeta| <= 2.5 / sigma_k``, envelope above 4 % of its
    peak for a Gaussian spectrum; all of ``zeta_range`` for a narrow band) the
    interpolation error ``(dK zeta)^2 / 8`` stays below ``tolerance^2 / 8``; the signal's
    period in ``zeta``, ``2 pi / dK``, exceeds ``zeta_range`` plus the whole envelope
    (``4.5 / sigma_k``), so no copy of an envelope appears inside the scan.
    """
    zr = max(float(zeta_range), 1e-7)
    env = 4.5 / sigma_k if sigma_k > 0 else math.inf
    if env >= zr:
        return tolerance / zr
    return min(tolerance / (2.5 / sigma_k), 2 * math.pi / (zr + env))


@dataclass(frozen=True)
class TransferFunction:
    """Tabulated ``H(Q, K)``.

    Attributes
    ----------
    K : (nb,) float64
        Axial bin centres, rad/mm (spacing ``dK``).
    table : (nb, nq) float32
        ``H[b, m]`` at ``|Q| = m dq``; zero beyond ``q_max``.
    dq : float, rad/mm
    q_max : float, rad/mm
        Largest ``|Q|`` passed: ``k_max (NA + NA_ill)``.
    k_eff, sigma_k : float, rad/mm
        Flat-mirror mean and rms width of ``K`` (:func:`flat_moments`).
    dK : float, rad/mm
    support : (nb,) float64
        Largest ``|Q|`` with a non-zero value in each bin, rad/mm.
    """

    K: np.ndarray
    table: np.ndarray
    dq: float
    q_max: float
    k_eff: float
    sigma_k: float
    dK: float
    support: np.ndarray

    @property
    def effective_wavelength_nm(self) -> float:
        return 4 * math.pi / self.k_eff * MM_TO_NM


def transfer_function(na: float, na_ill: float, obscuration: float, source: _sources.Source, *, dK: float,
                      n_q: int = _N_Q) -> TransferFunction:
    """Tabulate the transfer function on axial bins of spacing ``dK``.

    Parameters
    ----------
    na, na_ill, obscuration : float
        See :func:`unit_transfer_table`.
    source : Source
        The light source (its spectrum is sampled at ``dK / 4``).
    dK : float
        Axial bin spacing, rad/mm (:func:`axial_step`).

    Returns
    -------
    TransferFunction

    Kept on disk between processes (:mod:`._table_cache`).
    """
    args = {"na": float(na), "na_ill": float(na_ill), "obscuration": float(obscuration),
            "source": {"kind": source.kind, "wavelength_nm": float(source.wavelength_nm),
                       "bandwidth_nm": float(source.bandwidth_nm),
                       "table_nm": [float(v) for v in source.table_nm],
                       "table_weight": [float(v) for v in source.table_weight]},
            "dK": float(dK), "n_q": int(n_q)}
    t = cached_arrays("transfer_function", args, (__file__, _sources.__file__),
                      lambda: _transfer_arrays(na, na_ill, obscuration, source, dK=dK, n_q=n_q))
    return TransferFunction(K=t["K"], table=t["table"], dq=float(t["dq"]),
                            q_max=float(t["q_max"]), k_eff=float(t["k_eff"]),
                            sigma_k=float(t["sigma_k"]), dK=float(t["dK"]),
                            support=t["support"])


def _transfer_arrays(na, na_ill, obscuration, source, *, dK, n_q) -> dict:
    u, kappa, G = unit_transfer_table(float(na), float(na_ill), float(obscuration))
    k, w = source.sample(dk=dK / 4)
    k_eff, sigma_k = flat_moments(na, na_ill, obscuration, k, w)
    K_lo = float(k.min() * kappa[0])
    K_hi = float(k.max() * kappa[-1])
    nb = math.ceil((K_hi - K_lo) / dK) + 2
    if nb > MAX_AXIAL_BINS:
        raise MemoryBudgetError(f"the transfer function needs {nb} axial bins (> {MAX_AXIAL_BINS}): "
                                f"the heights and scan span too many fringes for the source's "
                                f"coherence; shorten the scan or the height range")
    K = K_lo + dK * np.arange(nb)
    q_max = float(k.max() * (na + na_ill))
    dq = q_max / (n_q - 1) if q_max > 0 else 1.0
    q = dq * np.arange(n_q)
    du = u[1] - u[0]
    table = np.zeros((nb, n_q))
    cols = np.arange(kappa.size)
    # G interpolated along u for each |Q| (rows), in buffers reused for every wavelength:
    # the same products and sum as the array expression, without its fresh temporaries
    gu = np.empty((n_q, kappa.size))
    lo_part = np.empty((n_q, kappa.size))
    for kj, wj in zip(k, w):
        pos_u = q / kj / du
        i0 = np.floor(pos_u).astype(np.int64)
        inside = i0 < u.size - 1
        f = (pos_u - i0)[inside]
        m = int(np.count_nonzero(inside))  # q rises: the rows inside come first
        i_in = i0[:m]
        np.take(G, i_in, axis=0, out=lo_part[:m])
        np.multiply(lo_part[:m], (1 - f)[:, None], out=lo_part[:m])
        np.take(G, i_in + 1, axis=0, out=gu[:m])
        np.multiply(gu[:m], f[:, None], out=gu[:m])
        np.add(lo_part[:m], gu[:m], out=gu[:m])
        gu[m:] = 0.0
        pos_k = (kj * kappa - K_lo) / dK
        b0 = np.clip(np.floor(pos_k).astype(np.int64), 0, nb - 2)
        t = np.clip(pos_k - b0, 0.0, 1.0)
        dep = np.zeros((nb, kappa.size))
        np.add.at(dep, (b0, cols), 1 - t)
        np.add.at(dep, (b0 + 1, cols), t)
        table += wj * (dep @ gu.T)
    nz = table > 1e-12 * max(table.max(), 1e-300)  # not a unit conversion: a relative floor
    support = np.where(nz.any(axis=1), q[np.where(nz, np.arange(n_q)[None, :], 0).max(axis=1)], -1.0)
    table[~nz] = 0.0
    return {"K": K, "table": table.astype(np.float32), "dq": np.float64(dq),
            "q_max": np.float64(q_max), "k_eff": np.float64(k_eff),
            "sigma_k": np.float64(sigma_k), "dK": np.float64(dK), "support": support}


def linear_itf(na: float, na_ill: float, obscuration: float, source: _sources.Source,
               frequency: ArrayLike) -> np.ndarray:
    """Instrument transfer function of the linear (small-height) regime.

    A height sinusoid of small amplitude ``a`` (``K a << 1``) at spatial frequency ``f``
    is measured, through the effective wavelength, with amplitude ``ITF(f) a``::

        ITF(f) = sum_K K H(2 pi f, K) / sum_K K H(0, K)

    (the pixel's own box filter not included).

    Parameters
    ----------
    na, na_ill, obscuration : float
    source : Source
    frequency : array
        Spatial frequencies, cycles/mm.

    Returns
    -------
    array of the shape of ``frequency``
    """
    q, curve = _itf_curve(float(na), float(na_ill), float(obscuration), source)
    f = np.asarray(frequency, dtype=np.float64)
    return np.interp(2 * math.pi * np.abs(f), q, curve, right=0.0)


@lru_cache(maxsize=16)
def _itf_curve(na, na_ill, obscuration, source):
    # the axial binning (a linear deposit) keeps sum K H exactly, so a few wide bins do
    k_lo, k_hi = source.wavenumber_range()
    dK = (max(2.0 * (k_hi - k_lo), 2.0 * k_hi * (1 - math.sqrt(1 - na * na))) / 4
          + 1e-9 * k_hi)  # not a unit conversion: a relative margin
    tf = transfer_function(na, na_ill, obscuration, source, dK=dK)
    num = np.sum(tf.K[:, None] * tf.table.astype(np.float64), axis=0)
    return tf.dq * np.arange(num.size), num / num[0]
