"""Compiled passes of the burr model (:mod:`._burrs`): the Gaussian smoothing of the
machined map and the search for its sharp edges, threaded over rows.

Both give the same numbers, to the last bit, as the array expressions they replace:

* :func:`gaussian_nearest` is scipy.ndimage's ``gaussian_filter(z, sigma,
  mode="nearest")`` (the same weights, truncated at int(4 sigma + 0.5) pixels; axis 0
  then axis 1; each output accumulated as scipy's symmetric correlation does it: the
  centre tap first, then the pairs of taps from the outermost inwards);
* :func:`edge_turn_maps` finds the edges and their turns from the slope angles.  A
  compiled pass first bounds each pixel's turn by its slopes alone (arctan is
  1-Lipschitz: the turn between the faces is at most (1 + c)|s_h1 - s_l1| + c|s_h2 - s_l2|);
  where that bound is below the threshold (by far more than any rounding) the pixel is no
  edge.  Only around the remaining candidates are the slope angles taken, with numpy's
  arctan (so that they are the very same numbers: the C library's arctangent differs in
  the last bit), in cells on threads; the turn at a candidate, the local-maximum test and
  the peak within +-3 span pixels are then evaluated as over the whole map.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from ..core.lazy import njit  # numba, imported on first use
from ..core.threads import over_rows
from ..core.smoothing import gaussian_weights

__all__ = ["gaussian_nearest", "gaussian_weights", "edge_turn_maps", "edge_turn_window", "gaussian_nearest_cross"]

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
    smooth_axis0(z, w, out, _SMOOTH_COLUMNS, 0, ny, 0, nx)
    smooth_axis1(out, w, out, _SMOOTH_COLUMNS, 0, ny, 0, nx)  # in place: each row is copied out first
    return out


def smooth_axis0(z: np.ndarray, w: np.ndarray, out: np.ndarray, cw: int, r0: int, r1: int, c0: int,
                 c1: int) -> None:
    """:func:`_smooth_axis0` on threads (its blocks of two rows by ``cw`` columns)."""
    nr = (r1 - r0 + 1) // 2
    nc = (c1 - c0 + cw - 1) // cw
    over_rows(_smooth_axis0, max(nr, 0) * max(nc, 0), z, w, out, cw, r0, r1, c0, c1)


def smooth_axis1(z: np.ndarray, w: np.ndarray, out: np.ndarray, cw: int, r0: int, r1: int, c0: int,
                 c1: int) -> None:
    """:func:`_smooth_axis1` on threads (its rows)."""
    over_rows(_smooth_axis1, max(r1 - r0, 0), z, w, out, cw, r0, r1, c0, c1)


@njit(cache=True, nogil=True)
def _smooth_axis0(z, w, out, cw, r0, r1, c0, c1, t0, t1):
    """Axis 0 of the smoothing into ``out`` (not ``z``) on its rows ``r0 .. r1 - 1`` and
    columns ``c0 .. c1 - 1`` (the rows of ``z`` clamped at its ends), in blocks of ``cw``
    columns: each thread takes a run of blocks and walks down the rows of each, two output
    rows at a time (the rows a tap of the second reads are those the next tap of the first
    reads: still in the first-level cache), so that the rows a window needs are still in
    the cache from the rows before.  Blocks ``t0 .. t1 - 1`` of those (:func:`smooth_axis0`
    runs them on threads)."""
    ny, nx = z.shape
    r = (w.size - 1) // 2
    w0 = w[r]
    nr = (r1 - r0 + 1) // 2
    nc = (c1 - c0 + cw - 1) // cw
    for t in range(t0, t1):
        c = t // nr
        i = r0 + 2 * (t - c * nr)
        q0 = c0 + c * cw
        m = min(q0 + cw, c1) - q0
        acc = np.empty(m)            # blocks of their own: the loops below vectorise
        acc2 = np.empty(m)
        zi = z[i, q0:q0 + m]
        zi2 = z[min(i + 1, ny - 1), q0:q0 + m]
        for q in range(m):
            acc[q] = zi[q] * w0
            acc2[q] = zi2[q] * w0
        for jj in range(-r, 0):
            a = z[min(max(i + jj, 0), ny - 1), q0:q0 + m]
            b = z[min(max(i - jj, 0), ny - 1), q0:q0 + m]
            a2 = z[min(max(i + 1 + jj, 0), ny - 1), q0:q0 + m]
            b2 = z[min(max(i + 1 - jj, 0), ny - 1), q0:q0 + m]
            wj = w[r + jj]
            for q in range(m):
                acc[q] = acc[q] + (a[q] + b[q]) * wj
                acc2[q] = acc2[q] + (a2[q] + b2[q]) * wj
        # (element by element: a slice assignment compiles numba's shape-mismatch message,
        # over a CPU-second)
        o = out[i, q0:q0 + m]
        for q in range(m):
            o[q] = acc[q]
        if i + 1 < r1:
            o = out[i + 1, q0:q0 + m]
            for q in range(m):
                o[q] = acc2[q]


@njit(cache=True, nogil=True)
def _smooth_axis1(z, w, out, cw, r0, r1, c0, c1, k0, k1):
    """Axis 1 of the smoothing on the rows ``r0 .. r1 - 1`` and columns ``c0 .. c1 - 1``
    of ``out`` (the columns of ``z`` clamped at its ends), in blocks of ``cw`` columns so
    that a block's accumulators and the padded row around it stay in the core's
    first-level cache.  ``out`` may be ``z`` in a call over whole rows (each row is copied
    out, padded, before it is written), not across calls over parts of the same rows.
    Rows ``r0 + k0 .. r0 + k1 - 1`` of those (:func:`smooth_axis1` runs them on threads)."""
    ny, nx = z.shape
    r = (w.size - 1) // 2
    w0 = w[r]
    n = c1 - c0
    for i in range(r0 + k0, r0 + k1):
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
    smooth_axis0(z, w, tmp, _SMOOTH_COLUMNS, va, vb, ka, kb)
    la, lb = max(ha - r, 0), min(hb + r, nx)
    if la < ka:
        smooth_axis0(z, w, tmp, _SMOOTH_COLUMNS, r0, r1, la, ka)
    if kb < lb:
        smooth_axis0(z, w, tmp, _SMOOTH_COLUMNS, r0, r1, kb, lb)
    out = np.empty_like(z)
    smooth_axis1(tmp, w, out, _SMOOTH_COLUMNS, va, vb, c0, c1)
    if ha < c0:
        smooth_axis1(tmp, w, out, _SMOOTH_COLUMNS, r0, r1, ha, c0)
    if c1 < hb:
        smooth_axis1(tmp, w, out, _SMOOTH_COLUMNS, r0, r1, c1, hb)
    return out


#: the slope angles are taken (numpy's arctan) in cells of this many pixels along and
#: across the axis, only in the cells that a candidate edge's tests read
_CELL = 128

#: a pixel is no candidate edge where the bound on its turn stays below the threshold by
#: more than this (relative, and absolute in rad, and relative to the height steps the
#: slopes are made of): far more than the rounding of the slopes, of the arctangents and
#: of the faces' differences (a few 1e-16 rad)
_BOUND_REL, _BOUND_ABS = 1e-9, 1e-12


def _bound_limit(thr: float, pixel: float) -> tuple[float, float]:
    """(limit, absolute margin) of :func:`_candidate` for the threshold ``thr`` (rad), in
    height steps (mm) of a pixel ``pixel``."""
    return thr * pixel * (1.0 - _BOUND_REL), _BOUND_ABS * pixel


@njit(inline="always")
def _candidate(dh1, dh2, dl1, dl2, c, lim, eps):
    """Whether a pixel may be an edge, from the height steps d = z[k + 1] - z[k] of its
    faces' slopes s = d / pixel: its turn |(1 + c)(a_h1 - a_l1) - c (a_h2 - a_l2)| (a =
    arctan s) is at most (1 + c)|s_h1 - s_l1| + c |s_h2 - s_l2| (arctan is 1-Lipschitz),
    here times the pixel, with margins for every rounding; NaN: a candidate."""
    g = (1.0 + c) * abs(dh1 - dl1) + c * abs(dh2 - dl2)
    m = abs(dh1) + abs(dh2) + abs(dl1) + abs(dl2)
    return not (g + _BOUND_ABS * m + eps < lim)


@njit(cache=True, nogil=True)
def _candidates0(z, ra, rb, ca, cb, p0, p1, span, lim, eps, cand, count, k0, k1):
    """Axis 0 of the map z[ra:rb, ca:cb] (its rows clamped at its ends): ``cand[p - p0,
    q]`` whether pixel (p, q) of it (p0 <= p < p1) may be an edge (:func:`_candidate`),
    ``count[p - p0]`` the candidates of row p; rows p0 + k0 .. p0 + k1 - 1 of those."""
    n_pix = rb - ra
    n = n_pix - 1
    c = (span - 0.5) / span
    for p in range(p0 + k0, p0 + k1):
        k = 0
        row = cand[p - p0]
        if p >= 1 and p <= n_pix - 2:
            h1 = ra + min(max(p + span - 1, 0), n - 1)
            h2 = ra + min(max(p + 2 * span - 1, 0), n - 1)
            l1 = ra + min(max(p - span, 0), n - 1)
            l2 = ra + min(max(p - 2 * span, 0), n - 1)
            zh1, zh1n, zh2, zh2n = z[h1, ca:cb], z[h1 + 1, ca:cb], z[h2, ca:cb], z[h2 + 1, ca:cb]
            zl1, zl1n, zl2, zl2n = z[l1, ca:cb], z[l1 + 1, ca:cb], z[l2, ca:cb], z[l2 + 1, ca:cb]
            for q in range(cb - ca):
                f = _candidate(zh1n[q] - zh1[q], zh2n[q] - zh2[q], zl1n[q] - zl1[q], zl2n[q] - zl2[q],
                               c, lim, eps)
                row[q] = f
                k += f
        else:
            row[:] = False
        count[p - p0] = k


@njit(cache=True, nogil=True)
def _candidates1(z, r0, r1, ca, cb, p0, p1, span, lim, eps, cand, count, k0, k1):
    """Axis 1 of the map z[r0:r1, ca:cb] (its columns clamped at its ends): ``cand[i,
    p - p0]`` whether pixel (i, p) of it (p0 <= p < p1) may be an edge, ``count[i]``; rows
    i = k0 .. k1 - 1."""
    n_pix = cb - ca
    n = n_pix - 1
    c = (span - 0.5) / span
    lo, hi = max(p0, 1), min(p1, n_pix - 1)
    # [e1, e2): the pixels whose four slopes lie inside the map (no clamping)
    e1 = min(max(lo, 2 * span), hi)
    e2 = min(max(e1, n - 2 * span + 1), hi)
    for i in range(k0, k1):
        zi = z[r0 + i]
        d = np.empty(n)
        for k in range(n):
            d[k] = zi[ca + k + 1] - zi[ca + k]
        row = cand[i]
        row[:] = False
        k = 0
        m = e2 - e1
        dh1, dh2 = d[e1 + span - 1:e1 + span - 1 + m], d[e1 + 2 * span - 1:e1 + 2 * span - 1 + m]
        dl1, dl2 = d[e1 - span:e1 - span + m], d[e1 - 2 * span:e1 - 2 * span + m]
        out = row[e1 - p0:e1 - p0 + m]
        for q in range(m):      # (slices of their own: the loop vectorises)
            f = _candidate(dh1[q], dh2[q], dl1[q], dl2[q], c, lim, eps)
            out[q] = f
            k += f
        for p in range(lo, e1):
            f = _candidate(d[min(max(p + span - 1, 0), n - 1)], d[min(max(p + 2 * span - 1, 0), n - 1)],
                           d[min(max(p - span, 0), n - 1)], d[min(max(p - 2 * span, 0), n - 1)], c, lim, eps)
            row[p - p0] = f
            k += f
        for p in range(e2, hi):
            f = _candidate(d[min(max(p + span - 1, 0), n - 1)], d[min(max(p + 2 * span - 1, 0), n - 1)],
                           d[min(max(p - span, 0), n - 1)], d[min(max(p - 2 * span, 0), n - 1)], c, lim, eps)
            row[p - p0] = f
            k += f
        count[i] = k


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


@njit(cache=True, nogil=True)
def _edges0(a, n_pix, ps, qs, p0, span, thr, edges, turn, x0, x1):
    """The edge tests along axis 0 of the candidates (``ps``, ``qs``) of a map of
    ``n_pix`` rows from its slope angles ``a`` (n_pix - 1 rows; read within 3 span + 1
    rows of each candidate); the larger turn is kept where ``turn`` has one already
    (``edges`` and ``turn`` hold the rows from ``p0``); candidates x0 .. x1 - 1 (each
    writes only its own pixel)."""
    n = n_pix - 1
    c = (span - 0.5) / span
    reach = 3 * span
    for x in range(x0, x1):
        p = ps[x]
        q = qs[x]
        j = _jturn(a, p, n_pix, q)
        if not (j > 0.0) or j < _jturn(a, p - 1, n_pix, q) or j < _jturn(a, p + 1, n_pix, q):
            continue                # not a local maximum of the turn: no edge
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
        turn[p - p0, q] = max(turn[p - p0, q], t)
        edges[p - p0, q] = True


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


@njit(cache=True, nogil=True)
def _edges1(a, n_pix, iis, ps, p0, span, thr, edges, turn, x0, x1):
    """:func:`_edges0` along axis 1: candidates (``iis``, ``ps``), ``a`` (rows, n_pix - 1)."""
    n = n_pix - 1
    c = (span - 0.5) / span
    reach = 3 * span
    for x in range(x0, x1):
        i = iis[x]
        p = ps[x]
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
        turn[i, p - p0] = max(turn[i, p - p0], t)
        edges[i, p - p0] = True


@njit(cache=True, nogil=True)
def _mark_cells(along, across, reach, n_along, cell, need):
    for x in range(along.size):
        m = across[x] // cell
        for i in range(max(along[x] - reach - 1, 0) // cell, min(along[x] + reach, n_along - 1) // cell + 1):
            need[i, m] = True


def _cells(along: np.ndarray, across: np.ndarray, reach: int, n_along: int,
           n_across: int) -> list[tuple[int, int, int, int]]:
    """Cells (first, end along; first, end across) of a slope array holding the slopes
    ``k - reach - 1 .. k + reach`` along the axis of every candidate (k, m) = (``along``,
    ``across``): runs of :data:`_CELL`-sided cells across the axis."""
    na, nb = -(-n_along // _CELL), -(-n_across // _CELL)
    need = np.zeros((na, nb), dtype=np.bool_)
    _mark_cells(np.ascontiguousarray(along, dtype=np.int64), np.ascontiguousarray(across, dtype=np.int64),
                int(reach), int(n_along), _CELL, need)
    out = []
    for i in np.flatnonzero(need.any(axis=1)):
        row = np.concatenate(([False], need[i], [False]))
        d = np.flatnonzero(row[1:] != row[:-1])
        for j0, j1 in zip(d[::2], d[1::2]):
            out.append((int(i) * _CELL, min((int(i) + 1) * _CELL, n_along),
                        int(j0) * _CELL, min(int(j1) * _CELL, n_across)))
    return out


def _angles(z: np.ndarray, axis: int, rows: tuple[int, int], cols: tuple[int, int],
            cells: list[tuple[int, int, int, int]], pixel: float) -> np.ndarray:
    """The slope angles of the map z[rows, cols] along ``axis`` on the ``cells`` of
    :func:`_cells` (elsewhere undefined): numpy's arctan of (z[i + 1] - z[i]) / pixel, the
    same numbers as over the whole map, computed on threads."""
    ra, rb = rows
    ca, cb = cols
    a = np.empty((rb - ra - 1, cb - ca) if axis == 0 else (rb - ra, cb - ca - 1))

    def cell(c):
        k0, k1, m0, m1 = c
        if axis == 0:
            v = a[k0:k1, m0:m1]
            np.subtract(z[ra + k0 + 1:ra + k1 + 1, ca + m0:ca + m1], z[ra + k0:ra + k1, ca + m0:ca + m1], out=v)
        else:
            v = a[m0:m1, k0:k1]
            np.subtract(z[ra + m0:ra + m1, ca + k0 + 1:ca + k1 + 1], z[ra + m0:ra + m1, ca + k0:ca + k1], out=v)
        np.divide(v, pixel, out=v)
        np.arctan(v, out=v)

    if len(cells) > 4 and _threads() > 1:
        with ThreadPoolExecutor(_threads()) as ex:
            list(ex.map(cell, cells))
    else:
        for c in cells:
            cell(c)
    return a


def _axis_edges(z: np.ndarray, axis: int, rows: tuple[int, int], cols: tuple[int, int],
                pix: tuple[int, int], *, pixel: float, span: int, thr: float,
                edges: np.ndarray, turn: np.ndarray) -> None:
    """The edges along ``axis`` of the map z[rows, cols] (clamped at its ends along the
    axis) on its pixels ``pix`` (first, end) along the axis, into ``edges`` and ``turn``
    (those pixels by the map's other axis; the larger turn kept).  The slope angles are
    taken only around the pixels whose turn may exceed ``thr`` (:func:`_candidate`); the
    tests are those of the whole map there."""
    (ra, rb), (ca, cb), (p0, p1) = rows, cols, pix
    pixel, span = float(pixel), int(span)
    cand = np.empty((p1 - p0, cb - ca) if axis == 0 else (rb - ra, p1 - p0), dtype=np.bool_)
    count = np.empty(cand.shape[0], dtype=np.int64)
    over_rows(_candidates0 if axis == 0 else _candidates1, cand.shape[0], z, ra, rb, ca, cb, p0, p1, span,
              *_bound_limit(thr, pixel), cand, count)
    lines = np.flatnonzero(count)
    if lines.size == 0:
        return
    li, other = np.nonzero(cand[lines])
    li = lines[li]
    n_pix = rb - ra if axis == 0 else cb - ca
    along = li + p0 if axis == 0 else other + p0          # the candidates' pixels along the axis
    across = other if axis == 0 else li
    a = _angles(z, axis, rows, cols, _cells(along, across, 3 * span, n_pix - 1, cand.shape[1 - axis]),
                pixel)
    if axis == 0:
        over_rows(_edges0, along.size, a, n_pix, along, across, p0, span, thr, edges, turn)
    else:
        over_rows(_edges1, along.size, a, n_pix, across, along, p0, span, thr, edges, turn)


def edge_turn_maps(z: np.ndarray, *, pixel: float, edge_angle_deg: float,
                   span: int) -> tuple[np.ndarray, np.ndarray]:
    """(edges, turn) of :func:`._burrs.edge_turns` for a 2-D float64 map, compiled."""
    z = np.ascontiguousarray(z, dtype=np.float64)
    ny, nx = z.shape
    edges = np.zeros(z.shape, dtype=bool)
    turn = np.zeros(z.shape)
    thr = math.radians(edge_angle_deg)
    if ny >= 3:
        _axis_edges(z, 0, (0, ny), (0, nx), (0, ny), pixel=pixel, span=span, thr=thr, edges=edges, turn=turn)
    if nx >= 3:
        _axis_edges(z, 1, (0, ny), (0, nx), (0, nx), pixel=pixel, span=span, thr=thr, edges=edges, turn=turn)
    return edges, turn


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
    edges = np.zeros((max(r1 - r0, 0), max(c1 - c0, 0)), dtype=bool)
    turn = np.zeros(edges.shape)
    if r1 <= r0 or c1 <= c0:
        return edges, turn
    thr = math.radians(edge_angle_deg)
    reach = 3 * int(span) + 1
    if ny >= 3:
        a, b = max(r0 - reach, 0), min(r1 + reach, ny)
        _axis_edges(z, 0, (a, b), (c0, c1), (r0 - a, r1 - a), pixel=pixel, span=span, thr=thr,
                    edges=edges, turn=turn)
    if nx >= 3:
        # (the larger of the two axes' turns kept: both >= 0, 0 off the edges)
        a, b = max(c0 - reach, 0), min(c1 + reach, nx)
        _axis_edges(z, 1, (r0, r1), (a, b), (c0 - a, c1 - a), pixel=pixel, span=span, thr=thr,
                    edges=edges, turn=turn)
    return edges, turn


@njit(cache=True, nogil=True, inline="always")
def _jumps_at(p, i, q, ny, nx, jump):
    """Whether pixel (i, q) of ``p`` differs from a neighbour along a grid axis by more than
    ``jump`` (NaN never differs)."""
    v = p[i, q]
    if i > 0 and abs(v - p[i - 1, q]) > jump:
        return True
    if i < ny - 1 and abs(p[i + 1, q] - v) > jump:
        return True
    if q > 0 and abs(v - p[i, q - 1]) > jump:
        return True
    return q < nx - 1 and abs(p[i, q + 1] - v) > jump


@njit(cache=True, nogil=True)
def _pass_jumps(p, jump, m, i0, i1):
    ny, nx = p.shape
    for i in range(i0, i1):
        for q in range(nx):
            m[i, q] = _jumps_at(p, i, q, ny, nx, jump)


@njit(cache=True, nogil=True)
def _pass_jump_counts(p, jump, counts, i0, i1):
    ny, nx = p.shape
    for i in range(i0, i1):
        n = 0
        for q in range(nx):
            if _jumps_at(p, i, q, ny, nx, jump):
                n += 1
        counts[i] = n


def pass_jump_mask(pass_map: np.ndarray, jump: float) -> np.ndarray:
    """Pixels next to a pixel whose value differs by more than ``jump`` along a grid axis
    (NaN never differs): :func:`._cutting.machined_edges`, compiled and threaded."""
    p = np.ascontiguousarray(pass_map, dtype=np.float64)
    m = np.zeros(p.shape, dtype=bool)
    if p.ndim == 2 and p.size:
        over_rows(_pass_jumps, p.shape[0], p, float(jump), m)
        return m
    raise ValueError("pass_map must be a 2-D array")


def pass_jump_count(pass_map: np.ndarray, jump: float) -> int:
    """The number of pixels :func:`pass_jump_mask` marks, without the mask (compiled and
    threaded, each row counted on its own)."""
    p = np.ascontiguousarray(pass_map, dtype=np.float64)
    if p.ndim != 2:
        raise ValueError("pass_map must be a 2-D array")
    counts = np.zeros(p.shape[0], dtype=np.int64)
    if p.size:
        over_rows(_pass_jump_counts, p.shape[0], p, float(jump), counts)
    return int(counts.sum())
