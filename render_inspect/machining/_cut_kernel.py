"""The fast, tileable kernel of the cutting mechanics: the model of :mod:`._cutting` (minimum
chip thickness, elastic recovery, side flow, the grooves of the cutting edge) computed pixel
by pixel in row blocks or tiles.

Per pixel it visits the same passes in the same (time) order as the direct kernel of
:func:`~render_inspect.machining.cut_turning_mechanics` (the passes whose nominal radius lies
within the mechanics window of the pixel, on both sides of the axis near it, every pass that
reaches where the window holds none) and applies the same state machine, so the machined
height, the cutting pass and the displaced material are those of the direct model.  What
makes it fast:

- no pass buffers away from the axis: the passes of one side are already in time order and
  go straight through the state machine (where the far side's passes reach the window
  too, both sides are gathered and merged by time, as in the direct kernel);
- the polar angle advances along a row with the series of the angle difference (one exact
  ``atan2`` at each 64-pixel block of the whole grid, as the envelope kernel does), so a
  tile or a row block gets the very angles of a whole-grid run;
- the grooves (:func:`~render_inspect.machining.groove_texture`: 128 random Fourier modes)
  are summed in the kernel, at the pixel's edge position and cutting distance, in one SIMD
  pass (x = k pi + r with pi in two parts, a minimax polynomial of cos r to r^16, the sign
  from k's parity: each cosine within 3e-16 of numpy's, the 128 modes' sum within 2^-52
  sum |cos| of numpy's, tested), instead of 128 passes over whole-map arrays;
- the cutting distance of the cutting pass comes from the pass's own segment and fraction;
  a pass whose arc provably stays h_min above the surface so far skips its square root;
- passes that provably change nothing are not looked up at all (away from the axis): the
  path's least and largest change of the tip's height from one revolution to the next at
  one angle (``CutPath.z_rev``) bound every pass's arc from one pass looked up and the
  nominal spiral, so the passes before the last one outside the pixel are skipped where each lies
  h_min above that pass's arc (that pass then cuts whatever they left, and the state
  after it is the same), and the passes after the cut where each lies h_min above the
  surface (from one such pass on, the bound only grows).  The maps are those of visiting
  every pass (tested; half the true change is tested to change pixels); the window's end
  passes come from products with 1 / cc (the division decides within 1e-6 of a whole
  pass).  The shipped grid's 16 M-pixel cut takes about a quarter less CPU time;
- each pass's segment is looked for first where the same pass was at the previous pixel
  (a segment that holds the pass's angle strictly inside is the only one that can hold
  it, so the table's bin and walk, which decide a pass on a path point, are only needed
  where that fails: about 1 pass in 100), and the pass loop is written in the row loop (no
  call and no reference counting per pixel) with unsigned indices (no wrap-around);
- each pixel's angle, radius and pass window are computed one pixel ahead, so that their
  chain of dependent operations (a division, a square root, the window's floors) runs
  beside the passes of the pixel before instead of after them, and the window's ends are
  tested for nearness to a whole pass without a round trip through an integer: the same
  numbers, about a quarter less CPU time on the shipped grid.

A measured cutting edge adds its height table to each arc as in the envelope kernel (the
pass skip's lower bound takes the table's lowest entry), and a tool wearing along the path
gives each pass its own minimum chip thickness (``CutPath.h_seg``, by segment).

The kernel runs on rows ``row0 .. row1`` and columns ``col0 .. col1`` of the whole grid, so
:func:`cut_fill` can be called block after block (progress, interruption) or on one tile
with :meth:`CutPath.slice_for` (the passes that reach it).  Every pixel depends only on the
path and its own position: a tile, with or without a halo, equals the same pixels of the
whole-grid run bit for bit (tested).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from ..core.lazy import njit  # numba, imported on first use
# (the largest |argument| the two-part reduction keeps exact: ARG_MAX)
from ._cut_grooves import _COS_ARG_MAX, _groove_sum, _groove_sum_libm
from ..core.threads import over_rows

from ..core.progress import report
from ..core.toolpath import ToolPath
from ._cut_inputs import Grooves, cutting_distance, mechanics_window
from ._cut_path import CutPath, _cut_direct, prepare_cut
from ._cut_window import _head_covered, _window, _window_near
from ._envelope import BLOCK, _polar_step
from ._envelope_step import _edge_dz, _lookup_bin

__all__ = ["CutPath", "Grooves", "prepare_cut", "cut_fill", "cut_turning", "cutting_distance",
           "mechanics_window", "load_cut_kernels", "OUT_CHANNELS", "BLOCK_SAMPLES"]

TWO_PI = 2 * math.pi
INV_2PI = 1.0 / TWO_PI
#: the maps :func:`cut_fill` writes (each (rows, cols) float64)
OUT_CHANNELS = ("machined", "pass_theta", "added")
#: passes a pixel may gather on one side of the axis (the direct kernel's cap)
_MAX_BUF = 1_000_000  # not a unit conversion
#: the relative widening of the path's height change per revolution for rounding
_WIDEN = 1e-9  # not a unit conversion
#: a pixel's state before its first pass (:func:`_step`; a global: one type, not literals)
_STATE0 = (math.inf, math.nan, math.nan, -1, 0.0, math.nan, 0.0, False)
#: passes whose segments a pixel remembers for the next pixel (a power of 2: slot j % _SEEN),
#: the steps walked from a remembered segment, and the pass of a slot that holds none
_SEEN = 64
_WALK = 4
_NO_PASS = -(1 << 62)
#: unsigned indices (no negative-index wrap-around in the pixel loop)
_U1, _U2, _U3, _U4 = np.uint64(1), np.uint64(2), np.uint64(3), np.uint64(4)


# ------------------------------------------------------------------ the kernel
@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _segment(theta, tab, tab_t0, tab_iw, s, j, seen):
    """:func:`_lookup_bin`'s segment of the pass at cumulative angle s (pass j): first the
    segment pass j had at the previous pixel (``seen``: pass and segment in slots
    2 (j % _SEEN), 2 (j % _SEEN) + 1, one array per side of the axis).  A segment that holds
    s strictly inside is the only one that can hold it, so only a pass on a path point (or
    beyond the path's ends, or away from the segment remembered) takes the table."""
    k = 2 * (j & (_SEEN - 1))
    if seen[k] == j:
        i = seen[k + 1]
        u = np.uint64(i)
        if theta[u] < s < theta[u + _U1]:
            return i
    return _segment_walk(theta, tab, tab_t0, tab_iw, s, j, seen, k)


@njit(cache=True, nogil=True, error_model="numpy")
def _segment_walk(theta, tab, tab_t0, tab_iw, s, j, seen, k):
    """:func:`_segment` past the remembered segment: a walk of at most _WALK segments from
    it to one that holds s strictly inside, else the table's bin and walk."""
    if seen[k] == j:
        i = seen[k + 1]
        lo = max(i - _WALK, 0)
        hi = min(i + _WALK, theta.size - 2)
        while True:
            t0 = theta[np.uint64(i)]
            if s <= t0:
                if s == t0 or i <= lo:
                    break
                i -= 1
            else:
                t1 = theta[np.uint64(i) + _U1]
                if s < t1:
                    seen[k + 1] = i
                    return i
                if s == t1 or i >= hi:
                    break
                i += 1
    i = _lookup_bin(theta, tab, int((s - tab_t0) * tab_iw), s)
    seen[k] = j
    seen[k + 1] = i
    return i


@njit(cache=True, nogil=True, inline="always", error_model="numpy")
def _locate(theta, tab, tab_t0, tab_iw, seg, s, sgn, r, j, seen):
    """(segment, fraction, nominal radius, distance from the pixel at sgn r, tool tip height)
    of pass j at cumulative angle s (``seg``: each segment's rho, d rho, z, d z in turn; the
    envelope's pass lookup from the bin (s - tab_t0) * tab_iw, ``tab_iw`` the reciprocal of
    the table's bin width: :func:`_segment`)."""
    i = _segment(theta, tab, tab_t0, tab_iw, s, j, seen)
    u = np.uint64(i)
    t0 = theta[u]
    dt = theta[u + _U1] - t0
    fr = (s - t0) / dt if dt > 0 else 0.0
    q = u * _U4
    rj = seg[q] + fr * seg[q + _U1]
    return i, fr, rj, sgn * r - rj, seg[q + _U2] + fr * seg[q + _U3]


@njit(cache=True, nogil=True, error_model="numpy")
def _pass_at(theta, tab, tab_t0, tab_iw, seg, s, sgn, r, hw, Rc, Rc2, edge, j, seen):
    """(in reach, arc height, tool radius, signed edge position, segment, fraction) of the
    pass at cumulative angle s for the pixel at sgn r (the direct kernel's arithmetic; the
    measured edge's height table ``edge`` added where given)."""
    i, fr, rj, d, zt = _locate(theta, tab, tab_t0, tab_iw, seg, s, sgn, r, j, seen)
    if abs(d) <= hw:
        zj = zt + Rc - math.sqrt(Rc2 - d * d)
        if edge.size > 0:
            zj += _edge_dz(edge, d)
        return True, zj, rj, d * sgn, i, fr
    return False, 0.0, 0.0, 0.0, 0, 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _step(st, sj, zj, ij, frj, dj, h_min, kappa, side_flow):
    """One pass through the state (surface, chip, pass angle, segment, fraction, edge
    position, added, piled) of the direct model."""
    surf, h_cut, sw, iw, fw, dw, add, piled = st
    if zj < surf:
        h = surf - zj
        if h >= h_min or surf == np.inf:
            return zj, h, sj, ij, frj, dj, 0.0, False
        return zj + kappa * h, h_cut, sw, iw, fw, dw, kappa * h, piled
    if side_flow and not piled:
        g = zj - surf
        if g < h_min:
            p = (1.0 - kappa) * (h_min - g)
            return surf + p, h_cut, sw, iw, fw, dw, add + p, True
    return st


@njit(cache=True, nogil=True, error_model="numpy")
def _gather(theta, tab, tab_t0, tab_iw, seg, t_first, t_last, a, cc, phi, r, sgn, W, Rc, Rc2, hw,
            bs, bz, bi, bf, bd, edge, seen):
    j0, j1 = _window(t_first, t_last, a, cc, phi, r, sgn, W)
    n = 0
    for j in range(j0, j1 + 1):
        if n >= bs.size:
            break
        s = phi + TWO_PI * j
        ok, zj, rj, dj, ij, frj = _pass_at(theta, tab, tab_t0, tab_iw, seg, s, sgn, r, hw, Rc, Rc2, edge, j, seen)
        if ok:
            bs[n] = s
            bz[n] = zj
            bi[n] = ij
            bf[n] = frj
            bd[n] = dj
            n += 1
    return n


@njit(cache=True, nogil=True, error_model="numpy")
def _merge(n1, n2, b1s, b1z, b1i, b1f, b1d, b2s, b2z, b2i, b2f, b2d, h_min, kappa, side_flow, st, hseg):
    """The gathered passes of both sides through the state in time order (a pass's own
    minimum chip thickness from ``hseg`` by its segment, where given)."""
    k1 = 0
    k2 = 0
    while k1 < n1 or k2 < n2:
        if k2 >= n2 or (k1 < n1 and b1s[k1] <= b2s[k2]):
            st = _step(st, b1s[k1], b1z[k1], b1i[k1], b1f[k1], b1d[k1],
                       hseg[b1i[k1]] if hseg.size > 0 else h_min, kappa, side_flow)
            k1 += 1
        else:
            st = _step(st, b2s[k2], b2z[k2], b2i[k2], b2f[k2], b2d[k2],
                       hseg[b2i[k2]] if hseg.size > 0 else h_min, kappa, side_flow)
            k2 += 1
    return st


@njit(cache=True, nogil=True, error_model="numpy")
def _cut_row(seg, theta, tab, dist, pv, side_flow, ku, kv, ph, gscale, fast_cos, x0, y, pixel, col0,
             sc0, sc1, machined, pass_theta, added, stats, bufs, ibufs, edge, hseg, seen):
    """One row (height y) of the whole grid, columns col0 .. col0 + cols - 1, into the
    row's maps; into ``stats``: over the row's columns sc0 .. sc1 - 1, the sum of the
    squared grooves, the pixels that got grooves, the largest added material.  ``pv``: the
    path's numbers in one tuple (a call of over 30 arguments compiles slowly in numba)."""
    tab_t0, tab_iw, t_first, t_last, a, cc, dev, f, Rc, hw, W, h_min, kappa, rise, fall, h_max = pv
    cols = machined.size
    # (a row of no columns: the displaced material is not kept, only its largest value)
    keep_added = added.size > 0
    Rc2 = Rc * Rc
    half_inv_rc = 0.5 / Rc
    inv_cc = 1.0 / cc
    e_low = edge[2] if edge.size > 0 else 0.0
    Wd = W + dev
    rho_end = a - cc * (t_last - t_first)
    grooves = ku.size > 0
    b1s, b1z, b1f, b1d = bufs[0], bufs[1], bufs[2], bufs[3]
    b2s, b2z, b2f, b2d = bufs[4], bufs[5], bufs[6], bufs[7]
    b1i, b2i = ibufs[0], ibufs[1]
    seen1, seen2 = seen[0], seen[1]
    c_first = (col0 // BLOCK) * BLOCK
    g2 = 0.0
    ng = 0.0
    amax = -np.inf
    phi = 0.0
    xp = 0.0
    # the head's candidate that held last (0: the last pass outside the pixel, 1: the one
    # before it), and the pixels to wait before trying again where neither held
    head_off = 0
    head_wait = 0
    proven = rise < np.inf and fall < np.inf
    # polar angle: exact at each block of the whole grid, the series step after it (from
    # the block's first column up to the row's first)
    for c in range(c_first, col0):
        x = x0 + c * pixel
        phi = _polar_step(phi, xp, x, y, c % BLOCK == 0)
        xp = x
    # each pixel's angle, radius and pass window are computed one pixel ahead: their chain
    # of dependent operations runs beside the passes of the pixel before (the same numbers)
    c_end = col0 + cols
    xn = x0 + col0 * pixel
    phin = _polar_step(phi, xp, xn, y, col0 % BLOCK == 0)
    rn = math.sqrt(xn * xn + y * y)
    Wpn = Wd + (0.5 * f if rn < 2.0 * f + dev else 0.0)
    j0n, j1n = _window_near(t_first, t_last, a, cc, inv_cc, phin, rn, Wpn)
    jcn = math.floor((t_first + (a - rn) * inv_cc - phin) * INV_2PI)
    for c in range(col0, c_end):
        phi, r, Wp, j0, j1, jcf = phin, rn, Wpn, j0n, j1n, jcn
        if c + 1 < c_end:
            x = xn
            xn = x0 + (c + 1) * pixel
            phin = _polar_step(phi, x, xn, y, (c + 1) % BLOCK == 0)
            rn = math.sqrt(xn * xn + y * y)
            Wpn = Wd + (0.5 * f if rn < 2.0 * f + dev else 0.0)
            j0n, j1n = _window_near(t_first, t_last, a, cc, inv_cc, phin, rn, Wpn)
            jcn = math.floor((t_first + (a - rn) * inv_cc - phin) * INV_2PI)
        st = _STATE0
        phi2 = phi + math.pi
        if phi2 >= TWO_PI:
            phi2 -= TWO_PI
        # the far side's passes reach the window only where r <= Wp - the nominal spiral's
        # radius at the path's end (1e-9 mm more for rounding): else this side's alone
        if r < Wp + hw and r <= Wp - rho_end + 1e-9:
            n1 = _gather(theta, tab, tab_t0, tab_iw, seg, t_first, t_last, a, cc, phi, r, 1.0, Wp, Rc,
                         Rc2, hw, b1s, b1z, b1i, b1f, b1d, edge, seen1)
            n2 = _gather(theta, tab, tab_t0, tab_iw, seg, t_first, t_last, a, cc, phi2, r, -1.0, Wp,
                         Rc, Rc2, hw, b2s, b2z, b2i, b2f, b2d, edge, seen2)
            n = n1 + n2
            st = _merge(n1, n2, b1s, b1z, b1i, b1f, b1d, b2s, b2z, b2i, b2f, b2d, h_min, kappa,
                        side_flow, st, hseg)
        else:
            # this side's passes in time order straight through the state: a pass whose arc
            # provably stays h_min above the surface so far (its tip plus d^2 / 2 Rc, a lower
            # bound of the arc, less 1e-12 mm for rounding and the measured edge's lowest
            # entry) changes nothing and skips the square root
            #
            # Two proofs skip passes without looking them up (``rise``, ``fall``: the most
            # the tip's height rises and falls from one revolution to the next at one
            # angle; a pass's distance from the pixel is at least its nominal radius' less
            # ``dev``):
            # - the head: the passes before the last one outside the pixel (jc, or the one
            #   before it) are not visited where each provably lies h_max above that pass's
            #   arc (:func:`_head_covered`): it then cuts whatever they left, its state the
            #   same (the chip thickness is not kept).  The candidate that held last is
            #   tried first; where neither holds, the next 8 pixels do not try;
            # - the tail: a pass inside the pixel whose bound from the last pass looked up
            #   (jl, tip ztl) lies h_max above the surface changes nothing, nor does any
            #   later one once the bound grows with each pass (dn f >= fall Rc).
            n = 0
            jl = j0
            ztl = 0.0
            jstart = j0
            proofs = proven and j1 - j0 + 1 < _MAX_BUF
            if proofs and head_wait > 0:
                head_wait -= 1
            elif proofs:
                jc0 = min(jcf, j1)
                for t in range(2):
                    jc = jc0 - ((head_off + t) & 1)
                    if jc <= j0:
                        continue
                    s = phi + TWO_PI * jc
                    i, fr, rj, d, zt = _locate(theta, tab, tab_t0, tab_iw, seg, s, 1.0, r, jc, seen1)
                    if not abs(d) <= hw:
                        continue
                    zj = zt + Rc - math.sqrt(Rc2 - d * d)
                    if edge.size > 0:
                        zj += _edge_dz(edge, d)
                    head_wait = 8
                    if _head_covered(j0, jc, phi, r, t_first, a, cc, dev, f, Rc, half_inv_rc, e_low, rise,
                                     zt, zj, h_max):
                        hm = hseg[i] if hseg.size > 0 else h_min
                        st = _step(st, s, zj, i, fr, d, hm, kappa, side_flow)
                        n = 1
                        jl = jc
                        ztl = zt
                        jstart = jc + 1
                        head_off = jc0 - jc
                        head_wait = 0
                        break
            for j in range(jstart, j1 + 1):
                s = phi + TWO_PI * j
                if proofs and n > 0:
                    dn = r - (a - cc * (s - t_first)) - dev - 1e-12
                    if dn > 0.0 and (ztl - (j - jl) * fall + dn * dn * half_inv_rc + e_low - 1e-12
                                     >= st[0] + h_max):
                        if dn * f >= fall * Rc:
                            break
                        continue
                i, fr, rj, d, zt = _locate(theta, tab, tab_t0, tab_iw, seg, s, 1.0, r, j, seen1)
                if abs(d) <= hw:
                    n += 1
                    jl = j
                    ztl = zt
                    hm = hseg[i] if hseg.size > 0 else h_min
                    if zt + d * d * half_inv_rc - 1e-12 + e_low >= st[0] + hm:
                        continue
                    zj = zt + Rc - math.sqrt(Rc2 - d * d)
                    if edge.size > 0:
                        zj += _edge_dz(edge, d)
                    st = _step(st, s, zj, i, fr, d, hm, kappa, side_flow)
                    if n >= _MAX_BUF:
                        break
        if n == 0 and Wp < hw + dev:
            # no pass within the window (beyond the path's ends): every pass that reaches
            n1 = _gather(theta, tab, tab_t0, tab_iw, seg, t_first, t_last, a, cc, phi, r, 1.0,
                         hw + dev, Rc, Rc2, hw, b1s, b1z, b1i, b1f, b1d, edge, seen1)
            n2 = 0
            if r < hw + dev:
                n2 = _gather(theta, tab, tab_t0, tab_iw, seg, t_first, t_last, a, cc, phi2, r, -1.0,
                             hw + dev, Rc, Rc2, hw, b2s, b2z, b2i, b2f, b2d, edge, seen2)
            st = _merge(n1, n2, b1s, b1z, b1i, b1f, b1d, b2s, b2z, b2i, b2f, b2d, h_min, kappa,
                        side_flow, st, hseg)
        surf, h_cut, sw, iw, fw, dw, add, piled = st
        ix = c - col0
        counted = sc0 <= ix < sc1
        if surf < np.inf:
            if grooves:
                v = dist[iw] + fw * (dist[iw + 1] - dist[iw])
                if fast_cos:
                    gs = _groove_sum(ku, kv, ph, dw, v) * gscale
                else:
                    gs = _groove_sum_libm(ku, kv, ph, dw, v) * gscale
                if counted:
                    g2 += gs * gs
                    ng += 1.0
                surf += gs
            machined[ix] = surf
            pass_theta[ix] = sw
            if keep_added:
                added[ix] = add
            if counted and add > amax:
                amax = add
        else:
            machined[ix] = np.nan
            pass_theta[ix] = np.nan
            if keep_added:
                added[ix] = 0.0
    stats[0], stats[1], stats[2] = g2, ng, amax


def _buffer_size(W, dev, f):
    nb = int(2 * (W + dev + f) / max(f, 1e-12)) + 8 if f > 0 else 64
    return min(nb, _MAX_BUF)


def _cut_rows(seg, theta, tab, tab_t0, tab_iw, dist, t_first, t_last, a, cc, dev, f, Rc, hw, W,
              h_min, kappa, rise, fall, h_max, side_flow, ku, kv, ph, gscale, fast_cos, x0, y0, pixel, row0, col0, sc0,
              sc1, machined, pass_theta, added, stats, edge, hseg):
    """Rows row0 .. row0 + rows - 1, columns col0 .. col0 + cols - 1 of the whole grid
    (origin (x0, y0)) into the (rows, cols) maps; per row into ``stats[row]``."""
    rows = machined.shape[0]
    nb = _buffer_size(W, dev, f)
    pv = (tab_t0, tab_iw, t_first, t_last, a, cc, dev, f, Rc, hw, W, h_min, kappa, rise, fall, h_max)
    bufs = np.empty((8, nb))
    ibufs = np.empty((2, nb), dtype=np.int64)
    # each side's passes' segments at the previous pixel: [pass, segment] (none yet)
    seen = np.zeros((2, 2 * _SEEN), dtype=np.int64)
    seen[:, 0::2] = _NO_PASS
    for k in range(rows):
        _cut_row(seg, theta, tab, dist, pv, side_flow, ku, kv, ph, gscale, fast_cos, x0, y0 + (row0 + k) * pixel,
                 pixel, col0, sc0, sc1, machined[k], pass_theta[k], added[k], stats[k], bufs, ibufs, edge, hseg,
                 seen)


#: one kernel without the GIL: on one core (tiles side by side), or on runs of rows on threads
#: (whole grids: :func:`~render_inspect.core.threads.over_rows`; numba's parallel loop took 3 x the compile)
_buffer_size = njit(cache=True)(_buffer_size)
_cut_serial = njit(nogil=True, cache=True, error_model="numpy")(_cut_rows)


def cut_fill(cp: CutPath, grooves: Grooves, origin: Sequence[float], pixel: float, out: dict, *,
             start: Sequence[int] = (0, 0), parallel: bool = True,
             stat_cols: Sequence[int] | None = None) -> np.ndarray:
    """The machined surface with the cutting mechanics and the grooves (mm), the cumulative
    spindle angle of each pixel's cutting pass (rad) and the material ploughed back or
    piled up by side flow (mm), written into ``out`` in place; NaN (0 added) where no pass
    reaches.

    Parameters
    ----------
    cp : CutPath
        The prepared path (or its slice for these pixels).
    grooves : Grooves
    origin : (x, y)
        Centre of pixel [0, 0] of the whole grid, mm.
    pixel : float
        Grid spacing, mm.
    out : dict
        ``machined``, ``pass_theta``, ``added``: (rows, cols) float64 arrays, pixels
        [start[0]:start[0] + rows, start[1]:start[1] + cols] of the whole grid; without
        ``added`` the displaced material is not written (its largest value still is).
    start : (row, col)
        Index of ``out[...][0, 0]`` in the whole grid (any: each pixel depends only on its
        position).
    parallel : bool
        Runs of rows on threads, as many as numba's parallel kernels use; False: the
        calling thread, without the GIL.
    stat_cols : (first, stop), optional
        The columns of ``out`` the returned sums cover (default: all).

    Returns
    -------
    (rows, 3) float64: per row the sum of the squared grooves (mm^2), the pixels that got
    grooves and the largest added material (mm; -inf where none).
    """
    m = out["machined"]
    rows = m.shape[0]
    sc0, sc1 = (0, m.shape[1]) if stat_cols is None else (int(stat_cols[0]), int(stat_cols[1]))
    stats = np.empty((rows, 3))
    ep = cp.ep
    if ep.cc <= 0:
        raise ValueError("cut_fill: the path must feed towards the axis (use cut_turning_mechanics)")
    gr = grooves
    fast_cos = bool(gr.ku.size == 0 or np.max(np.abs(gr.ku)) * (ep.half_width + 1.0)
                    + np.max(np.abs(gr.kv)) * float(np.max(np.abs(cp.dist))) + TWO_PI < _COS_ARG_MAX)
    pt = out["pass_theta"]
    add = out["added"] if "added" in out else np.empty((rows, 0))
    # the most the tip rises and falls in a revolution, widened for rounding (inf: unknown)
    lo, hi = (float(v) for v in cp.z_rev)
    known = math.isfinite(lo) and math.isfinite(hi)
    rise = hi + abs(hi) * _WIDEN + 1e-12 if known else math.inf
    fall = -lo + abs(lo) * _WIDEN + 1e-12 if known else math.inf
    h_max = max(cp.h_min, float(cp.h_seg.max()) if cp.h_seg.size else 0.0)

    def run(r0: int, r1: int) -> None:
        _cut_serial(ep.seg.reshape(-1), ep.theta, ep.tab, ep.tab_t0, 1.0 / ep.tab_w, cp.dist, ep.t0, ep.t_end, ep.a, ep.cc,
                    ep.dev, ep.f, ep.nose_radius, ep.half_width, ep.window, cp.h_min, cp.kappa, rise, fall, h_max,
                    cp.side_flow,
                    grooves.ku, grooves.kv, grooves.ph, float(grooves.scale), fast_cos, float(origin[0]),
                    float(origin[1]), float(pixel), int(start[0]) + r0, int(start[1]), sc0, sc1, m[r0:r1],
                    pt[r0:r1], add[r0:r1], stats[r0:r1], ep.edge, cp.h_seg)

    if parallel:
        over_rows(run, rows)
    else:
        run(0, rows)
    return stats


#: samples per row block of :func:`cut_turning` (about 0.1 s on one core): the driver
#: returns to Python between blocks, where a progress callback runs and an interrupt
#: (Ctrl-C) is raised
BLOCK_SAMPLES = 1 << 20  # not a unit conversion


def cut_turning(cp: CutPath, grooves: Grooves, *, region: Sequence[float], pixel: float,
                origin: Sequence[float] | None = None,
                progress: Callable[[int, int], Any] | None = None,
                block_samples: int = BLOCK_SAMPLES, parallel: bool = True,
                out: Sequence[np.ndarray] | None = None, keep_added: bool = True) -> dict:
    """The machined surface of ``region`` (x0, y0, x1, y1; mm) with the cutting mechanics
    and grooves, computed in row blocks.

    Parameters
    ----------
    cp : CutPath
    grooves : Grooves
    region : (x0, y0, x1, y1), mm;  pixel : float, mm
    origin : (x, y), optional
        Centre of pixel [0, 0] of the whole grid the region belongs to (default: the
        region's first pixel); the region's first pixel must lie on that grid.
    progress : callable(done, total), optional
        Called after each row block with the rows done and the rows in all; it may raise
        to stop the cut (the maps are then incomplete).  Default:
        :func:`render_inspect.core.progress.report` (the running step's bar, and a stop
        asked for by Ctrl-C or SIGTERM).
    block_samples : int
        Samples per row block (at least one row).
    parallel : bool
        All cores within each block; False: the calling thread.
    out : sequence of arrays, optional
        The maps to write, in the order of :data:`OUT_CHANNELS` (C-contiguous (ny, nx)
        float64 arrays, any contents; the first two where ``keep_added`` is False),
        returned in the result; default: new arrays.
    keep_added : bool
        Write the map of the displaced material; False: only its largest value
        (``added_max``), and the result has no ``added`` map.

    Returns
    -------
    dict
        ``machined`` (mm), ``pass_theta`` (rad, cumulative spindle angle of the cutting
        pass), ``added`` (mm; where kept): (ny, nx) float64; ``grooves_sumsq`` (mm^2), ``grooves_n``,
        ``added_max`` (mm, -inf where nothing was cut).
    """
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    if origin is None:
        origin, start = (x0, y0), (0, 0)
    else:
        start = (int(round((y0 - origin[1]) / pixel)), int(round((x0 - origin[0]) / pixel)))
    if cp.ep.cc <= 0:
        return _cut_direct(cp, grooves, region=region, pixel=pixel)
    channels = OUT_CHANNELS if keep_added else OUT_CHANNELS[:2]
    if out is None:
        maps = {k: np.empty((ny, nx)) for k in channels}
    else:
        if len(out) != len(channels):
            raise ValueError(f"cut_turning: out must hold {len(channels)} maps {channels}, got {len(out)}")
        maps = dict(zip(channels, out))
        for k, v in maps.items():
            if not (isinstance(v, np.ndarray) and v.shape == (ny, nx) and v.dtype == np.float64
                    and v.flags.c_contiguous and v.flags.writeable):
                raise ValueError(f"cut_turning: the {k} map of out must be a writeable C-contiguous float64 array of "
                                 f"shape {(ny, nx)}")
    step = max(1, int(block_samples) // max(nx, 1))
    stats = np.empty((ny, 3))
    for r0 in range(0, ny, step):
        r1 = min(r0 + step, ny)
        stats[r0:r1] = cut_fill(cp, grooves, origin, pixel, {k: v[r0:r1] for k, v in maps.items()},
                                start=(start[0] + r0, start[1]), parallel=parallel)
        # the running step's progress, and a stop asked for by a signal, between blocks
        (report if progress is None else progress)(r1, ny)
    return {**maps, "grooves_sumsq": float(stats[:, 0].sum()), "grooves_n": int(stats[:, 1].sum()),
            "added_max": float(stats[:, 2].max()) if ny else -math.inf}


def load_cut_kernels() -> None:
    """Compile (or load from numba's cache) the kernel: one call on a 2 x 2 grid of a
    three-revolution spiral (on one thread and on threads: the same kernel)."""
    theta = np.linspace(0.0, 6 * math.pi, 97)
    path = ToolPath(theta, 0.05 - 0.01 * theta / TWO_PI, np.zeros(theta.size), theta)
    cp = prepare_cut(path, nose_radius=0.1, half_width=0.05, h_min=1e-5, kappa=0.05)
    gr = Grooves.of(rms=1e-6, seed=0, modes=4)
    for par in (True, False):
        cut_fill(cp, gr, (0.0, 0.0), 0.001, {k: np.empty((2, 2)) for k in OUT_CHANNELS}, parallel=par)
