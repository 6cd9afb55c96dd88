"""The envelope kernel's per-pixel step, written once for the CPU and the GPU kernels.

The step (the segment lookup, the pass loop, the pass windows and the step itself) is a
set of plain functions compiled twice: here with ``numba.njit`` for the CPU kernels
(:mod:`._envelope`), and in :mod:`._envelope_gpu` with ``numba.cuda.jit(device=True)``
for the GPU kernel (:data:`DEVICE_FUNCTIONS`, in the order they call each other, rebuilt
there from this module's names).  The pass lookup (:func:`_lookup_bin`) also serves the
cutting-mechanics kernels.  The model and the pass window are described in
:mod:`._envelope`.
"""

from __future__ import annotations

import math

from ..core.lazy import njit

TWO_PI = 2 * math.pi
INV_2PI = 1.0 / TWO_PI


# ------------------------------------------------------------------ the per-pixel step
# The fast kernel's per-pixel step is written once, as the plain functions below (the
# segment lookup, the pass loop, the pass windows and the step itself), and compiled
# twice: here with numba.njit for the CPU kernels, and in ``_envelope_gpu`` with
# numba.cuda.jit(device=True) for the GPU kernel (:data:`DEVICE_FUNCTIONS`, in the order
# they call each other).  Only the loop over the pixels differs between the targets: the
# CPU walks square blocks and steps the polar angle by a series, a GPU thread takes one
# pixel and an exact atan2.  The functions use only what both targets compile (scalars,
# 1-D / 2-D float and int arrays, math, tuples).

def _lookup_bin(theta, tab, b, s):
    """Index i with theta[i] <= s <= theta[i + 1] (s inside the path), found from bin ``b``
    of the lookup table (:func:`_lookup_table`; clamped to the table) and a walk.

    The pass lookup of every kernel (the envelope's and the cutting mechanics'); each
    caller computes the bin from the angle with its own arithmetic (:func:`_lookup`
    divides by the bin width, the cutting kernel multiplies by its reciprocal), kept as it
    was because the bin decides which of two segments a pass exactly on a path point
    gets."""
    if b < 0:
        b = 0
    if b >= tab.size:
        b = tab.size - 1
    i = tab[b]
    n = theta.size
    while i < n - 2 and theta[i + 1] < s:
        i += 1
    while i > 0 and theta[i] > s:
        i -= 1
    return i


def _lookup(theta, tab, tab_t0, tab_w, s):
    """Index i with theta[i] <= s <= theta[i + 1] (s inside the path): :func:`_lookup_bin`
    from the bin (s - tab_t0) / tab_w."""
    return _lookup_bin(theta, tab, int((s - tab_t0) / tab_w), s)


def _edge_dz(edge, sd):
    """Height (mm) of a measured edge above the circular nose arc at the signed radial
    offset ``sd`` from the tool axis: the table of ``EdgeProfile.height_table``
    ([d0, 1 / step, lowest, g_0 ..]) linearly interpolated (0 for the empty table)."""
    n = edge.size - 3
    if n < 2:
        return 0.0
    u = (sd - edge[0]) * edge[1]
    if u <= 0.0:
        return edge[3]
    if u >= n - 1:
        return edge[n + 2]
    k = int(u)
    t = u - k
    return edge[3 + k] + t * (edge[4 + k] - edge[3 + k])


def _passes_lookup(seg, theta, tab, tab_t0, tab_w, j0, kmax, K, phi, sr, Rc, Rc2, hw, best, win,
                   edge):
    """:func:`_passes` on a path of varying angle steps: each pass's segment by the lookup
    table (compiled once, called by the step's copies of :func:`_passes`)."""
    nseg = seg.shape[0]
    t_first = theta[0]
    t_last = theta[nseg]
    for k in range(K):
        s = phi + TWO_PI * (j0 + k)
        if s >= t_first and s <= t_last:
            ii = _lookup(theta, tab, tab_t0, tab_w, s)
            dt = theta[ii + 1] - theta[ii]
            fr = (s - theta[ii]) / dt if dt > 0 else 0.0
            rj = seg[ii, 0] + fr * seg[ii, 1]
            d = abs(sr - rj)
            if d <= hw:
                zj = seg[ii, 2] + fr * seg[ii, 3] + Rc - math.sqrt(Rc2 - d * d)
                if edge.size > 0:
                    zj += _edge_dz(edge, sr - rj)
                best = min(best, zj)
                if k <= kmax:
                    win = min(win, zj)
    return best, win


def _passes(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a, icc,
            jw, K, phi, r, sgn, Rc, Rc2, hw, best, win, edge):
    """Lowest nose arc at (sgn r, phi) over K consecutive passes, the first being the first
    within ``jw`` revolutions of the pass whose nominal radius is sgn r: (lowest over the
    K passes, lowest over those within the window)."""
    jc = (t0 + (a - r * sgn) * icc - phi) * INV_2PI
    # (int(): numba.cuda's floor and ceil of a float are floats, the CPU target's ints)
    j0 = int(math.ceil(jc - jw))
    kmax = int(math.floor(jc + jw)) - j0
    sr = sgn * r
    nseg = seg.shape[0]
    if uniform:
        # pass j0 + k sits k revolutions = k nrev points after pass j0, at the same fraction
        u = (phi - t0) * inv
        fl = math.floor(u)
        g0 = int(fl) + j0 * nrev
        fr0 = u - fl
        for k in range(K):
            g = g0 + k * nrev
            fr = fr0
            # a pass through an end point of the path: rounding may put it one segment out
            if g == -1 and fr > 1.0 - 1e-9:
                g = 0
                fr = 0.0
            elif g == n_total - 1 and fr < 1e-9:
                g = n_total - 2
                fr = 1.0
            ii = g - offset
            if g >= 0 and g < n_total - 1 and ii >= 0 and ii < nseg:
                rj = seg[ii, 0] + fr * seg[ii, 1]
                d = abs(sr - rj)
                if d <= hw:
                    zj = seg[ii, 2] + fr * seg[ii, 3] + Rc - math.sqrt(Rc2 - d * d)
                    if edge.size > 0:
                        zj += _edge_dz(edge, sr - rj)
                    best = min(best, zj)
                    if k <= kmax:
                        win = min(win, zj)
    else:
        best, win = _passes_lookup(seg, theta, tab, tab_t0, tab_w, j0, kmax, K, phi, sr, Rc, Rc2, hw,
                                   best, win, edge)
    return best, win


def _passes_call(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a, icc,
                 jw, K, phi, r, sgn, Rc, Rc2, hw, best, win, edge):
    """:func:`_passes`'s code under a name of its own, compiled as a function that the
    per-pixel step calls rather than copies into itself: for the rare pixels that no pass
    of the window reaches (beyond the path's ends), so that the step's compiled body holds
    two copies of the pass loop, not four (the kernels' first compile takes a fraction of
    the time; the arithmetic is the same, so are the heights, bit for bit)."""


_passes_call.__code__ = _passes.__code__.replace(co_name="_passes_call")


def _pass_windows(cc, Wd, f, hw, dev):
    """The pass windows in revolutions: (1 / cc, the proven window, the window near the
    axis where the spiral ends, every pass that reaches)."""
    icc = 1.0 / cc
    jw_a = Wd * icc * INV_2PI
    jw_b = (Wd + 0.5 * f) * icc * INV_2PI
    jw_c = (hw + dev) * icc * INV_2PI
    return icc, jw_a, jw_b, jw_c


def _pass_count(jw):
    """Passes visited for a window of ``jw`` revolutions on each side (fixed per kernel)."""
    return int(math.floor(2.0 * jw)) + 1


def _pixel_height(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a,
                  icc, dev, f, Rc, Rc2, hw, Wd, jw_a, jw_b, jw_c, K_a, K_b, K_c, phi, r, edge):
    """Machined height at the pixel at radius ``r`` and polar angle ``phi`` (NaN where no
    pass reaches): the passes in the proven window on this side of the axis, on the far
    side near the axis, and every pass that reaches where the window holds none."""
    near = r < 2.0 * f + dev
    Wp = Wd + 0.5 * f if near else Wd
    jw = jw_b if near else jw_a
    K = K_b if near else K_a
    best, win = _passes(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a,
                        icc, jw, K, phi, r, 1.0, Rc, Rc2, hw, math.inf, math.inf, edge)
    phi2 = phi + math.pi
    if phi2 >= TWO_PI:
        phi2 -= TWO_PI
    if r < Wp + hw:
        best, win = _passes(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0,
                            a, icc, jw, K, phi2, r, -1.0, Rc, Rc2, hw, best, win, edge)
    if win == math.inf and Wp < hw + dev:
        # no pass within the window (beyond the path's ends): every pass that reaches
        best, win = _passes_call(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0,
                                 a, icc, jw_c, K_c, phi, r, 1.0, Rc, Rc2, hw, best, win, edge)
        if r < hw + dev:
            best, win = _passes_call(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total,
                                     t0, a, icc, jw_c, K_c, phi2, r, -1.0, Rc, Rc2, hw, best, win, edge)
    return best if best < math.inf else math.nan


#: the functions of the per-pixel step, in the order they call each other
DEVICE_FUNCTIONS = ("_lookup_bin", "_lookup", "_edge_dz", "_passes_lookup", "_passes", "_passes_call", "_pass_windows", "_pass_count", "_pixel_height")
_lookup_bin = njit(cache=True, inline="always")(_lookup_bin)
_lookup = njit(cache=True, inline="always")(_lookup)
_edge_dz = njit(cache=True, inline="always")(_edge_dz)
_passes_lookup = njit(cache=True, nogil=True)(_passes_lookup)
_passes = njit(cache=True, inline="always")(_passes)
_passes_call = njit(cache=True, nogil=True)(_passes_call)
_pass_windows = njit(cache=True, inline="always")(_pass_windows)
_pass_count = njit(cache=True, inline="always")(_pass_count)
_pixel_height = njit(cache=True, inline="always")(_pixel_height)
