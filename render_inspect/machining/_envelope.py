"""The machined surface of a turning path: the envelope of the tool-nose arcs.

In each radial section (angle phi) the tool passes once per revolution.  Pass j is at
cumulative angle theta_j = phi + 2 pi j; between programmed points the C, X and Z axes
interpolate linearly, giving the tool tip (rho_j, z_j).  Its nose arc cuts
z_j + Rc - sqrt(Rc^2 - (r - rho_j)^2) for |r - rho_j| <= the arc's half-width, and the
machined height at (r, phi) is the minimum over all passes (seed 000 section 3).  Turning
marks (feed scallops) and, without compensation, overcut waviness come out of this.

Only passes that can win are visited: an arc at distance d from the pixel is at least
d^2 / (2 Rc) above its tip, and tips differ by at most m |d - d0| between passes (m the
path's radial slope bound), so passes with |d| > 2 Rc m + f / 2 (f the feed per rev) never
win.  Passes on the far side of the axis (angle phi + pi) are included near the centre.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from ..core.errors import InputError

TWO_PI = 2 * math.pi


@njit(cache=True, inline="always")
def _lookup(theta, tab, tab_t0, tab_w, s):
    """Index i with theta[i] <= s <= theta[i+1] (s inside the path)."""
    b = int((s - tab_t0) / tab_w)
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


@njit(cache=True, inline="always")
def _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, sgn, W, Rc, Rc2, hw, best):
    """Visit the passes at angle phi whose nominal radius is within W of sgn * r."""
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
    j0 = math.ceil((s_lo - phi) / TWO_PI)
    j1 = math.floor((s_hi - phi) / TWO_PI)
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
            if zj < best:
                best = zj
    return best


@njit(parallel=True, cache=True)
def _envelope_kernel(theta, rho, z, tab, tab_t0, tab_w, a, cc, dev, f, x0, y0, pixel, nx, ny,
                     Rc, hw, W, out):
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
            best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, Wp, Rc, Rc2, hw, best)
            if r < Wp + hw:
                phi2 = phi + math.pi
                if phi2 >= TWO_PI:
                    phi2 -= TWO_PI
                best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, Wp, Rc, Rc2, hw, best)
            if best == np.inf and Wp < hw + dev:
                # no pass within the window (beyond the path's ends): visit every pass that reaches
                best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, hw + dev, Rc, Rc2, hw, best)
                if r < hw + dev:
                    phi2 = phi + math.pi
                    if phi2 >= TWO_PI:
                        phi2 -= TWO_PI
                    best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, hw + dev, Rc, Rc2,
                                    hw, best)
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


def simulate_turning(path, *, nose_radius: float, region, pixel: float, half_width: float | None = None,
                     slope_bound: float | None = None, window: float | None = None,
                     out: np.ndarray | None = None) -> np.ndarray:
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

    Returns
    -------
    (ny, nx) float64: NaN where no pass reaches.
    """
    theta = np.ascontiguousarray(path.theta, dtype=np.float64)
    rho = np.ascontiguousarray(path.rho, dtype=np.float64)
    z = np.ascontiguousarray(path.z, dtype=np.float64)
    if theta.size < 2:
        raise InputError(f"the tool path over simulation.region {list(region)} has "
                         f"{theta.size} point(s), at least 2 are needed: the region lies off the "
                         f"turned part (process.workpiece_radius, process.inner_radius)")
    Rc = float(nose_radius)
    hw = float(half_width) if half_width is not None else Rc
    hw = min(hw, Rc)
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    span = theta[-1] - theta[0]
    cc = (rho[0] - rho[-1]) / span if span > 0 else 0.0
    a = float(rho[0])
    dev = float(np.max(np.abs(rho - (a - cc * (theta - theta[0])))))
    f = abs(cc) * TWO_PI
    m = path_radial_slope(theta, rho, z) if slope_bound is None else float(slope_bound)
    W = min(hw, 2.1 * Rc * m + 0.5 * f + 1e-9) if window is None else float(window)
    tab, t0, w = _lookup_table(theta)
    if out is None:
        out = np.empty((ny, nx), dtype=np.float64)
    _envelope_kernel(theta, rho, z, tab, t0, w, a, cc, dev, f, float(x0), float(y0), float(pixel),
                     nx, ny, Rc, hw, W, out)
    return out
