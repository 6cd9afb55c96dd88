"""A turning path prepared for the envelope kernel (:class:`EnvelopePath`): its segments,
the angle -> segment lookup table, the nominal spiral the pass windows are counted on, the
proven pass window (widened for a measured edge) and the run of passes one tile needs
(:meth:`EnvelopePath.slice_for`).  The kernels that use it are in :mod:`._envelope` and
:mod:`._cut_kernel`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..core.lazy import njit  # numba, imported on first use
from ..core.toolpath import ToolPath
from ._envelope_step import TWO_PI

#: relative tolerance within which a path's angles count as a uniform grid
_UNIFORM_RTOL = 1e-9  # not a unit conversion
#: the empty edge table: the circular nose
_NO_EDGE = np.zeros(0)


@njit(cache=True, nogil=True)
def _right_counts(theta, edges, out):
    """out[k] = how many of ``theta`` are <= edges[k] (numpy's ``searchsorted(theta, edges,
    side="right")``) by one merge of the two sorted arrays; False (out undefined) where
    either is not nondecreasing."""
    n = theta.size
    for j in range(1, n):
        if not theta[j] >= theta[j - 1]:
            return False
    for k in range(1, edges.size):
        if not edges[k] >= edges[k - 1]:
            return False
    j = 0
    for k in range(edges.size):
        e = edges[k]
        while j < n and theta[j] <= e:
            j += 1
        out[k] = j
    return True


def _lookup_table(theta: np.ndarray):
    n = theta.size
    span = theta[-1] - theta[0]
    nb = int(min(max(n, 16), 4_000_000))
    w = span / nb if span > 0 else 1.0
    edges = theta[0] + w * np.arange(nb)
    # (a merge of the sorted angles and bin edges: the tiles' slices each make a table)
    right = np.empty(nb, dtype=np.intp)
    if not _right_counts(np.ascontiguousarray(theta, dtype=np.float64), edges, right):
        right = np.searchsorted(theta, edges, side="right")
    tab = np.clip(right - 1, 0, max(n - 2, 0)).astype(np.int64)
    return tab, float(theta[0]), float(w)


@njit(cache=True, nogil=True)
def _radial_slope(theta, rho, z):
    """(True, :func:`path_radial_slope`) by one merge of the angles with the angles one
    revolution later, the array form's operations in its order; (False, 0) where
    ``theta`` is not nondecreasing."""
    n = theta.size
    for j in range(1, n):
        if not theta[j] >= theta[j - 1]:
            return False, 0.0
    best = -np.inf
    good = False
    k = 0
    for i in range(n):
        key = theta[i] + TWO_PI
        while k < n and theta[k] < key:  # (numpy's searchsorted, side "left")
            k += 1
        if k >= n:
            break
        k0 = max(k - 1, 0)
        dt = theta[k] - theta[k0]
        fr = (theta[i] + TWO_PI - theta[k0]) / dt if dt > 0 else 0.0
        r2 = rho[k0] + fr * (rho[k] - rho[k0])
        z2 = z[k0] + fr * (z[k] - z[k0])
        dr = abs(r2 - rho[i])
        if dr > 0:
            v = abs(z2 - z[i]) / dr
            if not good or v > best or v != v:
                best = v
                good = True
                if v != v:  # (NaN, as numpy's max gives it)
                    return True, v
    return True, (best if good else 0.0)


@njit(cache=True, nogil=True, inline="always")
def _heights_at(theta, z, m0, key):
    """(lowest, highest) height of the path at angle ``key`` (theta[m0] the first angle >=
    key): every point's at that angle where the path has points there (a dwell has
    several), else the height interpolated between its neighbours."""
    if theta[m0] == key:
        lo = hi = z[m0]
        m = m0 + 1
        while m < theta.size and theta[m] == key:
            lo = min(lo, z[m])
            hi = max(hi, z[m])
            m += 1
        return lo, hi
    fr = (key - theta[m0 - 1]) / (theta[m0] - theta[m0 - 1])
    v = z[m0 - 1] + fr * (z[m0] - z[m0 - 1])
    return v, v


@njit(cache=True, nogil=True)
def _revolution_step(theta, z):
    """(least, largest) z(s + 2 pi) - z(s) over the angles s of the path and every height
    the path has there (z linear in the angle between points; the extremes lie at a point
    or one revolution before one); (-inf, inf) where the angles go back or a height is not
    finite, (0, 0) for a path of one revolution or less."""
    n = theta.size
    for j in range(n):
        if not math.isfinite(z[j]) or not math.isfinite(theta[j]):
            return -math.inf, math.inf
        if j > 0 and not theta[j] >= theta[j - 1]:
            return -math.inf, math.inf
    if n < 2 or theta[n - 1] - theta[0] <= TWO_PI:
        return 0.0, 0.0
    least = math.inf
    most = -math.inf
    # at each point s = theta[i]: the heights one revolution later
    m0 = 0
    for i in range(n):
        key = theta[i] + TWO_PI
        if key > theta[n - 1]:
            break
        while theta[m0] < key:
            m0 += 1
        lo, hi = _heights_at(theta, z, m0, key)
        least = min(least, lo - z[i])
        most = max(most, hi - z[i])
    # one revolution before each point: the heights there
    m0 = 0
    for i in range(n):
        key = theta[i] - TWO_PI
        if key < theta[0]:
            continue
        while theta[m0] < key:
            m0 += 1
        lo, hi = _heights_at(theta, z, m0, key)
        least = min(least, z[i] - hi)
        most = max(most, z[i] - lo)
    return least, most


def path_revolution_step(theta: np.ndarray, z: np.ndarray) -> tuple[float, float]:
    """The least and the largest change of the tool tip's height from one revolution to
    the next at the same angle (mm, signed: later minus earlier; :func:`_revolution_step`):
    they bound how far apart in height two passes a given number of revolutions apart can
    be at any pixel.  (-inf, inf) where unknown."""
    lo, hi = _revolution_step(np.ascontiguousarray(theta, dtype=np.float64),
                              np.ascontiguousarray(z, dtype=np.float64))
    return float(lo), float(hi)


def path_radial_slope(theta: np.ndarray, rho: np.ndarray, z: np.ndarray) -> float:
    """Largest |dz/drho| between a point and the point one revolution later (mm/mm)."""
    if theta.size < 3 or theta[-1] - theta[0] <= TWO_PI:
        return 0.0
    ok, m = _radial_slope(*(np.ascontiguousarray(a, dtype=np.float64) for a in (theta, rho, z)))
    if ok:
        return float(m)
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

    def slice_for(self, region: Sequence[float]) -> "EnvelopePath":
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


def edge_window(window: float, nose_radius: float, half_width: float,
                edge: np.ndarray | None) -> float:
    """The pass window (mm) widened for a measured edge: an arc at distance d is at least
    d^2 / (2 Rc) + min(g) above its tip (g the edge's height table), so the proven window
    grows by sqrt(2 Rc (max g - min g)); unchanged for the circular nose."""
    if edge is None or edge.size == 0:
        return window
    g = edge[3:]
    return min(half_width, window + math.sqrt(2.0 * nose_radius * float(g.max() - g.min())))


def edge_table(edge: Any, nose_radius: float, half_width: float) -> np.ndarray:
    """The kernels' table of ``edge`` (an ``EdgeProfile``, a ready table, or None)."""
    if edge is None:
        return _NO_EDGE
    if isinstance(edge, np.ndarray):
        return np.ascontiguousarray(edge, dtype=np.float64)
    return edge.height_table(nose_radius, half_width)


def prepare_envelope(path: ToolPath, *, nose_radius: float, half_width: float | None = None,
                     slope_bound: float | None = None, window: float | None = None,
                     edge: Any = None) -> EnvelopePath:
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
