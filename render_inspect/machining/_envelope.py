"""The machined surface of a turning path: the envelope of the tool-nose arcs.

In each radial section (angle phi) the tool passes once per revolution.  Pass j is at
cumulative angle theta_j = phi + 2 pi j; between programmed points the C, X and Z axes
interpolate linearly, giving the tool tip (rho_j, z_j).  Its nose arc cuts
z_j + Rc - sqrt(Rc^2 - (r - rho_j)^2) for |r - rho_j| <= the arc's half-width, and the
machined height at (r, phi) is the minimum over all passes (Li et al. 2018 [1]_, section
3).  Turning marks (feed scallops) and, without compensation, overcut waviness come out of
this.

Only passes that can win are visited: an arc at distance d from the pixel is at least
d^2 / (2 Rc) above its tip, and tips differ by at most m |d - d0| between passes (m the
path's radial slope bound), so passes with |d| > 2 Rc m + f / 2 (f the feed per rev) never
win.  Passes on the far side of the axis (angle phi + pi) are included near the centre.

Two kernels compute this envelope:

- the fast kernel (``simulate_turning``, ``envelope_fill``) works through the grid in
  square blocks of ``BLOCK`` pixels.  It advances the polar angle along a block row with
  the angle-difference series atan(t) = t - t^3/3 + t^5/5 - t^7/7 (|t| < 0.01: truncation
  below 1e-19 rad) and one exact atan2 per block row, visits a fixed number of passes
  per pixel (the passes in the proven window, counted in revolutions from the pixel's
  nominal pass, rounded up: no data-dependent loop lengths), and, on a constant-angle
  path, finds each pass's segment by index arithmetic (pass j + 1 is N points after
  pass j and shares its interpolation fraction).  It visits a superset of the reference
  kernel's passes, so its minimum is the same (the fall-back to every pass beyond the
  path's ends is decided, as there, by the passes inside the window alone); the heights differ from the reference
  only by the rounding of the interpolation fraction (tested: |difference| < 1e-12 mm);
- the reference kernel (``simulate_turning(..., reference=True)``) is the direct
  per-pixel form, kept to check the fast one.

A measured cutting edge (``toolpath.EdgeProfile``, nose radius Rc + delta(angle)) enters
as a table of its height above the circular arc over the signed radial offset from the tool
axis (``EnvelopePath.edge``, :func:`_edge_dz`), added to each arc's height; the pass window
grows by sqrt(2 Rc (max g - min g)) for it.  Without an edge the table is empty and the
arithmetic is the circle's, bit for bit.

A tile of the grid needs only the passes whose nose arcs reach it:
``EnvelopePath.slice_for(region)`` keeps those (a contiguous run of the spiral, plus the
innermost passes for tiles near the axis) and carries the whole path's constants, so a
tile computed from its slice equals the same pixels of the whole-grid run bit for bit.

The module is a little over 600 lines on purpose: the per-pixel step, the two kernels and
the path preparation share the pass window and the nominal spiral, and the reference
kernel stays next to the fast one it checks.

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566`
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np
from numba import njit, prange

from ..core.errors import InputError
from ..core.progress import report

TWO_PI = 2 * math.pi
INV_2PI = 1.0 / TWO_PI
#: side (pixels) of the square blocks the fast kernel works through
BLOCK = 64
#: grids at least this large go to a CUDA GPU when one is present (simulate_turning)
GPU_MIN_SAMPLES = 1 << 22
#: samples of one band of rows of the CPU kernel (a fraction of a second): the progress
#: is reported, and a stop asked by a signal honoured, between bands
BAND_SAMPLES = 1 << 20  # not a unit conversion
#: relative tolerance within which a path's angles count as a uniform grid
_UNIFORM_RTOL = 1e-9  # not a unit conversion
#: the empty edge table: the circular nose
_NO_EDGE = np.zeros(0)


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


def _passes(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a, icc,
            jw, K, phi, r, sgn, Rc, Rc2, hw, best, win, edge):
    """Lowest nose arc at (sgn r, phi) over K consecutive passes, the first being the first
    within ``jw`` revolutions of the pass whose nominal radius is sgn r: (lowest over the
    K passes, lowest over those within the window)."""
    jc = (t0 + (a - r * sgn) * icc - phi) * INV_2PI
    j0 = math.ceil(jc - jw)
    kmax = math.floor(jc + jw) - j0
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
        best, win = _passes(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0,
                            a, icc, jw_c, K_c, phi, r, 1.0, Rc, Rc2, hw, best, win, edge)
        if r < hw + dev:
            best, win = _passes(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total,
                                t0, a, icc, jw_c, K_c, phi2, r, -1.0, Rc, Rc2, hw, best, win, edge)
    return best if best < math.inf else math.nan


#: the functions of the per-pixel step, in the order they call each other
DEVICE_FUNCTIONS = ("_lookup_bin", "_lookup", "_edge_dz", "_passes", "_pass_windows", "_pass_count", "_pixel_height")
_lookup_bin = njit(cache=True, inline="always")(_lookup_bin)
_lookup = njit(cache=True, inline="always")(_lookup)
_edge_dz = njit(cache=True, inline="always")(_edge_dz)
_passes = njit(cache=True, inline="always")(_passes)
_pass_windows = njit(cache=True, inline="always")(_pass_windows)
_pass_count = njit(cache=True, inline="always")(_pass_count)
_pixel_height = njit(cache=True, inline="always")(_pixel_height)


# ------------------------------------------------------------------ the reference kernel
@njit(cache=True, inline="always")
def _polar_step(phi, xp, x, y, exact):
    """The polar angle in [0, 2 pi) of (x, y), from ``phi``, that of the previous pixel
    (xp, y) of the row: atan's difference series while the step is small, the exact
    atan2 when ``exact`` or otherwise (the CPU kernels' walk along a row)."""
    dot = xp * x + y * y
    t = y * (xp - x) / dot if not exact and dot > 0 else 1.0
    if -0.01 < t < 0.01:
        t2 = t * t
        phi += t * (1.0 - t2 * (1.0 / 3.0 - t2 * (0.2 - t2 * (1.0 / 7.0))))
        if phi < 0:
            phi += TWO_PI
        elif phi >= TWO_PI:
            phi -= TWO_PI
    else:
        phi = math.atan2(y, x)
        if phi < 0:
            phi += TWO_PI
    return phi


@njit(cache=True, inline="always")
def _pass_window(theta, a, cc, phi, r, sgn, W):
    """First and last pass j (at cumulative angle phi + 2 pi j on the path) whose nominal
    radius is within W of sgn * r."""
    t_first = theta[0]
    t_last = theta[theta.size - 1]
    # nominal rho(s) = a - cc (s - t_first); want |sgn r - rho| <= W with rho >= 0
    if cc > 0:
        s_lo = t_first + (a - (r * sgn + W)) / cc
        s_hi = t_first + (a - (r * sgn - W)) / cc
    else:
        s_lo = t_first
        s_hi = t_last
    if s_lo < t_first:
        s_lo = t_first
    if s_hi > t_last:
        s_hi = t_last
    return math.ceil((s_lo - phi) / TWO_PI), math.floor((s_hi - phi) / TWO_PI)


@njit(cache=True, inline="always")
def _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, sgn, W, Rc, Rc2, hw, best, edge):
    """Visit the passes at angle phi whose nominal radius is within W of sgn * r."""
    j0, j1 = _pass_window(theta, a, cc, phi, r, sgn, W)
    for j in range(j0, j1 + 1):
        s = phi + TWO_PI * j
        i = _lookup(theta, tab, tab_t0, tab_w, s)
        dt = theta[i + 1] - theta[i]
        fr = (s - theta[i]) / dt if dt > 0 else 0.0
        rj = rho[i] + fr * (rho[i + 1] - rho[i])
        d = sgn * r - rj
        if d < 0:
            d = -d
        if d <= hw:
            zj = z[i] + fr * (z[i + 1] - z[i]) + Rc - math.sqrt(Rc2 - d * d)
            if edge.size > 0:
                zj += _edge_dz(edge, sgn * r - rj)
            if zj < best:
                best = zj
    return best


@njit(parallel=True, cache=True)
def _reference_kernel(theta, rho, z, tab, tab_t0, tab_w, a, cc, dev, f, x0, y0, pixel, nx, ny,
                     Rc, hw, W, out, edge):
    Rc2 = Rc * Rc
    Wd = W + dev
    for iy in prange(ny):
        y = y0 + iy * pixel
        for ix in range(nx):
            x = x0 + ix * pixel
            r = math.sqrt(x * x + y * y)
            phi = math.atan2(y, x)
            if phi < 0:
                phi += TWO_PI
            # near the axis the spiral ends: the nearest pass can be up to ~0.75 f away
            Wp = Wd + 0.5 * f if r < 2.0 * f + dev else Wd
            best = np.inf
            best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, Wp, Rc, Rc2, hw, best, edge)
            if r < Wp + hw:
                phi2 = phi + math.pi
                if phi2 >= TWO_PI:
                    phi2 -= TWO_PI
                best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, Wp, Rc, Rc2, hw, best, edge)
            if best == np.inf and Wp < hw + dev:
                # no pass within the window (beyond the path's ends): visit every pass that reaches
                best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, hw + dev, Rc, Rc2, hw, best, edge)
                if r < hw + dev:
                    phi2 = phi + math.pi
                    if phi2 >= TWO_PI:
                        phi2 -= TWO_PI
                    best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, hw + dev, Rc, Rc2,
                                    hw, best, edge)
            out[iy, ix] = best if best < np.inf else np.nan


def _lookup_table(theta: np.ndarray):
    n = theta.size
    span = theta[-1] - theta[0]
    nb = int(min(max(n, 16), 4_000_000))
    w = span / nb if span > 0 else 1.0
    edges = theta[0] + w * np.arange(nb)
    tab = np.clip(np.searchsorted(theta, edges, side="right") - 1, 0, max(n - 2, 0)).astype(np.int64)
    return tab, float(theta[0]), float(w)


def path_radial_slope(theta: np.ndarray, rho: np.ndarray, z: np.ndarray) -> float:
    """Largest |dz/drho| between a point and the point one revolution later (mm/mm)."""
    if theta.size < 3 or theta[-1] - theta[0] <= TWO_PI:
        return 0.0
    k = np.searchsorted(theta, theta + TWO_PI)
    ok = k < theta.size
    i = np.flatnonzero(ok)
    k = k[ok]
    # interpolate the later pass at exactly theta + 2 pi
    k0 = np.maximum(k - 1, 0)
    dt = theta[k] - theta[k0]
    fr = np.where(dt > 0, (theta[i] + TWO_PI - theta[k0]) / np.where(dt > 0, dt, 1), 0.0)
    r2 = rho[k0] + fr * (rho[k] - rho[k0])
    z2 = z[k0] + fr * (z[k] - z[k0])
    dr = np.abs(r2 - rho[i])
    dz = np.abs(z2 - z[i])
    good = dr > 0
    return float(np.max(dz[good] / dr[good])) if good.any() else 0.0


# ------------------------------------------------------------------ the fast kernel (CPU)
def _fill_impl(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a, cc,
               dev, f, Rc, hw, W, x0, y0, pixel, iy_off, ix_off, out, edge):
    ny, nx = out.shape
    Rc2 = Rc * Rc
    Wd = W + dev
    icc, jw_a, jw_b, jw_c = _pass_windows(cc, Wd, f, hw, dev)
    K_a = _pass_count(jw_a)
    K_b = _pass_count(jw_b)
    K_c = _pass_count(jw_c)
    bx = (nx + BLOCK - 1) // BLOCK
    by = (ny + BLOCK - 1) // BLOCK
    for b in prange(bx * by):
        iy0 = (b // bx) * BLOCK
        ix0 = (b % bx) * BLOCK
        ix1 = min(ix0 + BLOCK, nx)
        for iy in range(iy0, min(iy0 + BLOCK, ny)):
            y = y0 + (iy_off + iy) * pixel
            phi = 0.0
            xp = 0.0
            for ix in range(ix0, ix1):
                x = x0 + (ix_off + ix) * pixel
                r = math.sqrt(x * x + y * y)
                # polar angle: series step from the previous pixel, exact atan2 otherwise
                phi = _polar_step(phi, xp, x, y, ix == ix0)
                xp = x
                out[iy, ix] = _pixel_height(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset,
                                            n_total, t0, a, icc, dev, f, Rc, Rc2, hw, Wd, jw_a, jw_b,
                                            jw_c, K_a, K_b, K_c, phi, r, edge)


#: the fast kernel on all cores (whole grids) and on one core without the GIL (tiles run
#: side by side by a scheduler)
_fill_parallel = njit(parallel=True, cache=True)(_fill_impl)
_fill_serial = njit(nogil=True, cache=True)(_fill_impl)


@dataclass(frozen=True)
class EnvelopePath:
    """A turning path prepared for the envelope kernel (or the run of it that one tile
    needs, see :meth:`slice_for`).

    Attributes
    ----------
    seg : (m, 4) float64
        Per segment (point i to i + 1): rho_i, rho_(i+1) - rho_i, z_i, z_(i+1) - z_i (mm).
    theta : (m + 1,) float64
        Cumulative angle of the segment ends (rad).
    tab, tab_t0, tab_w
        Lookup table from angle to segment (paths that are not constant-angle).
    uniform : bool
        Constant-angle path with a whole number ``nrev`` of points per revolution.
    inv : float
        1 / angle step (uniform paths), 1/rad.
    nrev : int
        Points per revolution (uniform paths).
    offset : int
        Index of ``seg[0]`` in the whole path.
    n_total : int
        Points of the whole path.
    t0, t_end, a, cc, dev, f : float
        The whole path's first and last angle (rad), first radius (mm), radial feed per radian
        (mm/rad), largest deviation from the nominal spiral (mm) and feed per revolution (mm).
    nose_radius, half_width, window : float
        Rc, the nose arc's radial half-width and the proven pass window (mm).
    edge : float64 array
        The measured edge's height table (``EdgeProfile.height_table``); empty: the
        circular nose.
    """

    seg: np.ndarray
    theta: np.ndarray
    tab: np.ndarray
    tab_t0: float
    tab_w: float
    uniform: bool
    inv: float
    nrev: int
    offset: int
    n_total: int
    t0: float
    t_end: float
    a: float
    cc: float
    dev: float
    f: float
    nose_radius: float
    half_width: float
    window: float
    edge: np.ndarray = field(default_factory=lambda: _NO_EDGE)

    def reach(self, rmin: float, rmax: float) -> float:
        """Largest radial distance (mm) between a pixel at rmin <= r <= rmax from the axis
        and a pass the kernel may visit there."""
        Wp = self.window + self.dev + 0.5 * self.f
        rho_in = self.a - self.cc * (self.t_end - self.t0)
        if Wp + self.dev <= self.half_width and rmin - Wp >= rho_in and rmax + Wp <= self.a:
            # a pass within the window always reaches: no pixel falls back to every pass
            return Wp + 2.0 * self.f
        return max(Wp, self.half_width + self.dev) + 2.0 * self.f

    def slice_for(self, region) -> "EnvelopePath":
        """The passes whose nose arcs can reach ``region`` (x0, y0, x1, y1; mm)."""
        x0, y0, x1, y1 = region
        rmax = max(math.hypot(x, y) for x in (x0, x1) for y in (y0, y1))
        rmin = math.hypot(min(max(0.0, x0), x1), min(max(0.0, y0), y1))
        R = self.reach(rmin, rmax)
        hi = rmax + R
        lo = rmin - R if rmin > R + self.half_width else -math.inf  # far side of the axis
        # nominal radius a - cc (s - t0) -> angle s
        s_lo = self.t0 + (self.a - hi) / self.cc - TWO_PI
        s_hi = self.t0 + (self.a - lo) / self.cc + TWO_PI if math.isfinite(lo) else math.inf
        th = self.theta
        i0 = max(int(np.searchsorted(th, s_lo, side="right")) - 2, 0)
        i1 = min(int(np.searchsorted(th, s_hi, side="left")) + 2, th.size - 1) if math.isfinite(s_hi) \
            else th.size - 1
        i1 = max(i1, i0 + 1)
        theta = th[i0:i1 + 1]
        seg = self.seg[i0:i1]
        if self.uniform:
            tab, tt0, tw = self.tab, self.tab_t0, self.tab_w
        else:
            tab, tt0, tw = _lookup_table(theta)
        return replace(self, seg=np.ascontiguousarray(seg), theta=np.ascontiguousarray(theta), tab=tab,
                       tab_t0=tt0, tab_w=tw, offset=self.offset + i0)

    @property
    def nbytes(self) -> int:
        return int(self.seg.nbytes + self.theta.nbytes + self.tab.nbytes + self.edge.nbytes)


def _nose_arc(nose_radius, half_width=None):
    """(Rc, radial half-width of the nose arc), mm: the half-width is at most Rc, and Rc
    when not given."""
    Rc = float(nose_radius)
    return Rc, min(float(half_width) if half_width is not None else Rc, Rc)


def _nominal_spiral(theta, rho):
    """The nominal spiral through the path's ends, rho = a - cc (theta - theta[0]), that the
    pass windows are counted on: (a, cc, dev, f) = first radius (mm), radial feed per
    radian (mm/rad), the path's largest deviation from it (mm), feed per revolution (mm)."""
    span = theta[-1] - theta[0]
    cc = (rho[0] - rho[-1]) / span if span > 0 else 0.0
    a = float(rho[0])
    dev = float(np.max(np.abs(rho - (a - cc * (theta - theta[0])))))
    return a, cc, dev, abs(cc) * TWO_PI


def edge_window(window: float, nose_radius: float, half_width: float, edge) -> float:
    """The pass window (mm) widened for a measured edge: an arc at distance d is at least
    d^2 / (2 Rc) + min(g) above its tip (g the edge's height table), so the proven window
    grows by sqrt(2 Rc (max g - min g)); unchanged for the circular nose."""
    if edge is None or edge.size == 0:
        return window
    g = edge[3:]
    return min(half_width, window + math.sqrt(2.0 * nose_radius * float(g.max() - g.min())))


def edge_table(edge, nose_radius: float, half_width: float) -> np.ndarray:
    """The kernels' table of ``edge`` (an ``EdgeProfile``, a ready table, or None)."""
    if edge is None:
        return _NO_EDGE
    if isinstance(edge, np.ndarray):
        return np.ascontiguousarray(edge, dtype=np.float64)
    return edge.height_table(nose_radius, half_width)


def prepare_envelope(path, *, nose_radius: float, half_width: float | None = None,
                     slope_bound: float | None = None, window: float | None = None,
                     edge=None) -> EnvelopePath:
    """Prepare a turning path for :func:`envelope_fill` (see :func:`simulate_turning` for
    the parameters)."""
    theta = np.ascontiguousarray(path.theta, dtype=np.float64)
    rho = np.ascontiguousarray(path.rho, dtype=np.float64)
    z = np.ascontiguousarray(path.z, dtype=np.float64)
    if theta.size < 2:
        raise ValueError("simulate_turning: the path needs at least 2 points")
    Rc, hw = _nose_arc(nose_radius, half_width)
    n = theta.size
    span = theta[-1] - theta[0]
    a, cc, dev, f = _nominal_spiral(theta, rho)
    m = path_radial_slope(theta, rho, z) if slope_bound is None else float(slope_bound)
    W = min(hw, 2.1 * Rc * m + 0.5 * f + 1e-9) if window is None else float(window)
    etab = edge_table(edge, Rc, hw)
    W = edge_window(W, Rc, hw, etab)
    seg = np.empty((n - 1, 4))
    seg[:, 0] = rho[:-1]
    seg[:, 1] = rho[1:] - rho[:-1]
    seg[:, 2] = z[:-1]
    seg[:, 3] = z[1:] - z[:-1]
    dth = span / (n - 1)
    nrev_f = TWO_PI / dth if dth > 0 else 0.0
    nrev = int(round(nrev_f))
    uniform = bool(dth > 0 and nrev >= 1 and abs(nrev_f - nrev) < _UNIFORM_RTOL * nrev
                   and np.max(np.abs(theta - (theta[0] + dth * np.arange(n))))
                   < _UNIFORM_RTOL * dth)
    if uniform:
        tab, tt0, tw = np.zeros(1, dtype=np.int64), float(theta[0]), 1.0
    else:
        tab, tt0, tw = _lookup_table(theta)
    return EnvelopePath(seg, theta, tab, tt0, tw, uniform, 1.0 / dth if dth > 0 else 0.0, nrev, 0, n,
                        float(theta[0]), float(theta[-1]), a, float(cc), dev, f, Rc, hw, float(W), etab)


def envelope_fill(ep: EnvelopePath, origin, pixel: float, out: np.ndarray, *, start=(0, 0),
                  parallel: bool = True) -> np.ndarray:
    """Machined heights (mm) written into ``out`` in place; NaN where no pass reaches.

    Parameters
    ----------
    ep : EnvelopePath
        The prepared path (or its slice for this tile).
    origin : (x, y)
        Centre of pixel [0, 0] of the whole grid, mm.
    pixel : float
        Grid spacing, mm.
    out : (ny, nx) float64 array
        Pixels [start[0]:start[0] + ny, start[1]:start[1] + nx] of the whole grid.
    start : (row, col)
        Index of ``out[0, 0]`` in the whole grid.  When both are multiples of ``BLOCK``
        the tile equals the same pixels of a whole-grid run bit for bit.
    parallel : bool
        All cores (numba threads); False runs on the calling thread without the GIL (for
        tiles that a scheduler runs side by side).
    """
    if ep.cc <= 0:
        raise ValueError("envelope_fill: the path must feed towards the axis (use simulate_turning)")
    fill = _fill_parallel if parallel else _fill_serial
    fill(ep.seg, ep.theta, ep.tab, ep.tab_t0, ep.tab_w, ep.uniform, ep.inv, ep.nrev, ep.offset, ep.n_total,
         ep.t0, ep.a, ep.cc, ep.dev, ep.f, ep.nose_radius, ep.half_width, ep.window,
         float(origin[0]), float(origin[1]), float(pixel), int(start[0]), int(start[1]), out, ep.edge)
    return out


def simulate_turning(path, *, nose_radius: float, region, pixel: float, half_width: float | None = None,
                     slope_bound: float | None = None, window: float | None = None,
                     out: np.ndarray | None = None, reference: bool = False, device: str = "auto",
                     edge=None) -> np.ndarray:
    """Machined height (mm) on the grid of ``region`` / ``pixel`` from a turning path.

    Parameters
    ----------
    path : ToolPath
        theta cumulative (rad), rho, z of the tool tip (mm).
    nose_radius : float
        Rc, mm.
    region : (x0, y0, x1, y1)
        mm; pixel centres at x0 + i pixel, y0 + j pixel.
    pixel : float
        mm.
    half_width : float, optional
        Radial half-width of the nose arc (Rc sin(included / 2)); Rc if None.
    slope_bound : float, optional
        Bound on the path's radial slope dz/drho; measured from the path if None.
    window : float, optional
        Radial window (mm) of passes visited around each pixel; by default the proven
        bound 2 Rc m + f / 2 (pass ``half_width`` to visit every pass that reaches).
    out : (ny, nx) float64 array, optional
        Written in place (saves one allocation).
    reference : bool
        Use the direct per-pixel kernel (slower; the fast kernel is checked against it).
    device : "auto", "cpu" or "gpu"
        "auto" runs grids of at least ``GPU_MIN_SAMPLES`` samples on a CUDA GPU when one is
        present (``_envelope_gpu``), after checking it against the CPU kernel on one block
        of the grid; "gpu" requires one.
    edge : EdgeProfile, optional
        The measured cutting edge (``toolpath.EdgeProfile``): the nose's height at each
        radial offset is the edge's instead of the circle's; None: the circular nose.

    Returns
    -------
    (ny, nx) float64: NaN where no pass reaches.
    """
    n_points = int(np.size(path.theta))
    if n_points < 2:
        raise InputError(f"the tool path over simulation.region {list(region)} has "
                         f"{n_points} point(s), at least 2 are needed: the region lies off the "
                         f"turned part (process.workpiece_radius, process.inner_radius)")
    ep = prepare_envelope(path, nose_radius=nose_radius, half_width=half_width, slope_bound=slope_bound,
                          window=window, edge=edge)
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    if out is None:
        out = np.empty((ny, nx), dtype=np.float64)
    if reference or ep.cc <= 0:
        theta = np.ascontiguousarray(path.theta, dtype=np.float64)
        rho = np.ascontiguousarray(path.rho, dtype=np.float64)
        z = np.ascontiguousarray(path.z, dtype=np.float64)
        tab, t0, w = _lookup_table(theta)
        _reference_kernel(theta, rho, z, tab, t0, w, ep.a, ep.cc, ep.dev, ep.f, float(x0), float(y0),
                          float(pixel), nx, ny, ep.nose_radius, ep.half_width, ep.window, out, ep.edge)
        return out
    if device not in ("auto", "cpu", "gpu"):
        raise ValueError(f"simulate_turning: device must be 'auto', 'cpu' or 'gpu', got {device!r}")
    if device == "gpu" or (device == "auto" and out.size >= GPU_MIN_SAMPLES):
        # the GPU module builds on this one (a top-level import would be circular)
        from ._envelope_gpu import cuda_available, envelope_fill_gpu, gpu_supports

        if cuda_available() and gpu_supports(ep):
            envelope_fill_gpu(ep, (x0, y0), pixel, out)
            probe = np.empty((min(BLOCK, ny), min(BLOCK, nx)))
            envelope_fill(ep, (x0, y0), pixel, probe, parallel=False)
            if np.array_equal(np.isnan(probe), np.isnan(out[:probe.shape[0], :probe.shape[1]])) and \
                    np.nanmax(np.abs(probe - out[:probe.shape[0], :probe.shape[1]]), initial=0.0) < 1e-9:
                return out
            warnings.warn("the GPU envelope kernel disagrees with the CPU kernel; using the CPU", RuntimeWarning,
                          stacklevel=2)
        elif device == "gpu":
            raise ValueError("simulate_turning: device='gpu' needs a CUDA device and a constant-angle path")
    # in bands of rows (whole blocks: each band equals the same rows of one whole-grid
    # call bit for bit), reporting the progress and stopping when asked between bands
    rows = BLOCK * max(1, BAND_SAMPLES // max(BLOCK * nx, 1))
    for r0 in range(0, ny, rows):
        r1 = min(r0 + rows, ny)
        envelope_fill(ep, (x0, y0), pixel, out[r0:r1], start=(r0, 0))
        report(r1, ny)
    return out


def load_kernels() -> None:
    """Compile (or load from numba's cache) the fast kernel for tile workers: one call on a
    2 x 2 grid of a three-revolution spiral."""
    theta = np.linspace(0.0, 6 * math.pi, 97)
    rho = 0.05 - 0.01 * theta / TWO_PI
    seg = np.empty((theta.size - 1, 4))
    seg[:, 0], seg[:, 1] = rho[:-1], np.diff(rho)
    seg[:, 2], seg[:, 3] = 0.0, 0.0
    ep = EnvelopePath(seg, theta, np.zeros(1, dtype=np.int64), 0.0, 1.0, True, 96 / (6 * math.pi), 32, 0,
                      theta.size, 0.0, float(theta[-1]), 0.05, 0.01 / TWO_PI, 0.0, 0.01, 0.1, 0.05, 0.0101)
    envelope_fill(ep, (0.0, 0.0), 0.001, np.empty((2, 2)), parallel=False)
