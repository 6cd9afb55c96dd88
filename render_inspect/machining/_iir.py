"""The lathe's digital filters: a second-order low-pass designed by the bilinear transform
and run as second-order sections.

These are SciPy's ``scipy.signal`` functions the machine model uses (``butter`` of order 2
as sections, ``bilinear_zpk``, ``zpk2sos``, ``sosfilt``), restricted to what the model
asks of them and computed with the same operations in the same order, so that their
numbers are SciPy's to the last bit (tests/test_iir.py compares them over many random
filters and signals).  Importing ``scipy.signal`` costs a command 0.4-0.5 s of start-up
(it imports ``scipy.stats``); this module costs nothing until a filter runs, and the
filter itself is one compiled loop (numba).

The design follows SciPy's code (BSD-3-Clause licence, Copyright the SciPy Developers):
``scipy/signal/_filter_design.py`` (``buttap``, ``lp2lp_zpk``, ``bilinear_zpk``,
``_cplxreal``, ``zpk2sos`` with its ``"nearest"`` pairing, ``zpk2tf``) and the section
loop of ``scipy/signal/_sosfilt.pyx``.
"""

from __future__ import annotations

import numpy as np

from ..core.lazy import njit  # numba, imported on first use

__all__ = ["butter2_sos", "bilinear_sos", "sosfilt"]


def _cplxreal(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(one of each complex-conjugate pair, the real values) of ``z``: SciPy's
    ``_cplxreal`` with its default tolerance."""
    z = np.atleast_1d(z)
    if z.size == 0:
        return z, z
    tol = 100 * np.finfo((1.0 * z).dtype).eps
    z = z[np.lexsort((abs(z.imag), z.real))]
    real_indices = abs(z.imag) <= tol * abs(z)
    zr = z[real_indices].real
    if len(zr) == len(z):
        return np.array([]), zr
    z = z[~real_indices]
    zp = z[z.imag > 0]
    zn = z[z.imag < 0]
    if len(zp) != len(zn):
        raise ValueError("a complex pole or zero has no matching conjugate")
    same_real = np.diff(zp.real) <= tol * abs(zp[:-1])
    diffs = np.diff(np.concatenate(([0], same_real, [0])))
    run_starts = np.nonzero(diffs > 0)[0]
    run_stops = np.nonzero(diffs < 0)[0]
    for i in range(len(run_starts)):
        start = run_starts[i]
        stop = run_stops[i] + 1
        for chunk in (zp[start:stop], zn[start:stop]):
            chunk[...] = chunk[np.lexsort([abs(chunk.imag)])]
    if any(abs(zp - zn.conj()) > tol * abs(zn)):
        raise ValueError("a complex pole or zero has no matching conjugate")
    return (zp + zn.conj()) / 2, zr


def _real_if_paired(coef: np.ndarray, roots: object) -> np.ndarray:
    """``coef`` made real when its ``roots`` come in complex-conjugate pairs."""
    if issubclass(coef.dtype.type, np.complexfloating):
        r = np.asarray(roots, complex)
        pos = np.compress(r.imag > 0, r)
        neg = np.conjugate(np.compress(r.imag < 0, r))
        if len(pos) == len(neg) and np.all(np.sort_complex(neg) == np.sort_complex(pos)):
            return coef.real.copy()
    return coef


def _tf(z: list, p: list) -> tuple[np.ndarray, np.ndarray]:
    """Numerator and denominator of the unit-gain section with zeros ``z`` and poles
    ``p`` (SciPy's ``zpk2tf`` with k = 1; real where the roots come in pairs)."""
    zz = np.atleast_1d(z)
    b = np.atleast_1d(1) * np.poly(zz)
    a = np.atleast_1d(np.poly(p))
    return _real_if_paired(b, zz), _real_if_paired(a, p)


def _nearest(fro: np.ndarray, to: complex, which: str) -> int:
    """Index of the element of ``fro`` nearest ``to`` (among the real or complex ones)."""
    order = np.argsort(np.abs(fro - to))
    if which == "any":
        return int(order[0])
    mask = np.isreal(fro[order])
    if which == "complex":
        mask = ~mask
    return int(order[np.nonzero(mask)[0][0]])


def _section(z: list, p: list) -> np.ndarray:
    sos = np.zeros(6)
    b, a = _tf(z, p)
    sos[3 - len(b):3] = b
    sos[6 - len(a):6] = a
    return sos


def _two_pole_sos(z: np.ndarray, p: np.ndarray, k: float) -> np.ndarray:
    """SciPy's ``zpk2sos(z, p, k)`` (digital, ``"nearest"`` pairing) of two poles and two
    zeros: one section, (1, 6)."""
    if len(z) != 2 or len(p) != 2:
        raise ValueError("two poles and two zeros are expected")
    z = np.concatenate(_cplxreal(z))
    p = np.concatenate(_cplxreal(p))
    if not np.isreal(k):
        raise ValueError("the gain must be real")
    k = k.real
    sos = np.zeros((1, 6))

    def worst(q: np.ndarray) -> int:
        return int(np.argmin(np.abs(1 - np.abs(q))))

    p1_idx = worst(p)
    p1 = p[p1_idx]
    p = np.delete(p, p1_idx)
    if np.isreal(p1) and np.isreal(p).sum() == 0:  # (cannot happen with two poles)
        raise ValueError("a real pole without a real partner")
    if np.isreal(p1):
        prealidx = np.flatnonzero(np.isreal(p))
        p2_idx = prealidx[worst(p[prealidx])]
        p2 = p[p2_idx]
        p = np.delete(p, p2_idx)
    else:
        p2 = p1.conj()
    z1_idx = _nearest(z, p1, "any")
    z1 = z[z1_idx]
    z = np.delete(z, z1_idx)
    if not np.isreal(z1):
        sos[0] = _section([z1, z1.conj()], [p1, p2])
    else:
        z2_idx = _nearest(z, p1, "real")
        z2 = z[z2_idx]
        z = np.delete(z, z2_idx)
        sos[0] = _section([z1, z2], [p1, p2])
    sos[0][:3] *= k
    return sos


def _bilinear(p: np.ndarray, k: float, fs: float) -> tuple[np.ndarray, np.ndarray, float]:
    """SciPy's ``bilinear_zpk`` of an all-pole analog filter (poles ``p``, gain ``k``)
    at the sampling rate ``fs``: (zeros, poles, gain) of the digital filter."""
    z = np.atleast_1d(np.array([]))
    p = np.atleast_1d(p)
    fs = float(fs)
    degree = len(p) - len(z)
    fs2 = 2.0 * fs
    z_z = (fs2 + z) / (fs2 - z)
    p_z = (fs2 + p) / (fs2 - p)
    z_z = np.append(z_z, -np.ones(degree))
    k_z = k * np.real(np.prod(fs2 - z) / np.prod(fs2 - p))
    return z_z, p_z, k_z


def butter2_sos(wc: float) -> np.ndarray:
    """``scipy.signal.butter(2, wc, output="sos")``: the second-order Butterworth
    low-pass of cut-off ``wc`` (a fraction of the Nyquist frequency, 0 < wc < 1) as one
    second-order section, (1, 6)."""
    wn = np.asarray(wc)
    if np.any(wn <= 0) or np.any(wn >= 1) or wn.size != 1:
        raise ValueError(f"the cut-off must be in (0, 1) of the Nyquist frequency, received {wc!r}")
    n = 2
    m = np.arange(-n + 1, n, 2)
    p = -np.exp(1j * np.pi * m / (2 * n))       # the analog prototype's poles, gain 1
    fs = 2.0
    warped = 2 * fs * np.tan(np.pi * wn / fs)
    wo = float(warped)
    p_lp = wo * p
    k_lp = 1 * wo ** 2
    z_z, p_z, k_z = _bilinear(p_lp, k_lp, fs)
    return _two_pole_sos(z_z, p_z, k_z)


def bilinear_sos(poles: np.ndarray, gain: float, fs: float) -> np.ndarray:
    """``scipy.signal.zpk2sos(*bilinear_zpk([], poles, gain, fs))`` with a real gain,
    for two analog ``poles``: the digital section, (1, 6)."""
    z, p, k = _bilinear(np.asarray(poles), gain, fs)
    return _two_pole_sos(z, p, np.real(k))


@njit(cache=True, nogil=True)
def _sosfilt_kernel(sos, x):  # pragma: no cover - numba
    n_sections = sos.shape[0]
    zi = np.zeros((n_sections, 2))
    for n in range(x.size):
        x_cur = x[n]
        for s in range(n_sections):
            x_new = sos[s, 0] * x_cur + zi[s, 0]
            zi[s, 0] = sos[s, 1] * x_cur - sos[s, 4] * x_new + zi[s, 1]
            zi[s, 1] = sos[s, 2] * x_cur - sos[s, 5] * x_new
            x_cur = x_new
        x[n] = x_cur


def sosfilt(sos: np.ndarray, x: np.ndarray, *, overwrite_x: bool = False) -> np.ndarray:
    """``scipy.signal.sosfilt(sos, x)`` of a 1-D real signal from rest: the filtered
    copy of ``x`` (float64).  ``overwrite_x``: filter ``x`` itself when it is a
    contiguous float64 array (returned), a copy otherwise."""
    sos = np.ascontiguousarray(np.atleast_2d(sos), dtype=np.float64)
    if sos.ndim != 2 or sos.shape[1] != 6 or not (sos[:, 3] == 1).all():
        raise ValueError("second-order sections are (n, 6) with sos[:, 3] == 1")
    y = np.asarray(x, dtype=np.float64, order="C") if overwrite_x else \
        np.array(x, dtype=np.float64, order="C")
    if y.ndim != 1:
        raise ValueError("a 1-D signal is expected")
    if y.size:
        _sosfilt_kernel(sos, y)
    return y

