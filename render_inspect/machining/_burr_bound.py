"""A proof that a tile has no burr edge, found before the burr model smooths its block.

The burr model (:func:`~._burrs.material_burr_block`) looks for edges on the machined map
smoothed by a Gaussian; a pixel can be an edge only where the bound on its turn from the
smoothed map's height steps (:func:`~._burr_kernels._candidate`) reaches the threshold.
Where it stays below everywhere on the tile's window, the model finds no edge and adds
nothing: it returns None.  :func:`no_edge_possible` shows that without the smoothing of
the block (about 4 M pixel-passes of 161 taps at 0.5 um), from

* the exact two-dimensional smoothing on every ``SAMPLE``-th column (row) of the window,
  along the whole column (row): there the steps the bound reads are those of the model's
  smoothed map up to rounding, and
* a bound on how much those steps change from one column (row) to the next, which holds
  between the sampled ones: with e = z - d for a reference map d (the design), the
  change of the step difference D across the axis is at most ||delta * w||_1 T E + (sum
  w)^2 2 M, with w the Gaussian's weights, T their total variation, E the largest
  distance of e from the middle of its range and M the largest mixed second difference of
  d (the smoothing is linear, and commutes with differences away from the map's ends).

Only blocks whose smoothing and edge tests read no clamped pixel take this route (a tile
away from the grid's border, every pixel cut); the answer is "no edge" or "don't know",
never an edge, so the burrs are the model's own bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.lazy import njit  # numba, imported on first use

__all__ = ["no_edge_possible", "SAMPLE"]

#: columns (rows) between the sampled ones: a pixel is at most SAMPLE // 2 from one
SAMPLE = 8

#: rounding allowance, relative to the largest |height| of the map (the sums here and the
#: model's differ in order only: a few 1e-14 of it)
_ROUND = 1e-10


@njit(cache=True, nogil=True)
def _reference_stats(z, d):
    """(min of z - d, max of z - d, max |z|, max |mixed second difference of d|), NaN
    propagated as NaN."""
    ny, nx = z.shape
    lo = np.inf
    hi = -np.inf
    za = 0.0
    mixed = 0.0
    bad = False
    for i in range(ny):
        for j in range(nx):
            v = z[i, j]
            e = v - d[i, j]
            if e != e:
                bad = True
            if e < lo:
                lo = e
            if e > hi:
                hi = e
            if abs(v) > za:
                za = abs(v)
        if i + 1 < ny:
            for j in range(nx - 1):
                m = abs(d[i + 1, j + 1] - d[i + 1, j] - d[i, j + 1] + d[i, j])
                if m != m:
                    bad = True
                if m > mixed:
                    mixed = m
    if bad:
        return np.nan, np.nan, np.nan, np.nan
    return lo, hi, za, mixed


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _line_max(u, w, v, k0, k1, span, c, best):
    """One line of the sampled bound: ``u`` (the line smoothed across it, 2 r more entries
    than ``v``) smoothed along it into ``v`` by w, then the larger of ``best`` and the
    largest (1 + c)|D1| + c|D2| at the entries k0 .. k1 - 1 of ``v`` (inf where NaN)."""
    r = (w.size - 1) // 2
    for i in range(v.size):
        acc = 0.0
        for t in range(2 * r + 1):
            acc += w[t] * u[i + t]
        v[i] = acc
    for k in range(k0, k1):
        d1 = (v[k + span] - v[k + span - 1]) - (v[k - span + 1] - v[k - span])
        d2 = (v[k + 2 * span] - v[k + 2 * span - 1]) - (v[k - 2 * span + 1] - v[k - 2 * span])
        g = (1.0 + c) * abs(d1) + c * abs(d2)
        if not (g <= best):
            best = g if g == g else np.inf
    return best


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _sampled_max(z, w, r0, r1, qs, span, c):
    """max over p in [r0, r1) and the columns ``qs`` of (1 + c)|D1| + c|D2| along axis 0
    of z smoothed by w along both axes (no clamping: the caller checks the reach), D1 and
    D2 the step differences the edge bound reads (:func:`~._burr_kernels._candidate`)."""
    r = (w.size - 1) // 2
    a = r0 - 2 * span          # rows of the smoothed map read: [a, b)
    b = r1 + 2 * span
    n = b - a
    ns = qs.size
    u = np.empty((ns, n + 2 * r))
    for i in range(n + 2 * r):          # along axis 1 at the columns qs, rows a - r .. b + r
        row = z[a - r + i]
        for s in range(ns):
            seg = row[qs[s] - r:qs[s] + r + 1]
            acc = 0.0
            for j in range(2 * r + 1):
                acc += w[j] * seg[j]
            u[s, i] = acc
    v = np.empty(n)
    best = 0.0
    for s in range(ns):                 # then along axis 0
        best = _line_max(u[s], w, v, r0 - a, r1 - a, span, c, best)
    return best


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _sampled_max_rows(z, w, c0, c1, ps, span, c):
    """:func:`_sampled_max` along axis 1: over q in [c0, c1) and the rows ``ps`` (the map
    read along its rows)."""
    r = (w.size - 1) // 2
    a = c0 - 2 * span
    b = c1 + 2 * span
    n = b - a
    u = np.empty(n + 2 * r)
    v = np.empty(n)
    best = 0.0
    for p in ps:
        u[:] = 0.0
        for t in range(2 * r + 1):      # along axis 0 at row p, columns a - r .. b + r
            row = z[p - r + t, a - r:b + r]
            wt = w[t]
            for j in range(n + 2 * r):
                u[j] += wt * row[j]
        best = _line_max(u, w, v, c0 - a, c1 - a, span, c, best)  # then along axis 1
    return best


def _samples(c0: int, c1: int) -> np.ndarray:
    q = np.arange(c0, c1, SAMPLE, dtype=np.int64)
    if q[-1] != c1 - 1:
        q = np.append(q, c1 - 1)
    return q


def _stencil(span: int, far: bool) -> np.ndarray:
    """The step difference D1 (``far``: D2) as weights on the map's pixels p - 2 span ..
    p + 2 span."""
    s = np.zeros(4 * span + 1)
    o = 2 * span
    k = 2 * span if far else span
    s[o + k] += 1.0
    s[o + k - 1] -= 1.0
    s[o - k + 1] -= 1.0
    s[o - k] += 1.0
    return s


def no_edge_possible(z: np.ndarray, reference: np.ndarray, w: np.ndarray,
                     window: tuple[int, int, int, int], *, pixel: float, edge_angle_deg: float,
                     span: int, lim: float, eps: float, rel: float) -> bool:
    """Whether no pixel of ``window`` (first row, end row, first column, end column) of the
    block ``z`` can be a candidate edge of :func:`~._burr_kernels.edge_turn_window` on z
    smoothed by the weights ``w`` (the model's: no pixel passes the bound ``g + rel m +
    eps < lim`` of :func:`~._burr_kernels._candidate` along either axis).  ``reference``:
    a map of the block close to z (the design; any finite map gives a valid answer, a
    close one a useful one).  False where it cannot tell (the smoothing or the tests would
    reach the block's ends, a NaN)."""
    z = np.ascontiguousarray(z, dtype=np.float64)
    d = np.ascontiguousarray(reference, dtype=np.float64)
    ny, nx = z.shape
    r0, r1, c0, c1 = (int(v) for v in window)
    r = (w.size - 1) // 2
    reach = 2 * span + r
    if d.shape != z.shape or r1 <= r0 or c1 <= c0 or r0 - reach < 0 or r1 + reach > ny \
            or c0 - reach < 0 or c1 + reach > nx:
        return False
    lo, hi, za, mixed = _reference_stats(z, d)
    if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(mixed)):
        return False
    half = (hi - lo) / 2 * (1 + 1e-12)      # |e - middle| <= half
    total_var = float(np.abs(np.diff(np.concatenate(([0.0], w, [0.0])))).sum())
    wsum = float(np.abs(w).sum())
    c = (span - 0.5) / span
    # the most D1 and D2 change from one column to the next (the same across rows)
    lip = [float(np.abs(np.convolve(_stencil(span, far), w)).sum()) * total_var * wsum * half
           + wsum * wsum * 2.0 * mixed for far in (False, True)]
    slack = (SAMPLE // 2) * ((1.0 + c) * lip[0] + c * lip[1])
    # rounding: the sums' order; the model's margin rel * m with m <= 4 * 2 max|z|
    allow = slack + _ROUND * za + 8.0 * rel * za + eps
    if not allow < lim:
        return False
    g0 = _sampled_max(z, w, r0, r1, _samples(c0, c1), span, c)
    if not g0 + allow < lim:
        return False
    g1 = _sampled_max_rows(z, w, c0, c1, _samples(r0, r1), span, c)
    return bool(g1 + allow < lim)
