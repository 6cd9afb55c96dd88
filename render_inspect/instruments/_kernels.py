"""Compiled inner loop of the imaging model (numba, built on first use)."""

from __future__ import annotations

__all__ = ["filter_fold"]

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
