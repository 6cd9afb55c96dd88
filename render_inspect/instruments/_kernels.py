"""Compiled inner loops of the imaging model and the camera (numba, built on first use)."""

from __future__ import annotations

import numpy as np

from ..core.lazy import njit, prange  # numba, imported on first use

__all__ = ["adc_frame", "electrons", "filter_fold", "frames_from_field"]

_KERNEL = None


def _build():
    import math

    import numba

    @numba.njit(parallel=True, cache=True)
    def kernel(spec, row_ok, qy2, sepy, cols, ccols, qx2, sepx, table, inv_dq, s_fold, out):
        hc, wc = out.shape
        nq = table.shape[0]
        for rc in numba.prange(hc):
            for c in range(wc):
                out[rc, c] = 0
            for k in range(s_fold):
                r = rc + k * hc
                if not row_ok[r]:
                    continue
                sy = sepy[r]
                y2 = qy2[r]
                for j in range(cols.shape[0]):
                    c = cols[j]
                    i = int(math.sqrt(y2 + qx2[c]) * inv_dq + 0.5)
                    if i >= nq:
                        continue
                    t = table[i]
                    if t == 0.0:
                        continue
                    out[rc, ccols[j]] += spec[r, c] * (sy * sepx[c] * t)
        return out

    return kernel


def filter_fold(spec, row_ok, qy2, sepy, cols, ccols, qx2, sepx, table, inv_dq, s_fold, out):
    """Multiply a fine-grid spectrum by the transfer function of one axial bin and by the
    pixel-box/centring factors, and fold it onto the camera grid.

    Parameters
    ----------
    spec : (Hs, Ws) complex64
        FFT of the sub-sampled field.
    row_ok : (Hs,) bool
        Rows inside the bin's support.
    qy2, qx2 : (Hs,), (Ws,) float32
        Squared frequencies, (rad/mm)^2.
    sepy, sepx : (Hs,), (Ws,) complex64
        Separable pixel-box and centring factors.
    cols, ccols : (nc,) int64
        Fine columns inside the bin's support and their folded (camera) columns.
    table : (nq,) float32
        ``H[b, m]`` at ``|Q| = m / inv_dq``.
    s_fold : int
        Sub-samples per pixel (fine rows folding onto one camera row).
    out : (H, W) complex64
        Camera-grid spectrum (overwritten).
    """
    global _KERNEL
    if _KERNEL is None:
        _KERNEL = _build()
    return _KERNEL(spec, row_ok, qy2, sepy, cols, ccols, qx2, sepx, table, inv_dq, s_fold, out)


# ------------------------------------------------------------ frames from the field
@njit(parallel=True, cache=True)
def _frames_kernel(x, light, rho_r, two_sr, out):
    nfr, m = x.shape
    for p in prange(m):
        v = x[0, p]
        mag = v.real * v.real + v.imag * v.imag
        for f in range(1, nfr):
            v = x[f, p]
            a = v.real * v.real + v.imag * v.imag
            if a > mag or a != a:  # (np.max: a NaN wins)
                mag = a
        lp = light[p]
        if lp != lp or mag != mag:  # (np.maximum: a NaN wins)
            bg = lp + mag
        else:
            bg = lp if lp >= mag else mag
        bg = bg + rho_r
        for f in range(nfr):
            o = bg + two_sr * x[f, p].real
            out[f, p] = o if (o >= 0 or o != o) else np.float32(0.0)


def frames_from_field(x, light, rho_r, two_sr, out):
    """The frames' intensities from the interference term of a block of pixels:
    ``out[f] = max(light, max_f |x_f|^2) + rho_r + two_sr Re x_f``, floored at 0, in
    float32 with the operations (and their rounding) of the array expressions
    ``np.maximum(light, np.max(x.real**2 + x.imag**2, axis=0)) + rho_r + two_sr * x.real``
    then ``np.maximum(out, 0)``, in one pass threaded over the pixels.

    Parameters
    ----------
    x : (N, M) complex64
    light : (M,) float32
    rho_r, two_sr : float32
    out : (N, M) float32 (written)
    """
    _frames_kernel(x, light, np.float32(rho_r), np.float32(two_sr), out)
    return out


# -------------------------------------------------------------------- camera frames
@njit(parallel=True, cache=True)
def _electrons_kernel(inten, scale, e, low_below):
    h, w = e.shape
    low = 0
    for r in prange(h):
        n = 0
        for c in range(w):
            v = inten[r, c] * scale[r, c]
            if v < 0:
                v = np.float32(0.0)
            e[r, c] = v
            if v < low_below:
                n += 1
        low += n
    return low


@njit(parallel=True, cache=True)
def _adc_kernel(e, z, read2, offset, full_well, e_per_adu, levels, sat, out):
    h, w = e.shape
    for r in prange(h):
        for c in range(w):
            ev = e[r, c]
            v = ev + z[r, c] * np.sqrt(ev + read2)
            v = v + offset[r, c]
            if v >= full_well:
                sat[r, c] = True
            if v < 0:
                v = np.float32(0.0)
            elif v > full_well:
                v = full_well
            out[r, c] = np.rint(v / e_per_adu) / levels


def electrons(inten, scale, e, low_below):
    """``e = max(inten * scale, 0)`` (float32, in place) and the number of pixels below
    ``low_below`` electrons, in one pass threaded over rows."""
    return int(_electrons_kernel(inten, scale, e, np.float32(low_below)))


def adc_frame(e, z, read_noise_e, offset, full_well, e_per_adu, levels, sat, out):
    """One noisy frame where every count is in the Gaussian limit: the electrons ``e`` plus
    the deviates ``z`` times ``sqrt(e + read_noise_e^2)``, the fixed offset, the full well
    (``sat`` set where reached; clipped), quantised: the float32 operations of the array
    expressions in :func:`~._camera.expose`, threaded over rows."""
    # (float32 ** 2 is a float64 scalar: squared as numpy does, then float32 as the
    # array expression's operand)
    read2 = np.float32(np.float32(read_noise_e) ** 2)
    _adc_kernel(e, z, read2, offset, np.float32(full_well),
                np.float32(e_per_adu), np.float32(levels), sat, out)
    return out
