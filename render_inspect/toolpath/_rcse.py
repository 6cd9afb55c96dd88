"""Rotary-coordinate, shuttling-element (RCSE) spiral tool paths, after the RCSE paper [1]_.

The part is a set of identical elements (spherical dimples or bumps) on concentric rings.
Instead of modelling the whole surface on a rectangular grid and interpolating cutting
contact points (CCPs) onto the spiral (the *conventional* method), the RCSE generator
places the CCPs directly on the Archimedean spiral

    rho(theta) = r_outer - d theta / (2 pi),   theta_k = k dtheta_p   (k = 0, 1, ...)

(``d`` the spiral pitch = feed per revolution, ``dtheta_p`` the polar step) and evaluates
the height of each CCP *exactly* in the local frame of the one element it falls on:

- **rotary coordinate (ratchet)**: element ``n`` of a ring of ``N`` elements is the basic
  element rotated by ``n dtheta`` (``dtheta = 2 pi / N``).  A CCP at polar angle ``psi``
  (measured from the ring's phase) belongs to element ``n = round(psi / dtheta)``; rotating
  the frame back by ``n dtheta`` gives its local polar angle ``phi = psi - n dtheta`` in
  the basic element's plane local coordinate system (PLCS), and local coordinates
  ``u = rho cos(phi) - R_ring``, ``v = rho sin(phi)``;
- **shuttling element**: at the same local angle the spiral is ``D = d dtheta / (2 pi)``
  nearer the centre on element ``n + 1`` than on element ``n`` (rho(theta + dtheta) =
  rho(theta) - D), i.e. seen from the basic element's frame the element shuttles outward
  by ``D`` per step.  Using the spiral's own radius ``rho_k`` carries that offset exactly;
- **stitching**: the sub-paths of consecutive elements are consecutive runs of spiral
  samples, so the last CCP of element ``n``'s sub-path is followed directly by the first
  CCP of the next sub-path (on the flat between elements, or on element ``n + 1``): the
  stitched path is one spiral, its radius strictly decreasing.

The within-revolution angle is reduced with integer arithmetic (``k mod P``), so the
height of a CCP does not depend on how many revolutions came before it.

The conventional comparison (:func:`conventional_ccps`) models the design on a
rectangular point cloud (grid spacing ``g``) and takes each spiral point from it: with
``snap_to_rows`` (the default, the paper's "interpolation in the X-axis direction") the
CCP lies on the nearest point-cloud row, its height interpolated along that row, so its
polar radius - the X axis - jitters by up to ``g / 2`` about the spiral; without it, the
height is interpolated (bilinear or cubic spline) at the exact spiral point and only the
profile error remains.

References
----------
.. [1] "Rotary-coordinate and shuttling-element cutting strategy for ultra-precision
       diamond turning of optical microstructures," Optica Publishing Group (2024); the
       project's copy lacks the author list (docs/references.md).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.errors import InputError, SceneError, check_range
from ..core.toolpath import ToolPath
from ..core.units import MIN_TO_S
from ._tool import Tool
from ._build import region_radii
from ._compensation import normal_compensation, z_compensation
from ._spiral import chordal_error

TWO_PI = 2.0 * math.pi
#: ring stride of the integer key of a (ring, element) pair: ring * stride + element
_RING_KEY_STRIDE = 1_000_000  # not a unit conversion

__all__ = ["RingLayout", "RcseCcps", "PointCloudModel", "rcse_ccps", "conventional_ccps",
           "rcse_toolpath", "paper_layout"]


# ---------------------------------------------------------------------------------------
# element layout
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class RingLayout:
    """Identical spherical elements on concentric rings (the ``lenslet_rings`` design).

    Parameters
    ----------
    ring_radii : (m,) float, mm
        Radius of each ring of element centres (0 = one element at the centre).
    counts : (m,) int
        Elements on each ring; element ``n`` of ring ``i`` is centred at polar angle
        ``phase + 2 pi n / counts[i]``.
    element_radius : float, mm
        Plane (aperture) radius ``a`` of an element.
    depth : float, mm
        Sag ``h`` of an element (0 < h < a); the sphere radius is (a^2 + h^2) / (2 h).
    concave : bool
        True: dimples (rim at ``offset``, bottom at ``offset - depth``);
        False: bumps (top at ``offset + depth``).
    phase : float, rad
        Polar angle of element 0 of every ring.
    offset : float, mm
        Height of the flat land between the elements.
    """

    ring_radii: tuple
    counts: tuple
    element_radius: float
    depth: float
    concave: bool = True
    phase: float = 0.0
    offset: float = 0.0

    def __post_init__(self):
        radii = tuple(float(r) for r in self.ring_radii)
        counts = tuple(int(c) for c in self.counts)
        object.__setattr__(self, "ring_radii", radii)
        object.__setattr__(self, "counts", counts)
        if not radii or len(radii) != len(counts):
            raise InputError(f"ring_radii and counts must be non-empty and of one length, "
                             f"received {len(radii)} and {len(counts)}")
        check_range("element_radius", self.element_radius, 0.0, None, lo_open=True)
        check_range("depth", self.depth, 0.0, self.element_radius, lo_open=True, hi_open=True)
        for i, (r, c) in enumerate(zip(radii, counts)):
            if r < 0:
                raise InputError(f"ring_radii[{i}] must be >= 0 mm, received {r}")
            if c < 1 or (r == 0 and c != 1):
                raise InputError(f"counts[{i}] must be >= 1 (exactly 1 on a ring of radius 0), "
                                 f"received {c} on ring radius {r}")

    # -- construction -------------------------------------------------------------------
    @classmethod
    def from_config(cls, cfg: Any) -> "RingLayout":
        """From a ``[design]`` config of type ``lenslet_rings`` (pydantic model or dict)."""
        get: Callable[..., Any] = (cfg.get if isinstance(cfg, dict)
                                   else (lambda k, d=None: getattr(cfg, k, d)))
        if get("type") != "lenslet_rings":
            raise SceneError(f"process.kind = 'rcse' needs design.type = 'lenslet_rings' "
                             f"(elements on rings), received design.type = {get('type')!r}")
        return cls(tuple(get("ring_radii")), tuple(get("counts")), float(get("element_radius")),
                   float(get("depth")), bool(get("concave", True)),
                   math.radians(float(get("phase_deg", 0.0) or 0.0)), float(get("offset", 0.0) or 0.0))

    # -- geometry -----------------------------------------------------------------------
    @property
    def sphere_radius(self) -> float:
        """Radius of curvature of an element, (a^2 + h^2) / (2 h), mm."""
        a, h = self.element_radius, self.depth
        return (a * a + h * h) / (2.0 * h)

    @property
    def max_slope(self) -> float:
        """Largest |grad z| on an element (at its rim), a / sqrt(R^2 - a^2)."""
        R, a = self.sphere_radius, self.element_radius
        return a / math.sqrt(R * R - a * a)

    @property
    def outer_radius(self) -> float:
        """Largest distance of any element point from the centre, mm."""
        return max(self.ring_radii) + self.element_radius

    def element_height(self, s2: np.ndarray) -> np.ndarray:
        """Height (mm) at squared local distance ``s2`` (mm^2) from an element centre;
        ``offset`` outside the element."""
        s2 = np.asarray(s2, dtype=np.float64)
        R, a, h = self.sphere_radius, self.element_radius, self.depth
        inside = s2 < a * a
        sag = R - np.sqrt(np.maximum(R * R - np.where(inside, s2, a * a), 0.0))  # 0 at centre, h at rim
        rel = np.where(inside, (sag - h) if self.concave else (h - sag), 0.0)
        return self.offset + rel

    def overlaps(self, *, gap: float = 0.0) -> list[str]:
        """Pairs of elements closer than ``2 a + gap`` (an empty list: the layout fits)."""
        a = self.element_radius
        out = []
        for i, (r, n) in enumerate(zip(self.ring_radii, self.counts)):
            if n > 1 and 2 * r * math.sin(math.pi / n) < 2 * a + gap:
                out.append(f"ring {i} (radius {r} mm): {n} elements need a radius >= "
                           f"{(2 * a + gap) / (2 * math.sin(math.pi / n)):.4g} mm")
        order = np.argsort(self.ring_radii, kind="stable")
        for i, j in zip(order[:-1], order[1:]):
            if self.ring_radii[j] - self.ring_radii[i] < 2 * a + gap:
                out.append(f"rings {i} and {j} (radii {self.ring_radii[i]}, {self.ring_radii[j]} mm) "
                           f"are closer than 2 * element_radius = {2 * a} mm")
        return out

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Reference evaluation of the layout at Cartesian (x, y) (mm), by the nearest
        element of each ring (no spiral needed); used by the conventional method."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        x, y = np.broadcast_arrays(x, y)
        rho = np.hypot(x, y).ravel()
        ang = np.arctan2(y, x).ravel()
        return self._height_polar(rho, ang).reshape(x.shape)

    def _height_polar(self, rho: np.ndarray, ang: np.ndarray) -> np.ndarray:
        """Height at polar (rho, ang), 1-D arrays; ``ang`` any real angle (rad)."""
        z = np.full(rho.shape, self.offset, dtype=np.float64)
        a = self.element_radius
        for R, N in zip(self.ring_radii, self.counts):
            m = np.abs(rho - R) < a
            if not np.any(m):
                continue
            r = rho[m]
            dth = TWO_PI / N
            psi = ang[m] - self.phase
            n = np.floor(psi / dth + 0.5)  # ratchet index: nearest element
            phi = psi - n * dth  # local polar angle in the basic element's PLCS
            u = r * np.cos(phi) - R
            v = r * np.sin(phi)
            s2 = u * u + v * v
            inside = s2 < a * a
            idx = np.flatnonzero(m)[inside]
            z[idx] = self.element_height(s2[inside])
        return z

    def to_dict(self) -> dict:
        return {"ring_radii": list(self.ring_radii), "counts": list(self.counts),
                "element_radius": self.element_radius, "depth": self.depth,
                "concave": self.concave, "phase_deg": math.degrees(self.phase),
                "offset": self.offset, "sphere_radius": self.sphere_radius,
                "elements": int(sum(self.counts))}


def paper_layout(*, region_radius: float = 4.75, element_radius: float = 0.4, depth: float = 0.002,
                 rings: int = 5, max_count: int = 36, gap: float = 0.05) -> RingLayout:
    """A layout like the RCSE paper's that fits: ``rings`` equally spaced rings, the outermost
    element edge at ``region_radius``, ``min(max_count, 6 k)`` elements on ring ``k``.

    With the paper's numbers (0.4 mm elements in a 9.5 mm region) no ring can hold 36
    elements (that needs a ring radius >= 4.6 mm, whose elements would stick out of the
    region), so ring ``k`` (radius 0.86 k mm) carries 6 k elements (6, 12, 18, 24, 30;
    90 in all) with at least ``gap`` between neighbours.
    """
    pitch = (region_radius - element_radius) / rings
    radii, counts = [], []
    for k in range(1, rings + 1):
        r = pitch * k
        fit = math.floor(math.pi / math.asin(min(1.0, (2 * element_radius + gap) / (2 * r))))
        radii.append(round(r, 6))
        counts.append(int(min(max_count, 6 * k, fit)))
    return RingLayout(tuple(radii), tuple(counts), element_radius, depth, True)


# ---------------------------------------------------------------------------------------
# RCSE CCPs
# ---------------------------------------------------------------------------------------
@dataclass
class RcseCcps:
    """CCPs of an RCSE spiral.

    Attributes
    ----------
    k : (n,) int64
        Sample index along the full spiral (theta = k * 2 pi / P).
    theta : (n,) float64, rad (cumulative spindle angle C)
    rho : (n,) float64, mm (X; strictly decreasing)
    z : (n,) float64, mm (the design height at the CCP, exact)
    ring, element : (n,) int32
        Ring and element index of the element each CCP lies on, -1 on the flat land.
    meta : dict
    """

    k: np.ndarray
    theta: np.ndarray
    rho: np.ndarray
    z: np.ndarray
    ring: np.ndarray
    element: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def x(self) -> np.ndarray:
        return self.rho * np.cos(self.theta)

    @property
    def y(self) -> np.ndarray:
        return self.rho * np.sin(self.theta)

    def sub_paths(self) -> np.ndarray:
        """(m, 4) int array of (ring, element, first, last) CCP index runs on elements,
        in cutting order: the sub-paths that RCSE stitches end to end."""
        on = self.ring >= 0
        key = np.where(on, self.ring.astype(np.int64) * _RING_KEY_STRIDE + self.element, -1)
        change = np.flatnonzero(np.diff(key) != 0) + 1
        starts = np.concatenate([[0], change])
        ends = np.concatenate([change - 1, [key.size - 1]])
        keep = key[starts] >= 0
        return np.stack([self.ring[starts[keep]], self.element[starts[keep]],
                         starts[keep], ends[keep]], axis=1) if key.size else np.zeros((0, 4), int)


def rcse_ccps(layout: RingLayout, *, r_outer: float, pitch: float, points_per_rev: int,
              r_inner: float = 0.0, r_range: tuple[float, float] | None = None) -> RcseCcps:
    """RCSE cutting-contact points on the inward Archimedean spiral.

    Parameters
    ----------
    layout : RingLayout
    r_outer : float
        mm, spiral start radius (theta = 0 there).
    pitch : float
        mm, spiral pitch ``d`` (= feed per revolution).
    points_per_rev : int
        ``P``, constant polar step 2 pi / P (the paper: 0.25 deg, P = 1440).
    r_inner : float
        mm, the spiral stops at the first sample at or inside this radius.
    r_range : (lo, hi), optional
        mm; keep only the samples with lo <= rho <= hi (same samples as the full spiral:
        a window of it, not a new spiral).

    Returns
    -------
    RcseCcps
    """
    check_range("r_outer", r_outer, 0.0, None, lo_open=True)
    check_range("pitch", pitch, 0.0, r_outer, lo_open=True)
    if not 0.0 <= r_inner < r_outer:
        raise InputError(f"r_inner must be in [0, r_outer={r_outer}) mm, received {r_inner}")
    P = int(points_per_rev)
    if P < 8 or P != points_per_rev:
        raise InputError(f"points_per_rev must be an integer >= 8, received {points_per_rev!r}")
    k_end = int(math.ceil((r_outer - r_inner) * P / pitch - 1e-9))
    k0, k1 = 0, k_end
    if r_range is not None:
        lo, hi = float(r_range[0]), float(r_range[1])
        if not hi >= lo:
            raise InputError(f"r_range must be (lo, hi) with hi >= lo, received {r_range}")
        k0 = max(0, int(math.ceil((r_outer - hi) * P / pitch - 1e-9)))
        k1 = min(k_end, int(math.floor((r_outer - lo) * P / pitch + 1e-9)))
        if k1 < k0:
            raise InputError(f"r_range {r_range} mm holds no spiral sample between r_inner={r_inner} "
                             f"and r_outer={r_outer} mm")
    k = np.arange(k0, k1 + 1, dtype=np.int64)
    step = TWO_PI / P
    theta = k * step
    rho = r_outer - pitch * (k / P)
    if k1 == k_end:
        rho[-1] = max(rho[-1], r_inner)
    z = np.full(k.size, layout.offset, dtype=np.float64)
    ring = np.full(k.size, -1, dtype=np.int32)
    element = np.full(k.size, -1, dtype=np.int32)
    # within-revolution polar angle, reduced exactly with integers (the ratchet works on it)
    ang = (k % P) * step
    a = layout.element_radius
    for i, (R, N) in enumerate(zip(layout.ring_radii, layout.counts)):
        # rho is monotone: the CCPs near ring i are one contiguous run of samples
        j0 = int(np.searchsorted(-rho, -(R + a), side="right"))
        j1 = int(np.searchsorted(-rho, -(R - a), side="left"))
        if j1 <= j0:
            continue
        r = rho[j0:j1]
        dth = TWO_PI / N
        psi = ang[j0:j1] - layout.phase
        n = np.floor(psi / dth + 0.5)  # ratchet: the element this CCP falls on
        phi = psi - n * dth  # rotate the PLCS back by n dtheta
        u = r * np.cos(phi) - R  # local coordinates in the basic element
        v = r * np.sin(phi)
        s2 = u * u + v * v
        inside = s2 < a * a
        sl = np.flatnonzero(inside) + j0
        z[sl] = layout.element_height(s2[inside])
        ring[sl] = i
        element[sl] = np.mod(n[inside], N).astype(np.int32)
    meta = {"method": "rcse", "pitch_mm": pitch, "points_per_rev": P,
            "polar_step_deg": 360.0 / P, "r_outer": r_outer, "r_inner": r_inner,
            "shuttle_D_mm": [pitch / N for N in layout.counts]}
    return RcseCcps(k, theta, rho, z, ring, element, meta)


# ---------------------------------------------------------------------------------------
# conventional: rectangular point cloud + interpolation
# ---------------------------------------------------------------------------------------
class PointCloudModel:
    """The conventional method's surface model: heights on a square grid of nodes at
    ``g (i - M)`` (both axes), interpolated linearly or by cubic B-spline.

    Parameters
    ----------
    z : (2M+1, 2M+1) array, mm (row = y, column = x)
    spacing : float, mm
    order : {1, 3}
    """

    def __init__(self, z: np.ndarray, spacing: float, order: int = 1):
        from scipy import ndimage

        self.spacing = float(spacing)
        self.M = (z.shape[0] - 1) // 2
        self.order = int(order)
        self.z = np.ascontiguousarray(z, dtype=np.float64)
        self._coef = ndimage.spline_filter(self.z, order=3) if self.order == 3 else self.z

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        from scipy import ndimage

        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        x, y = np.broadcast_arrays(x, y)
        coords = np.stack([y.ravel() / self.spacing + self.M, x.ravel() / self.spacing + self.M])
        out = ndimage.map_coordinates(self._coef, coords, order=self.order, mode="nearest",
                                      prefilter=False)
        return out.reshape(x.shape)


def conventional_ccps(surface: Any, theta: np.ndarray, rho: np.ndarray, *, grid_spacing: float,
                      interpolation: str = "linear", snap_to_rows: bool = True,
                      profile_error: bool = True) -> dict:
    """The conventional tool path: model the design on a rectangular grid, then take the
    spiral's CCPs from that point cloud.

    Parameters
    ----------
    surface : object with ``height(x, y)`` (mm)
        The design (e.g. the ``lenslet_rings`` Surface or a :class:`RingLayout`).
    theta, rho : (n,) arrays
        The nominal spiral samples (rad, mm); C stays at ``theta`` (the spindle turns
        uniformly), X becomes the polar radius of the point taken from the point cloud.
    grid_spacing : float
        mm, spacing ``g`` of the rectangular point cloud (nodes at integer multiples of g).
    interpolation : {"linear", "cubic"}
        Linear (= scipy RegularGridInterpolator "linear") or cubic B-spline
        (scipy.ndimage.map_coordinates order 3).
    snap_to_rows : bool
        True: each CCP lies on the nearest point-cloud row (y = j g), its height
        interpolated along the row at the spiral's x ("interpolation in the X-axis
        direction"); False: interpolated at the exact spiral (x, y).
    profile_error : bool
        Also evaluate ``surface`` at the machine position (C, X) to report the error.

    Returns
    -------
    dict with ``rho`` (X, mm), ``z`` (mm), ``profile_error`` (z - design at (C, X), mm, or
    None), ``modelling_s``, ``toolpath_s``, ``grid_shape``, ``model`` (the
    :class:`PointCloudModel`, for the conventional tool-radius compensation).
    """
    check_range("grid_spacing", grid_spacing, 0.0, None, lo_open=True)
    if interpolation not in ("linear", "cubic"):
        raise InputError(f"interpolation must be 'linear' or 'cubic', received {interpolation!r}")
    theta = np.asarray(theta, dtype=np.float64)
    rho = np.asarray(rho, dtype=np.float64)
    g = float(grid_spacing)
    r_max = float(np.max(np.abs(rho))) if rho.size else 0.0
    M = int(math.ceil(r_max / g)) + 3
    if (2 * M + 1) ** 2 > 60_000_000:
        raise InputError(f"grid_spacing {g} mm gives a {(2 * M + 1)}^2 point cloud for radius "
                         f"{r_max:.4g} mm; use grid_spacing >= {2 * r_max / 7700:.3g} mm")
    t0 = time.perf_counter()
    nodes = g * np.arange(-M, M + 1, dtype=np.float64)
    zg = np.asarray(surface.height(nodes[None, :], nodes[:, None]), dtype=np.float64)
    zg = np.broadcast_to(zg, (nodes.size, nodes.size))
    model = PointCloudModel(zg, g, 1 if interpolation == "linear" else 3)
    t1 = time.perf_counter()
    x = rho * np.cos(theta)
    y = rho * np.sin(theta)
    col = x / g + M
    if snap_to_rows:
        row = np.rint(y / g)
        y_cc = row * g
        row = row + M
    else:
        y_cc = y
        row = y / g + M
    if interpolation == "linear" and snap_to_rows:
        ri = row.astype(np.int64)
        c0 = np.floor(col).astype(np.int64)
        w = col - c0
        z = (1.0 - w) * zg[ri, c0] + w * zg[ri, c0 + 1]
    else:
        z = model.height(x, y_cc)
    rho_c = np.hypot(x, y_cc) if snap_to_rows else rho.copy()
    t2 = time.perf_counter()
    err = None
    if profile_error:
        err = z - np.asarray(surface.height(rho_c * np.cos(theta), rho_c * np.sin(theta)))
    return {"rho": rho_c, "z": np.asarray(z, dtype=np.float64), "profile_error": err,
            "modelling_s": t1 - t0, "toolpath_s": t2 - t1, "grid_shape": list(zg.shape),
            "model": model}


# ---------------------------------------------------------------------------------------
# CCPs -> ToolPath
# ---------------------------------------------------------------------------------------
def rcse_toolpath(layout: RingLayout, tool: Tool, *, workpiece_radius: float, pitch: float,
                  points_per_rev: int, spindle_rpm: float, inner_radius: float = 0.0,
                  compensation: str = "z", region: Sequence[float] | None = None,
                  ccps: RcseCcps | None = None,
                  surface: Any = None) -> ToolPath:
    """The RCSE tool path: CCPs on the spiral, then tool-radius compensation.

    Parameters
    ----------
    layout : RingLayout
        The elements (:meth:`RingLayout.from_config` of a ``lenslet_rings`` design).
    tool : Tool
    workpiece_radius : float
        mm; the spiral starts there at theta = 0.
    pitch : float
        Spiral pitch d = feed per revolution, mm.
    points_per_rev : int
        Polar step 2 pi / points_per_rev.
    spindle_rpm : float
        Sets t = theta / omega.
    inner_radius : float
        mm; the spiral stops there.
    compensation : {"none", "normal", "z"}
    region : (x0, y0, x1, y1), optional
        mm; keep only the revolutions whose tool nose can reach this window.
    ccps : RcseCcps, optional
        Precomputed CCPs (as :func:`rcse_ccps` returns them for these settings).
    surface : Surface, optional
        The design used by the compensation (``layout`` itself if None: the same heights
        as ``design.LensletRings``, evaluated faster).

    Returns
    -------
    ToolPath
        theta (cumulative), rho, z (tool tip), t = theta / omega; ``meta`` holds the
        method, compensation, pitch and the CCP design heights' source.
    """
    bad = layout.overlaps()
    if bad:
        raise SceneError("process.kind = 'rcse' needs elements that do not overlap (each CCP on "
                         "at most one element); design.ring_radii / design.counts: " + "; ".join(bad))
    Rc = float(tool.nose_radius)
    if ccps is None:
        r_range = None
        if region is not None:
            r_range = region_radii(region, tool.half_width + 2 * pitch)
        ccps = rcse_ccps(layout, r_outer=workpiece_radius, pitch=pitch,
                         points_per_rev=points_per_rev, r_inner=inner_radius, r_range=r_range)
    theta, rho, z = ccps.theta, ccps.rho, ccps.z
    comp = compensation
    if comp == "none":
        rho_t, z_t = rho.copy(), z.copy()
    else:
        if surface is None:
            surface = layout  # the same heights as design.LensletRings, evaluated faster
        if comp == "z":
            rho_t = rho.copy()
            z_t = z_compensation(surface, theta, rho, Rc, max_slope=layout.max_slope * 1.05,
                                 half_width=tool.half_width)
        else:
            rho_t, z_t = normal_compensation(surface, theta, rho, Rc)
    omega = TWO_PI * spindle_rpm / MIN_TO_S  # rpm -> rad/s
    meta = dict(ccps.meta)
    # the CCPs are exact, but the axes interpolate linearly between them: chordal error
    if theta.size >= 2:
        ce = chordal_error(layout, theta, rho, z)
        i = int(np.argmax(ce))
        tm, rm = 0.5 * (theta[i] + theta[i + 1]), 0.5 * (rho[i] + rho[i + 1])
        meta["chordal_error_max_mm"] = float(ce[i])
        meta["chordal_error_worst_at_mm"] = [float(rm * math.cos(tm)), float(rm * math.sin(tm))]
    meta.update({"compensation": comp, "feed_per_rev_mm": pitch, "nose_radius": Rc,
                 "spindle_rpm": spindle_rpm, "layout": layout.to_dict(),
                 "sampling": "constant_angle"})
    meta["r_range_mm"] = [float(rho.min()), float(rho.max())]
    meta["time_s"] = float((theta[-1] - theta[0]) / omega)
    return ToolPath(theta.copy(), rho_t, z_t, theta / omega, meta, ccp_rho=rho.copy(), ccp_z=z.copy())
