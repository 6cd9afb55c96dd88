"""Compiled passes of the burr model (:mod:`._burrs`): the Gaussian smoothing of the
machined map and the search for its sharp edges, threaded over rows.

Both give the same numbers, to the last bit, as the array expressions they replace:

* :func:`gaussian_nearest` is scipy.ndimage's ``gaussian_filter(z, sigma,
  mode="nearest")`` (the same weights, truncated at int(4 sigma + 0.5) pixels; axis 0
  then axis 1; each output accumulated as scipy's symmetric correlation does it: the
  centre tap first, then the pairs of taps from the outermost inwards);
* :func:`edge_turn_maps` finds the edges and their turns from the slope angles (the
  arctangents stay numpy's, computed in row blocks on threads, so that they are the very
  same numbers); the turn at a pixel, the local-maximum test and the peak within +-3 span
  pixels are evaluated pixel by pixel, the peak test only where the turn exceeds the
  threshold.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from ..core.lazy import njit, prange  # numba, imported on first use
from ..core.smoothing import gaussian_weights

__all__ = ["gaussian_nearest", "gaussian_weights", "edge_turn_maps", "edge_turn_window", "gaussian_nearest_cross", "slope_angles"]

#: rows per block of the threaded numpy passes
_BLOCK_ROWS = 256


def _threads() -> int:
    return max(1, min(8, os.cpu_count() or 1))


#: columns per block of the smoothing: along axis 0 the 2 r + 1 rows of a block stay in the
#: core's cache (161 rows of 512 columns, 660 kB, for the 20-pixel sigma of a 0.5 um grid);
#: along axis 1 a block's accumulators and its stretch of the row stay in the first level
_SMOOTH_COLUMNS = 512


def gaussian_nearest(z: np.ndarray, sigma: float) -> np.ndarray:
    """``scipy.ndimage.gaussian_filter(z, sigma, mode="nearest")`` of a 2-D float64 map,
    the same to the last bit, threaded over rows."""
    z = np.ascontiguousarray(z, dtype=np.float64)
    w = gaussian_weights(sigma)
    if z.ndim != 2 or z.size == 0 or not np.all(np.abs(w - w[::-1]) <= np.finfo(float).eps):
        from scipy import ndimage

        return ndimage.gaussian_filter(z, sigma, mode="nearest")
    ny, nx = z.shape
    out = np.empty_like(z)
    _smooth_axis0(z, w, out, _SMOOTH_COLUMNS, 0, ny, 0, nx)
    _smooth_axis1(out, w, out, _SMOOTH_COLUMNS, 0, ny, 0, nx)  # in place: each row is copied out first
    return out


@njit(parallel=True, cache=True)
def _smooth_axis0(z, w, out, cw, r0, r1, c0, c1):
    """Axis 0 of the smoothing into ``out`` (not ``z``) on its rows ``r0 .. r1 - 1`` and
    columns ``c0 .. c1 - 1`` (the rows of ``z`` clamped at its ends), in blocks of ``cw``
    columns: each thread takes a run of blocks and walks down the rows of each, so that the
    rows a window needs are still in the cache from the row before."""
    ny, nx = z.shape
    r = (w.size - 1) // 2
    w0 = w[r]
    nr = r1 - r0
    nc = (c1 - c0 + cw - 1) // cw
    for t in prange(nr * nc):
        c = t // nr
        i = r0 + t - c * nr
        q0 = c0 + c * cw
        m = min(q0 + cw, c1) - q0
        acc = np.empty(m)            # a block of its own: the loops below vectorise
        zi = z[i, q0:q0 + m]
        for q in range(m):
            acc[q] = zi[q] * w0
        for jj in range(-r, 0):
            a = z[min(max(i + jj, 0), ny - 1), q0:q0 + m]
            b = z[min(max(i - jj, 0), ny - 1), q0:q0 + m]
            wj = w[r + jj]
            for q in range(m):
                acc[q] = acc[q] + (a[q] + b[q]) * wj
        out[i, q0:q0 + m] = acc


@njit(parallel=True, cache=True)
def _smooth_axis1(z, w, out, cw, r0, r1, c0, c1):
    """Axis 1 of the smoothing on the rows ``r0 .. r1 - 1`` and columns ``c0 .. c1 - 1``
    of ``out`` (the columns of ``z`` clamped at its ends), in blocks of ``cw`` columns so
    that a block's accumulators and the padded row around it stay in the core's
    first-level cache.  ``out`` may be ``z`` in a call over whole rows (each row is copied
    out, padded, before it is written), not across calls over parts of the same rows."""
    ny, nx = z.shape
    r = (w.size - 1) // 2
    w0 = w[r]
    n = c1 - c0
    for i in prange(r0, r1):
        pad = np.empty(n + 2 * r)
        zi = z[i]
        for q in range(n + 2 * r):
            pad[q] = zi[min(max(c0 + q - r, 0), nx - 1)]
        acc = np.empty(cw)
        for q0 in range(0, n, cw):
            m = min(cw, n - q0)
            c = pad[q0 + r:q0 + r + m]
            for q in range(m):
                acc[q] = c[q] * w0
            for jj in range(-r, 0):
                wj = w[r + jj]
                a = pad[q0 + r + jj:q0 + r + jj + m]
                b = pad[q0 + r - jj:q0 + r - jj + m]
                for q in range(m):
                    acc[q] = acc[q] + (a[q] + b[q]) * wj
            o = out[i, c0 + q0:c0 + q0 + m]
            for q in range(m):
                o[q] = acc[q]


def gaussian_nearest_cross(z: np.ndarray, sigma: float, window: tuple[int, int, int, int],
                           reach: int) -> np.ndarray | None:
    """:func:`gaussian_nearest` of ``z`` where :func:`edge_turn_window` reads it for the
    pixels ``window`` = (first row, end row, first column, end column): the window's
    columns on its rows widened by ``reach``, and its rows on its columns widened by
    ``reach`` (a cross); the same numbers there to the last bit, other pixels undefined.
    None where the compiled passes do not apply (then smooth the whole map)."""
    z = np.ascontiguousarray(z, dtype=np.float64)
    w = gaussian_weights(sigma)
    if z.ndim != 2 or z.size == 0 or not np.all(np.abs(w - w[::-1]) <= np.finfo(float).eps):
        return None
    ny, nx = z.shape
    r = (w.size - 1) // 2
    r0, r1, c0, c1 = (int(v) for v in window)
    if r1 <= r0 or c1 <= c0:
        return np.empty_like(z)
    va, vb = max(r0 - reach, 0), min(r1 + reach, ny)      # the cross's rows on the window's columns
    ha, hb = max(c0 - reach, 0), min(c1 + reach, nx)      # its columns on the window's rows
    tmp = np.empty_like(z)
    # axis 0 where axis 1 reads it: the cross widened by the Gaussian's reach along the rows
    ka, kb = max(c0 - r, 0), min(c1 + r, nx)
    _smooth_axis0(z, w, tmp, _SMOOTH_COLUMNS, va, vb, ka, kb)
    la, lb = max(ha - r, 0), min(hb + r, nx)
    if la < ka:
        _smooth_axis0(z, w, tmp, _SMOOTH_COLUMNS, r0, r1, la, ka)
    if kb < lb:
        _smooth_axis0(z, w, tmp, _SMOOTH_COLUMNS, r0, r1, kb, lb)
    out = np.empty_like(z)
    _smooth_axis1(tmp, w, out, _SMOOTH_COLUMNS, va, vb, c0, c1)
    if ha < c0:
        _smooth_axis1(tmp, w, out, _SMOOTH_COLUMNS, r0, r1, ha, c0)
    if c1 < hb:
        _smooth_axis1(tmp, w, out, _SMOOTH_COLUMNS, r0, r1, c1, hb)
    return out


def slope_angles(z: np.ndarray, pixel: float) -> tuple[np.ndarray, np.ndarray]:
    """arctan of the slopes between neighbouring pixels along each grid axis: (ny - 1,
    nx) along y and (ny, nx - 1) along x, numpy's arctan of (z[i + 1] - z[i]) / pixel,
    computed in row blocks on threads."""
    ny, nx = z.shape
    a0 = np.empty((max(ny - 1, 0), nx))
    a1 = np.empty((ny, max(nx - 1, 0)))

    def block(r0):
        r1 = min(r0 + _BLOCK_ROWS, ny)
        if r0 < ny - 1:
            s = min(r1, ny - 1)
            v = a0[r0:s]
            np.subtract(z[r0 + 1:s + 1], z[r0:s], out=v)
            np.divide(v, pixel, out=v)
            np.arctan(v, out=v)
        if nx > 1:
            v = a1[r0:r1]
            np.subtract(z[r0:r1, 1:], z[r0:r1, :-1], out=v)
            np.divide(v, pixel, out=v)
            np.arctan(v, out=v)

    starts = range(0, ny, _BLOCK_ROWS)
    if len(starts) > 1 and _threads() > 1:
        with ThreadPoolExecutor(_threads()) as ex:
            list(ex.map(block, starts))
    else:
        for r0 in starts:
            block(r0)
    return a0, a1


@njit(inline="always")
def _jturn(a, k, n_pix, q):
    """|angle change| at pixel k along axis 0 of a (slopes k - 1 and k), 0 at the ends
    and where NaN."""
    if k < 1 or k > n_pix - 2:
        return 0.0
    v = abs(a[k, q] - a[k - 1, q])
    if v != v:
        return 0.0
    return v


@njit(inline="always")
def _face(a, k1, k2, n, q, c):
    a1 = a[min(max(k1, 0), n - 1), q]
    a2 = a[min(max(k2, 0), n - 1), q]
    return a1 - c * (a2 - a1)


@njit(parallel=True, cache=True)
def _turns_axis0(a, span, thr, edges, turn):
    """Edges along axis 0 of a map of (n_pix, nx) pixels from the slope angles ``a``
    (n_pix - 1, nx); the larger turn is kept where ``turn`` has one already."""
    n_pix, nx = edges.shape
    n = n_pix - 1
    c = (span - 0.5) / span
    reach = 3 * span
    for p in prange(n_pix):
        for q in range(nx):
            j = _jturn(a, p, n_pix, q)
            if not (j > 0.0) or j < _jturn(a, p - 1, n_pix, q) or j < _jturn(a, p + 1, n_pix, q):
                continue                # not a local maximum of the turn: no candidate
            t = abs(_face(a, p + span - 1, p + 2 * span - 1, n, q, c)
                    - _face(a, p - span, p - 2 * span, n, q, c))
            if t != t:
                t = 0.0
            if not (t > thr):
                continue
            peak = True
            for k in range(max(0, p - reach), min(n_pix - 1, p + reach) + 1):
                if _jturn(a, k, n_pix, q) > j:
                    peak = False
                    break
            if not peak:
                continue
            turn[p, q] = max(turn[p, q], t)
            edges[p, q] = True


@njit(inline="always")
def _jturn1(a, i, k, n_pix):
    if k < 1 or k > n_pix - 2:
        return 0.0
    v = abs(a[i, k] - a[i, k - 1])
    if v != v:
        return 0.0
    return v


@njit(inline="always")
def _face1(a, i, k1, k2, n, c):
    a1 = a[i, min(max(k1, 0), n - 1)]
    a2 = a[i, min(max(k2, 0), n - 1)]
    return a1 - c * (a2 - a1)


@njit(parallel=True, cache=True)
def _turns_axis1(a, span, thr, edges, turn):
    ny, n_pix = edges.shape
    n = n_pix - 1
    c = (span - 0.5) / span
    reach = 3 * span
    for i in prange(ny):
        for p in range(n_pix):
            j = _jturn1(a, i, p, n_pix)
            if not (j > 0.0) or j < _jturn1(a, i, p - 1, n_pix) or j < _jturn1(a, i, p + 1, n_pix):
                continue
            t = abs(_face1(a, i, p + span - 1, p + 2 * span - 1, n, c)
                    - _face1(a, i, p - span, p - 2 * span, n, c))
            if t != t:
                t = 0.0
            if not (t > thr):
                continue
            peak = True
            for k in range(max(0, p - reach), min(n_pix - 1, p + reach) + 1):
                if _jturn1(a, i, k, n_pix) > j:
                    peak = False
                    break
            if not peak:
                continue
            turn[i, p] = max(turn[i, p], t)
            edges[i, p] = True


def edge_turn_maps(z: np.ndarray, *, pixel: float, edge_angle_deg: float,
                   span: int) -> tuple[np.ndarray, np.ndarray]:
    """(edges, turn) of :func:`._burrs.edge_turns` for a 2-D float64 map, compiled."""
    z = np.ascontiguousarray(z, dtype=np.float64)
    ny, nx = z.shape
    edges = np.zeros(z.shape, dtype=bool)
    turn = np.zeros(z.shape)
    a0, a1 = slope_angles(z, pixel)
    thr = math.radians(edge_angle_deg)
    if ny >= 3:
        _turns_axis0(a0, int(span), thr, edges, turn)
    if nx >= 3:
        _turns_axis1(a1, int(span), thr, edges, turn)
    return edges, turn


def _axis_angles(z: np.ndarray, pixel: float, axis: int) -> np.ndarray:
    """arctan of the slopes along one grid axis of ``z``: the very numbers of
    :func:`slope_angles` (the same numpy operations, element by element), in row blocks
    on threads."""
    ny, nx = z.shape
    a = np.empty((ny - 1, nx) if axis == 0 else (ny, nx - 1))

    def block(r0):
        r1 = min(r0 + _BLOCK_ROWS, a.shape[0])
        v = a[r0:r1]
        if axis == 0:
            np.subtract(z[r0 + 1:r1 + 1], z[r0:r1], out=v)
        else:
            np.subtract(z[r0:r1, 1:], z[r0:r1, :-1], out=v)
        np.divide(v, pixel, out=v)
        np.arctan(v, out=v)

    starts = range(0, a.shape[0], _BLOCK_ROWS)
    if len(starts) > 1 and _threads() > 1:
        with ThreadPoolExecutor(_threads()) as ex:
            list(ex.map(block, starts))
    else:
        for r0 in starts:
            block(r0)
    return a


def edge_turn_window(z: np.ndarray, window: tuple[int, int, int, int], *, pixel: float,
                     edge_angle_deg: float, span: int) -> tuple[np.ndarray, np.ndarray]:
    """(edges, turn) of :func:`edge_turn_maps` on the pixels ``window`` = (first row, end
    row, first column, end column) of ``z`` only, the same numbers to the last bit.  A
    pixel's tests along an axis read the slopes at most 3 ``span`` + 1 pixels away along
    that axis, so the slopes are taken only on the window's rows widened by that along
    axis 0 and on its columns widened by it along axis 1 (the kernels clamp at the ends of
    what they are given as at the map's, which lie beyond that reach or are the map's)."""
    z = np.ascontiguousarray(z, dtype=np.float64)
    ny, nx = z.shape
    r0, r1, c0, c1 = (int(v) for v in window)
    edges = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    turn = np.zeros((r1 - r0, c1 - c0))
    if r1 <= r0 or c1 <= c0:
        return edges, turn
    thr = math.radians(edge_angle_deg)
    reach = 3 * int(span) + 1
    if ny >= 3:
        a, b = max(r0 - reach, 0), min(r1 + reach, ny)
        e = np.zeros((b - a, c1 - c0), dtype=bool)
        t = np.zeros((b - a, c1 - c0))
        _turns_axis0(_axis_angles(z[a:b, c0:c1], pixel, 0), int(span), thr, e, t)
        edges |= e[r0 - a:r1 - a]
        turn[...] = t[r0 - a:r1 - a]
    if nx >= 3:
        a, b = max(c0 - reach, 0), min(c1 + reach, nx)
        e = np.zeros((r1 - r0, b - a), dtype=bool)
        t = np.zeros((r1 - r0, b - a))
        _turns_axis1(_axis_angles(z[r0:r1, a:b], pixel, 1), int(span), thr, e, t)
        edges |= e[:, c0 - a:c1 - a]
        # the kernel keeps the larger of the two axes' turns (both >= 0, 0 off the edges)
        np.maximum(turn, t[:, c0 - a:c1 - a], out=turn)
    return edges, turn


@njit(parallel=True, cache=True)
def _pass_jumps(p, jump, m):
    ny, nx = p.shape
    for i in prange(ny):
        for q in range(nx):
            v = p[i, q]
            e = False
            if i > 0 and abs(v - p[i - 1, q]) > jump:
                e = True
            elif i < ny - 1 and abs(p[i + 1, q] - v) > jump:
                e = True
            elif q > 0 and abs(v - p[i, q - 1]) > jump:
                e = True
            elif q < nx - 1 and abs(p[i, q + 1] - v) > jump:
                e = True
            m[i, q] = e


def pass_jump_mask(pass_map: np.ndarray, jump: float) -> np.ndarray:
    """Pixels next to a pixel whose value differs by more than ``jump`` along a grid axis
    (NaN never differs): :func:`._cutting.machined_edges`, compiled and threaded."""
    p = np.ascontiguousarray(pass_map, dtype=np.float64)
    m = np.zeros(p.shape, dtype=bool)
    if p.ndim == 2 and p.size:
        _pass_jumps(p, float(jump), m)
        return m
    raise ValueError("pass_map must be a 2-D array")
