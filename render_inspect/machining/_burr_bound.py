"""A proof that a map or a tile has no burr edge, found before the burr model smooths it.

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

A tile's window must lie so far inside its block that its smoothing and edge tests read
no clamped pixel (a tile away from the grid's border, every pixel cut).  A whole map
(``ends=True``) is read as the model reads it, clamped at its ends: the smoothing there
takes the nearest pixel inside (mode "nearest") and the tests the nearest step inside.
Clamping folds the weights onto the end pixels, which does not raise their sum of
absolute values, and leaves the mixed second differences of the reference those of d or
0, so the same bound holds with ||delta * w||_1 taken at its largest for any two steps,
2 T.  The answer is "no edge" or "don't know", never an edge, so the burrs are the
model's own bit for bit.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.lazy import njit  # numba, imported on first use
from ..core.threads import over_rows

__all__ = ["no_edge_possible", "SAMPLE", "SAMPLE_MAX"]

#: columns (rows) between the sampled ones: a pixel is at most SAMPLE // 2 from one
SAMPLE = 8

#: the most columns (rows) between the sampled ones that :func:`no_edge_possible` chooses
SAMPLE_MAX = 64

#: rounding allowance, relative to the largest |height| of the map (the sums here and the
#: model's differ in order only: a few 1e-14 of it)
_ROUND = 1e-10


@njit(cache=True, nogil=True)
def _reference_rows(z, d, out, i0, i1):
    """Rows i0 .. i1 - 1 of the statistics of :func:`_reference_stats`: out[i] = (min and
    max of z - d, max |z| on row i, max |mixed second difference of d| between rows i and
    i + 1, NaN seen: 1 or 0)."""
    ny, nx = z.shape
    for i in range(i0, i1):
        lo = np.inf
        hi = -np.inf
        za = 0.0
        mixed = 0.0
        bad = 0.0
        for j in range(nx):
            v = z[i, j]
            e = v - d[i, j]
            if e != e:
                bad = 1.0
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
                    bad = 1.0
                if m > mixed:
                    mixed = m
        out[i, 0] = lo
        out[i, 1] = hi
        out[i, 2] = za
        out[i, 3] = mixed
        out[i, 4] = bad


def _reference_stats(z: np.ndarray, d: np.ndarray) -> tuple[float, float, float, float]:
    """(min of z - d, max of z - d, max |z|, max |mixed second difference of d|), NaN
    where any of them is NaN; rows on threads."""
    out = np.empty((z.shape[0], 5))
    over_rows(_reference_rows, z.shape[0], z, d, out)
    if out[:, 4].any():
        return math.nan, math.nan, math.nan, math.nan
    return (float(out[:, 0].min()), float(out[:, 1].max()), float(out[:, 2].max()),
            float(out[:, 3].max()))


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _line_max(u, w, v, p0, p1, a, n_pix, span, c):
    """One line of the sampled bound: ``u`` (the line smoothed across it, on its pixels
    a - r .. a + v.size + r - 1, clamped at its ends) smoothed along it into ``v`` (its
    pixels a ..), then the largest (1 + c)|D1| + c|D2| at its pixels p0 .. p1 - 1 (inf
    where NaN), the steps D1 and D2 read as the edge search reads them on a line of
    ``n_pix`` pixels: the nearest step inside where one lies beyond the ends."""
    r = (w.size - 1) // 2
    for i in range(v.size):
        acc = 0.0
        for t in range(2 * r + 1):
            acc += w[t] * u[i + t]
        v[i] = acc
    n = n_pix - 1
    best = 0.0
    for p in range(p0, p1):
        h1 = min(max(p + span - 1, 0), n - 1) - a
        h2 = min(max(p + 2 * span - 1, 0), n - 1) - a
        l1 = min(max(p - span, 0), n - 1) - a
        l2 = min(max(p - 2 * span, 0), n - 1) - a
        d1 = (v[h1 + 1] - v[h1]) - (v[l1 + 1] - v[l1])
        d2 = (v[h2 + 1] - v[h2]) - (v[l2 + 1] - v[l2])
        g = (1.0 + c) * abs(d1) + c * abs(d2)
        if not (g <= best):
            best = g if g == g else np.inf
    return best


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _sampled_max(z, w, r0, r1, qs, span, c, best, k0, k1):
    """best[s] = max over p in [r0, r1) of (1 + c)|D1| + c|D2| along axis 0 at the column
    qs[s] of z smoothed by w along both axes (clamped at z's ends), D1 and D2 the step
    differences the edge bound reads (:func:`~._burr_kernels._candidate`); columns
    s = k0 .. k1 - 1 of ``qs``."""
    ny, nx = z.shape
    r = (w.size - 1) // 2
    a = max(r0 - 2 * span, 0)           # rows of the smoothed map read: [a, b)
    b = min(r1 + 2 * span, ny)
    n = b - a
    ns = k1 - k0
    u = np.empty((ns, n + 2 * r))
    for i in range(n + 2 * r):          # along axis 1 at the columns qs, rows a - r .. b + r
        row = z[min(max(a - r + i, 0), ny - 1)]
        for s in range(ns):
            q = qs[k0 + s]
            acc = 0.0
            if q - r >= 0 and q + r < nx:
                seg = row[q - r:q + r + 1]
                for j in range(2 * r + 1):
                    acc += w[j] * seg[j]
            else:
                for j in range(2 * r + 1):
                    acc += w[j] * row[min(max(q - r + j, 0), nx - 1)]
            u[s, i] = acc
    v = np.empty(n)
    for s in range(ns):                 # then along axis 0
        best[k0 + s] = _line_max(u[s], w, v, r0, r1, a, ny, span, c)


@njit(cache=True, nogil=True, fastmath={"reassoc", "contract"})
def _sampled_max_rows(z, w, c0, c1, ps, span, c, best, k0, k1):
    """:func:`_sampled_max` along axis 1: best[s] the max over q in [c0, c1) at the row
    ps[s] (the map read along its rows); rows s = k0 .. k1 - 1 of ``ps``."""
    ny, nx = z.shape
    r = (w.size - 1) // 2
    a = max(c0 - 2 * span, 0)
    b = min(c1 + 2 * span, nx)
    n = b - a
    u = np.empty(n + 2 * r)
    v = np.empty(n)
    # columns a - r .. b + r - 1 of the map: those inside, and how many lie beyond each end
    ja, jb = max(a - r, 0), min(b + r, nx)
    left, right = ja - (a - r), (b + r) - jb
    for s in range(k0, k1):
        p = ps[s]
        u[:] = 0.0
        for t in range(2 * r + 1):      # along axis 0 at row p, columns a - r .. b + r
            row = z[min(max(p - r + t, 0), ny - 1)]
            wt = w[t]
            inside = row[ja:jb]
            us = u[left:left + jb - ja]
            for j in range(jb - ja):
                us[j] += wt * inside[j]
            for j in range(left):
                u[j] += wt * row[0]
            for j in range(right):
                u[left + jb - ja + j] += wt * row[nx - 1]
        best[s] = _line_max(u, w, v, c0, c1, a, nx, span, c)  # then along axis 1


def _sampled(kernel, z, w, lo: int, hi: int, lines: np.ndarray, span: int, c: float) -> float:
    """The largest bound of ``kernel`` (:func:`_sampled_max` or :func:`_sampled_max_rows`)
    over its sampled ``lines``, run on threads."""
    best = np.empty(lines.size)
    over_rows(kernel, lines.size, z, w, lo, hi, lines, span, c, best)
    g = float(best.max())
    return g if g == g else math.inf


def _samples(c0: int, c1: int, sample: int = SAMPLE) -> np.ndarray:
    q = np.arange(c0, c1, sample, dtype=np.int64)
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
                     span: int, lim: float, eps: float, rel: float, sample: int | None = SAMPLE,
                     ends: bool = False) -> bool:
    """Whether no pixel of ``window`` (first row, end row, first column, end column) of the
    block ``z`` can be a candidate edge of :func:`~._burr_kernels.edge_turn_window` on z
    smoothed by the weights ``w`` (the model's: no pixel passes the bound ``g + rel m +
    eps < lim`` of :func:`~._burr_kernels._candidate` along either axis).  ``reference``:
    a map of the block close to z (the design; any finite map gives a valid answer, a
    close one a useful one).  False where it cannot tell (the smoothing or the tests would
    reach the block's ends and ``ends`` is False, a NaN).  ``ends``: z is the whole map the
    model smooths (clamped at its ends), and the window may reach them.  ``sample``:
    columns (rows) between the sampled ones (None: chosen along each axis from the margin
    that lines :data:`SAMPLE_MAX` apart leave, :func:`_axis_holds`)."""
    z = np.ascontiguousarray(z, dtype=np.float64)
    d = np.ascontiguousarray(reference, dtype=np.float64)
    ny, nx = z.shape
    r0, r1, c0, c1 = (int(v) for v in window)
    r = (w.size - 1) // 2
    reach = 2 * span + r
    inside = r0 - reach >= 0 and r1 + reach <= ny and c0 - reach >= 0 and c1 + reach <= nx
    if d.shape != z.shape or r1 <= r0 or c1 <= c0 or r0 < 0 or c0 < 0 or r1 > ny or c1 > nx \
            or not (inside or ends) or ny < 3 or nx < 3:
        return False
    lo, hi, za, mixed = _reference_stats(z, d)
    if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(mixed)):
        return False
    half = (hi - lo) / 2 * (1 + 1e-12)      # |e - middle| <= half
    total_var = float(np.abs(np.diff(np.concatenate(([0.0], w, [0.0])))).sum())
    wsum = float(np.abs(w).sum())
    c = (span - 0.5) / span
    # the most D1 and D2 change from one column to the next (the same across rows); with
    # the ends read, each of the two steps of D folded onto the end pixels: at most T each
    lip = [(float(np.abs(np.convolve(_stencil(span, far), w)).sum()) if inside else 2.0 * total_var)
           * total_var * wsum * half + wsum * wsum * 2.0 * mixed for far in (False, True)]
    step = (1.0 + c) * lip[0] + c * lip[1]
    # rounding: the sums' order; the model's margin rel * m with m <= 4 * 2 max|z|
    base = _ROUND * za + 8.0 * rel * za + eps
    return (_axis_holds(_sampled_max, z, w, (r0, r1), (c0, c1), span, c, step, base, lim, sample)
            and _axis_holds(_sampled_max_rows, z, w, (c0, c1), (r0, r1), span, c, step, base, lim, sample))


def _axis_holds(kernel, z, w, along: tuple[int, int], across: tuple[int, int], span: int, c: float,
                step: float, base: float, lim: float, sample: int | None) -> bool:
    """Whether the bound of ``kernel`` on the pixels ``along`` of the lines sampled
    ``sample`` apart across ``across`` (allowing ``step`` for each line between a pixel's
    and the nearest sampled one, and ``base``) stays below ``lim``.  ``sample`` None:
    the lines :data:`SAMPLE_MAX` apart first, then as far apart (down to :data:`SAMPLE`)
    as keeps the allowance within three quarters of the margin they leave, the lines not
    read yet added; refused at once where the first lines leave too little."""
    lo, hi = along
    if sample is not None:
        allow = (int(sample) // 2) * step + base
        return allow < lim and _sampled(kernel, z, w, lo, hi, _samples(*across, int(sample)), span, c) \
            + allow < lim
    if not (SAMPLE // 2) * step + base < lim:
        return False
    coarse = _samples(*across, SAMPLE_MAX)
    g = _sampled(kernel, z, w, lo, hi, coarse, span, c)
    s = SAMPLE_MAX
    while s > SAMPLE and not (s // 2) * step <= 0.75 * (lim - base - g):
        s //= 2
    if not g + (s // 2) * step + base < lim:
        return False
    if s < SAMPLE_MAX:
        rest = np.setdiff1d(_samples(*across, s), coarse)
        if rest.size:
            g = max(g, _sampled(kernel, z, w, lo, hi, rest, span, c))
    return g + (s // 2) * step + base < lim
