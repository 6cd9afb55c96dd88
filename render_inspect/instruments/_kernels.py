"""Compiled inner loops of the imaging model (numba, built on first use).

Each loop over rows is a serial kernel that releases the GIL, given a first and an end
row, run on threads by :func:`~render_inspect.core.threads.over_rows` (compiled in a
fraction of the time numba's ``parallel=True`` takes, with the same numbers)."""

from __future__ import annotations

import math

import numpy as np

from ..core.lazy import load_numba, njit  # numba, imported on first use
from ..core.threads import over_rows
from ..core.smoothing import gaussian_weights

__all__ = ["facets", "filter_fold", "frames_from_field", "gaussian_weights", "heights_about",
           "pixel_means", "preload", "radial_index", "smoothed_cosine", "steps_over"]

_KERNEL = None


def _build():
    import math

    numba = load_numba()

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


@njit(cache=True, nogil=True)
def _radial_index_kernel(qy2, qx2, inv_dq, nq, out, r0, r1):
    for r in range(r0, r1):
        y2 = qy2[r]
        for c in range(qx2.shape[0]):
            i = int(math.sqrt(y2 + qx2[c]) * inv_dq + 0.5)
            out[r, c] = i if i < nq else nq


@njit(cache=True, nogil=True)
def _filter_fold_indexed(spec, row_ok, index, sepy, cols, ccols, sepx, table, s_fold, out, r0, r1):
    hc, wc = out.shape
    nq = table.shape[0]
    for rc in range(r0, r1):
        for c in range(wc):
            out[rc, c] = 0
        for k in range(s_fold):
            r = rc + k * hc
            if not row_ok[r]:
                continue
            sy = sepy[r]
            for j in range(cols.shape[0]):
                c = cols[j]
                i = index[r, c]
                if i >= nq:
                    continue
                t = table[i]
                if t == 0.0:
                    continue
                out[rc, ccols[j]] += spec[r, c] * (sy * sepx[c] * t)


def radial_index(qy2: np.ndarray, qx2: np.ndarray, inv_dq: float | np.floating,
                 nq: int) -> np.ndarray:
    """The transfer function's radial sample of every fine frequency, ``round(|Q| inv_dq)``
    (at most ``nq``: beyond the table), computed as :func:`filter_fold` computes it, once
    for all axial bins (int16, or int32 for tables longer than int16 holds)."""
    out = np.empty((qy2.shape[0], qx2.shape[0]), dtype=np.int16 if nq < 32767 else np.int32)
    over_rows(_radial_index_kernel, qy2.shape[0], qy2, qx2, np.float32(inv_dq), int(nq), out)
    return out


def filter_fold(spec: np.ndarray, row_ok: np.ndarray, qy2: np.ndarray, sepy: np.ndarray,
                cols: np.ndarray, ccols: np.ndarray, qx2: np.ndarray, sepx: np.ndarray,
                table: np.ndarray, inv_dq: float | np.floating, s_fold: int, out: np.ndarray,
                index: np.ndarray | None = None) -> np.ndarray:
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
    index : (Hs, Ws) int array, optional
        :func:`radial_index` of ``qy2``, ``qx2``, ``inv_dq`` and the table's length: the
        same result without the square root of every frequency in every bin.
    """
    if index is not None:
        over_rows(_filter_fold_indexed, out.shape[0], spec, row_ok, index, sepy, cols, ccols, sepx,
                  table, s_fold, out)
        return out
    global _KERNEL
    if _KERNEL is None:
        _KERNEL = _build()
    return _KERNEL(spec, row_ok, qy2, sepy, cols, ccols, qx2, sepx, table, inv_dq, s_fold, out)


# ------------------------------------------------------------ frames from the field
@njit(cache=True, nogil=True)
def _frames_kernel(x, light, rho_r, two_sr, out, p0, p1):
    nfr, m = x.shape
    for p in range(p0, p1):
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


def frames_from_field(x: np.ndarray, light: np.ndarray, rho_r: float | np.floating,
                      two_sr: float | np.floating, out: np.ndarray) -> np.ndarray:
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
    over_rows(_frames_kernel, x.shape[1], x, light, np.float32(rho_r), np.float32(two_sr), out)
    return out


# ------------------------------------------- the facets' cosine after the PSF smoothing
@njit(cache=True, nogil=True)
def _wrap_axis0(u, w, out, i0, i1):
    ny, nx = u.shape
    r = (w.size - 1) // 2
    w0 = w[r]
    for i in range(i0, i1):
        acc = np.empty(nx)
        ui = u[i]
        for q in range(nx):
            acc[q] = np.float64(ui[q]) * w0
        for jj in range(-r, 0):
            a = u[(i + jj) % ny]
            b = u[(i - jj) % ny]
            wj = w[r + jj]
            for q in range(nx):
                acc[q] = acc[q] + (np.float64(a[q]) + np.float64(b[q])) * wj
        for q in range(nx):
            out[i, q] = np.float32(acc[q])


@njit(cache=True, nogil=True)
def _wrap_axis1_cosine(u0, u1, u2, w, out, i0, i1):
    ny, nx = u0.shape
    r = (w.size - 1) // 2
    w0 = w[r]
    for i in range(i0, i1):
        pad = np.empty(nx + 2 * r)
        acc = np.empty(nx)
        sm = np.empty((3, nx), dtype=np.float32)
        for k in range(3):
            ui = u0[i] if k == 0 else (u1[i] if k == 1 else u2[i])
            for q in range(nx + 2 * r):
                pad[q] = np.float64(ui[(q - r) % nx])
            for q in range(nx):
                acc[q] = pad[q + r] * w0
            for jj in range(-r, 0):
                wj = w[r + jj]
                for q in range(nx):
                    acc[q] = acc[q] + (pad[q + r + jj] + pad[q + r - jj]) * wj
            for q in range(nx):
                sm[k, q] = np.float32(acc[q])
        tiny = np.float32(1e-12)
        for q in range(nx):
            a, b, c = sm[0, q], sm[1, q], sm[2, q]
            n = np.float32(math.sqrt(a * a + b * b + c * c))
            out[i, q] = c / (n if n >= tiny else tiny)


def smoothed_cosine(u0: np.ndarray, u1: np.ndarray, u2: np.ndarray,
                    sigma: float, *, overwrite: bool = False) -> np.ndarray | None:
    """The cosine of the smoothed facets' tilt: the three components of the unit normal
    (float32, 0 where no light returns) each smoothed by SciPy's
    ``gaussian_filter(u, sigma, mode="wrap")`` (axis 0, then axis 1, each pass rounded to
    float32), then ``u2 / max(sqrt(u0^2 + u1^2 + u2^2), 1e-12)`` in float32: the same
    numbers, to the last bit, as those array expressions, in two compiled passes threaded
    over rows.  Returns None where the weights are not symmetric or the filter is longer
    than the field (the caller then uses SciPy).  ``overwrite``: the components' own
    arrays (three distinct C-ordered float32 arrays) may hold the passes' intermediate
    results and the cosine (the same numbers, two fewer arrays of the field's size); they
    are left as they were when None is returned."""
    w = gaussian_weights(sigma)
    r = (w.size - 1) // 2
    ny, nx = u0.shape
    if r >= min(ny, nx) or not np.all(np.abs(w - w[::-1]) <= np.finfo(float).eps):
        return None
    if overwrite and _distinct_float32(u0, u1, u2):
        # each component is read once, by the first pass, and its array then takes the
        # next component's pass (the first into a fresh array), the last one the cosine
        t0 = np.empty((ny, nx), dtype=np.float32)
        over_rows(_wrap_axis0, ny, u0, w, t0)
        over_rows(_wrap_axis0, ny, u1, w, u0)
        over_rows(_wrap_axis0, ny, u2, w, u1)
        over_rows(_wrap_axis1_cosine, ny, t0, u0, u1, w, u2)
        return u2
    t0, t1, t2 = (np.empty((ny, nx), dtype=np.float32) for _ in range(3))
    for u, t in ((u0, t0), (u1, t1), (u2, t2)):
        over_rows(_wrap_axis0, ny, np.ascontiguousarray(u, dtype=np.float32), w, t)
    out = np.empty((ny, nx), dtype=np.float32)
    over_rows(_wrap_axis1_cosine, ny, t0, t1, t2, w, out)
    return out


def _distinct_float32(*arrays: np.ndarray) -> bool:
    """Whether the arrays are C-ordered float32 arrays of one shape, writeable, sharing no
    memory."""
    if not all(isinstance(a, np.ndarray) and a.dtype == np.float32 and a.flags.c_contiguous
               and a.flags.writeable and a.shape == arrays[0].shape for a in arrays):
        return False
    return not any(np.shares_memory(a, b) for i, a in enumerate(arrays) for b in arrays[i + 1:])


# ------------------------------------------------------------- the facets' orientation
@njit(cache=True, nogil=True, error_model="numpy")
def _facets_kernel(nrm, h, cos_t, fin, reached, u0, u1, u2, i0, i1):
    ny, nx = h.shape
    zero = np.float32(0.0)
    for i in range(i0, i1):
        for j in range(nx):
            a = nrm[i, j, 0]
            b = nrm[i, j, 1]
            c = nrm[i, j, 2]
            nn = np.float32(math.sqrt(a * a + b * b + c * c))
            ct = c / nn
            f = math.isfinite(h[i, j])
            r = f and ct > 0
            cos_t[i, j] = ct
            fin[i, j] = f
            reached[i, j] = r
            u0[i, j] = a / nn if r else zero
            u1[i, j] = b / nn if r else zero
            u2[i, j] = c / nn if r else zero


def facets(nrm: np.ndarray, h: np.ndarray
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[np.ndarray]]:
    """The facets' orientation from the traced normals (float32, any length) and heights
    (float64, NaN: no surface), in one compiled pass threaded over rows, the same numbers
    as the float32 array expressions ``nn = sqrt(n_x^2 + n_y^2 + n_z^2)``,
    ``cos_t = n_z / nn``, ``reached = isfinite(h) & (cos_t > 0)`` and the unit normal
    ``n / nn`` where reached (0 elsewhere).

    Returns
    -------
    cos_t : (H, W) float32
    fin, reached : (H, W) bool
    unit : list of three (H, W) float32
    """
    nrm = np.ascontiguousarray(nrm, dtype=np.float32)
    h = np.ascontiguousarray(h, dtype=np.float64)
    shape = h.shape
    cos_t = np.empty(shape, dtype=np.float32)
    fin = np.empty(shape, dtype=bool)
    reached = np.empty(shape, dtype=bool)
    unit = [np.empty(shape, dtype=np.float32) for _ in range(3)]
    over_rows(_facets_kernel, shape[0], nrm, h, cos_t, fin, reached, *unit)
    return cos_t, fin, reached, unit


# ------------------------------------------------------------- the truth's pixel means
#: Most sub-samples per pixel side whose means :func:`pixel_means` computes (NumPy sums
#: the rows of longer pixels pairwise, in eight partial sums).
PIXEL_MEANS_MAX_S = 7


@njit(cache=True, nogil=True, error_model="numpy")
def _pixel_means_kernel(h, s, m, out, i0, i1):
    ny, nx = out.shape
    for i in range(i0, i1):
        for j in range(nx):
            tot = 0.0
            cnt = 0
            for a in range(s):
                row = 0.0
                for b in range(s):
                    v = h[m + i * s + a, m + j * s + b]
                    if v != v:
                        v = 0.0
                    else:
                        cnt += 1
                    row = row + v
                tot = tot + row
            out[i, j] = tot / cnt  # (no sample: 0 / 0, NaN)


def pixel_means(h_sub: np.ndarray, s: int, margin: int,
                shape: tuple[int, int]) -> np.ndarray | None:
    """The mean of each camera pixel's ``s x s`` sub-samples of ``h_sub`` (float64, NaN:
    none; the pixels start ``margin`` sub-samples in), NaN where none has a value: the
    numbers of ``nanmean`` of the ``(ny, s, nx, s)`` blocks over axes 1 and 3 as NumPy
    sums them (each row of a pixel in order, then the rows in order), in one compiled
    pass threaded over rows.  Returns None for ``s`` above :data:`PIXEL_MEANS_MAX_S`."""
    if int(s) > PIXEL_MEANS_MAX_S or int(s) < 1 or h_sub.dtype != np.float64:
        return None
    out = np.empty(shape, dtype=np.float64)
    over_rows(_pixel_means_kernel, out.shape[0], h_sub, int(s), int(margin), out)
    return out


# --------------------------------------------------------- the under-sampling count
@njit(cache=True, nogil=True)
def _steps_over_kernel(dh, ret, lim, rows, i0, i1):
    ny, nx = dh.shape
    for i in range(i0, i1):
        c = 0
        for j in range(nx):
            if not ret[i, j]:
                continue
            v = dh[i, j]
            if j + 1 < nx and ret[i, j + 1] and abs(dh[i, j + 1] - v) > lim:
                c += 1
            if i + 1 < ny and ret[i + 1, j] and abs(dh[i + 1, j] - v) > lim:
                c += 1
        rows[i] = c


def steps_over(dh32: np.ndarray, returns: np.ndarray, lim: float | np.floating) -> int:
    """How many pairs of neighbouring returning sub-samples (along rows and along
    columns) differ by more than ``lim`` (float32, as ``np.abs(np.diff(dh32)) > lim``
    compares), counted in one compiled pass threaded over rows."""
    rows = np.zeros(np.shape(dh32)[0], dtype=np.int64)
    over_rows(_steps_over_kernel, rows.size, np.ascontiguousarray(dh32, dtype=np.float32),
              np.ascontiguousarray(returns, dtype=np.bool_), np.float32(lim), rows)
    return int(rows.sum())


# ------------------------------------------- the heights about the reference plane
@njit(cache=True, nogil=True)
def _heights_about_kernel(h, ret, zbar, out, lo, hi, i0, i1):
    ny, nx = h.shape
    for i in range(i0, i1):
        a = np.float32(np.inf)
        b = np.float32(-np.inf)
        for j in range(nx):
            if ret[i, j]:
                v = np.float32(h[i, j] - zbar)
                out[i, j] = v
                a = min(a, v)
                b = max(b, v)
            else:
                out[i, j] = 0
        lo[i] = a
        hi[i] = b


def heights_about(h: np.ndarray, returns: np.ndarray,
                  zbar: float) -> tuple[np.ndarray, float, float]:
    """The heights ``h`` (mm) about the plane ``zbar`` in float32 where ``returns`` (0
    elsewhere), and the least and largest of the returning ones (0 and 0 where none
    returns), in one compiled pass threaded over rows: the numbers of
    ``(h - zbar).astype(np.float32)`` with ``[~returns] = 0`` and the ``min()`` and
    ``max()`` of its returning elements, without their temporaries."""
    h64 = np.ascontiguousarray(h, dtype=np.float64)
    out = np.empty(h64.shape, dtype=np.float32)
    lo = np.empty(h64.shape[0], dtype=np.float32)
    hi = np.empty(h64.shape[0], dtype=np.float32)
    over_rows(_heights_about_kernel, h64.shape[0], h64, np.ascontiguousarray(returns, dtype=np.bool_),
              float(zbar), out, lo, hi)
    a, b = (float(lo.min()), float(hi.max())) if lo.size else (math.inf, -math.inf)
    if a > b:  # (no returning sub-sample)
        return out, 0.0, 0.0
    return out, a, b


# ------------------------------------------------------------ loading them beforehand
def preload() -> None:
    """Load the compiled passes above (from numba's cache, or compiled where it lacks
    them) for the argument types the imaging model calls them with, by calling each on a
    few elements, and import the libraries the model and its files use next (SciPy's
    FFTs and filters, Pillow's PNG writer, OpenEXR).  Nothing is kept but the loaded
    code: the results of later calls are the same with or without it.  The
    interferometer runs it in a thread while the ray tracer builds its tree (which lets
    go of the interpreter), so that the first load (numba's own start, about 1 CPU-s)
    does not wait until the frames ask for it."""
    import scipy.fft  # noqa: F401  (the frames' FFTs)
    from PIL import Image  # noqa: F401  (the fringe image)
    from PIL.PngImagePlugin import PngInfo  # noqa: F401
    import OpenEXR  # noqa: F401  (interferogram.exr)

    n = 16
    f32 = np.zeros((n, n), dtype=np.float32)
    nrm = np.zeros((n, n, 3), dtype=np.float32)
    nrm[..., 2] = 1.0
    h = np.zeros((n, n), dtype=np.float64)
    cos_t, _, reached, unit = facets(nrm, h)
    smoothed_cosine(unit[0], unit[1], unit[2], 1.0)
    steps_over(f32, reached, np.float32(1.0))
    heights_about(h, reached, 0.0)
    pixel_means(h, 2, 0, (n // 2, n // 2))
    q2 = np.zeros(n, dtype=np.float32)
    index = radial_index(q2, q2, np.float32(1.0), 4)
    spec = np.zeros((n, n), dtype=np.complex64)
    sep = np.ones(n, dtype=np.complex64)
    cols = np.arange(n, dtype=np.int64)
    filter_fold(spec, np.ones(n, dtype=bool), q2, sep, cols, cols % (n // 2), q2, sep,
                np.ones(4, dtype=np.float32), np.float32(1.0), 2,
                np.empty((n // 2, n // 2), dtype=np.complex64), index=index)
    frames_from_field(np.zeros((2, n), dtype=np.complex64), np.zeros(n, dtype=np.float32),
                      np.float32(1.0), np.float32(1.0), np.empty((2, n), dtype=np.float32))
