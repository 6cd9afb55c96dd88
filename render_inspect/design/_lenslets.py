"""Lenslet (micro-lens) arrays: spherical elements on a rectangular grid or on rings.

Every length is in mm.  Heights, gradients and Hessians are analytic: inside an element
of radius of curvature R the sag is ``s^2 / (R + sqrt(R^2 - s^2))`` (s = distance from the
element's centre), its gradient ``(dx, dy) / sqrt(R^2 - s^2)``.

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566`
.. [2] L. Kong, Y. Ma, M. Ren, M. Xu, C.-F. Cheung, "Generation and characterization of
       ultra-precision compound freeform surfaces," Science Progress 103(1), 1-12 (2020).
       :DOI:`10.1177/0036850419880112`
.. [3] C. Zhang, C.-F. Cheung, X. Liang, B. Bulla, "A theoretical and experimental
       investigation of high-frequency ultrasonic vibration-assisted sculpturing of
       optical microstructures," Applied Sciences 12(21), 10937 (2022).
.. [4] "Rotary-coordinate and shuttling-element cutting strategy for ultra-precision
       diamond turning of optical microstructures," Optica Publishing Group (2024).
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from ..core.errors import InputError, check_positive
from ..core.section import MAX_LENGTH_MM, Length, Section
from ._base import Surface
from ._registry import register_design

__all__ = ["LensletArray", "LensletRings", "sphere_sag", "lens_radius_from_sag"]


def sphere_sag(s2: np.ndarray | float, radius: float) -> np.ndarray:
    """Sag (mm) of a sphere of radius ``radius`` at squared distance ``s2`` (mm^2)."""
    return s2 / (radius + np.sqrt(radius * radius - s2))


def lens_radius_from_sag(aperture_radius: float, sag: float) -> float:
    """Radius of curvature (mm) of a cap of aperture radius ``a`` and chord height ``h``:
    ``R = (a^2 + h^2) / (2 h)``."""
    check_positive("sag", sag)
    check_positive("aperture_radius", aperture_radius)
    return (aperture_radius ** 2 + sag ** 2) / (2 * sag)


def _cap_derivs(dx, dy, inside, radius, sign):
    """Gradient and Hessian of ``sign * sag(s)`` where ``inside`` (0 elsewhere)."""
    s2 = dx * dx + dy * dy
    # outside the apertures the derivatives are 0: keep w away from 0 there (no 0 * inf)
    w = np.sqrt(np.where(inside, np.maximum(radius * radius - s2, 1e-300), 1.0))
    w3 = w ** 3
    k = np.where(inside, sign, 0.0)
    gx, gy = k * dx / w, k * dy / w
    hxx = k * (1 / w + dx * dx / w3)
    hxy = k * dx * dy / w3
    hyy = k * (1 / w + dy * dy / w3)
    return gx, gy, hxx, hxy, hyy


class LensletArray(Surface):
    """Spherical lenslets on a ``rows`` x ``cols`` rectangular grid.

    Parameters
    ----------
    rows, cols : int
        Number of lenslets along y and x.
    pitch_x, pitch_y : float
        Centre spacing (mm).
    lens_radius : float, optional
        Radius of curvature of each lenslet (mm).  Give this or ``sag``.
    aperture_radius : float, optional
        Aperture (plane) radius of a round lenslet (mm); required for ``cells="round"``.
    concave : bool
        True: dimples (round) / bowls (quad); False: bumps.
    cells : {"round", "quad"}
        ``"round"``: spherical caps of radius ``aperture_radius`` on a flat base at
        ``offset`` (Li et al. 2018 [1]_, Table 4; Kong et al. 2020 [2]_).  ``"quad"``:
        sharp-edged rectangular cells filling the grid, ``z = offset +- sag(s)`` with the
        cell centre at ``offset`` (Zhang et al. 2022 [3]_); outside the array the blank
        stays at the corners' level.
    center_x, center_y : float
        Centre of the array (mm).
    offset : float
        Height of the base plane (round) or of the cell centres (quad), mm.
    sag : float, optional
        Chord height of a round lenslet (mm): ``lens_radius = (a^2 + sag^2) / (2 sag)``.

    Attributes
    ----------
    lens_radius, aperture_radius (round; None for quad), pitch_x, pitch_y, concave,
    cells, rows, cols, chord_height (mm: depth of a round lenslet, or of a quad cell at its
    corners).
    """
    kind = "lenslet_array"

    def __init__(self, rows=2, cols=2, pitch_x=1.0, pitch_y=1.0, lens_radius=None,
                 aperture_radius=None, concave=True, cells="round", center_x=0.0,
                 center_y=0.0, offset=0.0, sag=None):
        for name, v in (("design.rows", rows), ("design.cols", cols)):
            if int(v) != v or v < 1:
                raise InputError(f"{name} must be an integer >= 1, received {v!r}")
        check_positive("design.pitch_x", pitch_x)
        check_positive("design.pitch_y", pitch_y)
        if cells not in ("round", "quad"):
            raise InputError(f"design.cells must be 'round' or 'quad', received {cells!r}")
        if (lens_radius is None) == (sag is None):
            raise InputError("give exactly one of design.lens_radius and design.sag, received "
                             f"lens_radius={lens_radius!r}, sag={sag!r}")
        self.rows, self.cols = int(rows), int(cols)
        self.pitch_x, self.pitch_y = float(pitch_x), float(pitch_y)
        self.concave, self.cells = bool(concave), cells
        self.center_x, self.center_y, self.offset = float(center_x), float(center_y), float(offset)
        if cells == "round":
            if aperture_radius is None:
                raise InputError("design.aperture_radius is required for cells = 'round'")
            a = float(check_positive("design.aperture_radius", aperture_radius))
            half = min(self.pitch_x, self.pitch_y) / 2
            if a > half:
                raise InputError(f"design.aperture_radius must be in (0, {half:g}] (half the "
                                 f"smaller pitch), received {a}")
            if sag is not None:
                if not 0 < sag < a:
                    raise InputError(f"design.sag must be in (0, {a:g}) mm, received {sag!r}")
                lens_radius = lens_radius_from_sag(a, float(sag))
            R = float(check_positive("design.lens_radius", lens_radius))
            if a >= R:
                raise InputError(f"design.aperture_radius must be < design.lens_radius ({R} mm), "
                                 f"received {a}")
            self.aperture_radius = a
            self.lens_radius = R
            self.chord_height = float(sphere_sag(a * a, R))
        else:
            if sag is not None or aperture_radius is not None:
                raise InputError("design.sag and design.aperture_radius apply to cells = 'round' "
                                 f"only, received sag={sag!r}, aperture_radius={aperture_radius!r}")
            R = float(check_positive("design.lens_radius", lens_radius))
            half_diag2 = (self.pitch_x ** 2 + self.pitch_y ** 2) / 4
            if half_diag2 >= R * R:
                raise InputError(f"design.lens_radius must be > half the cell diagonal "
                                 f"({math.sqrt(half_diag2):g} mm), received {R}")
            self.aperture_radius = None
            self.lens_radius = R
            self.chord_height = float(sphere_sag(half_diag2, R))
        self._sign = 1.0 if self.concave else -1.0   # sign of d(height)/d(sag)
        self._x_first = self.center_x - (self.cols - 1) / 2 * self.pitch_x
        self._y_first = self.center_y - (self.rows - 1) / 2 * self.pitch_y

    # ---- layout -------------------------------------------------------------------------
    def lateral_scale(self) -> float:
        """The larger pitch (mm)."""
        return max(self.pitch_x, self.pitch_y)

    def centers(self) -> list[tuple[int, int, float, float]]:
        """(row, col, x_mm, y_mm) of every lenslet; row 0 has the smallest y."""
        return [(i, j, self._x_first + j * self.pitch_x, self._y_first + i * self.pitch_y)
                for i in range(self.rows) for j in range(self.cols)]

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """(x0, y0, x1, y1) of the array's cells (mm)."""
        return (self._x_first - self.pitch_x / 2, self._y_first - self.pitch_y / 2,
                self._x_first + (self.cols - 0.5) * self.pitch_x,
                self._y_first + (self.rows - 0.5) * self.pitch_y)

    def _local(self, x, y):
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        x, y = np.broadcast_arrays(x, y)
        fj = (x - self._x_first) / self.pitch_x
        fi = (y - self._y_first) / self.pitch_y
        j = np.clip(np.rint(fj), 0, self.cols - 1)
        i = np.clip(np.rint(fi), 0, self.rows - 1)
        dx = x - (self._x_first + j * self.pitch_x)
        dy = y - (self._y_first + i * self.pitch_y)
        if self.cells == "round":
            inside = dx * dx + dy * dy < self.aperture_radius ** 2
        else:  # inside the array's cells (the nearest cell is the cell)
            inside = (np.abs(fj - j) <= 0.5 + 1e-9) & (np.abs(fi - i) <= 0.5 + 1e-9)
        return dx, dy, inside

    # ---- Surface ------------------------------------------------------------------------
    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        dx, dy, inside = self._local(x, y)
        R = self.lens_radius
        if self.cells == "round":
            depth = np.where(inside, self.chord_height - sphere_sag(
                np.where(inside, dx * dx + dy * dy, 0.0), R), 0.0)
            return self.offset - self._sign * depth
        sag = np.where(inside, sphere_sag(np.where(inside, dx * dx + dy * dy, 0.0), R),
                       self.chord_height)
        return self.offset + self._sign * sag

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        dx, dy, inside = self._local(x, y)
        gx, gy, *_ = _cap_derivs(dx, dy, inside, self.lens_radius, self._sign)
        return gx, gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dx, dy, inside = self._local(x, y)
        _, _, hxx, hxy, hyy = _cap_derivs(dx, dy, inside, self.lens_radius, self._sign)
        return hxx, hxy, hyy

    def max_slope(self, region: Sequence[float] | None = None, pixel: float | None = None) -> float:
        """Largest |grad F| inside the lenslets (at the aperture edge or the cell corner)."""
        s2 = (self.aperture_radius ** 2 if self.cells == "round"
              else (self.pitch_x ** 2 + self.pitch_y ** 2) / 4)
        return float(math.sqrt(s2 / (self.lens_radius ** 2 - s2)))

    def __repr__(self):
        return (f"LensletArray(rows={self.rows}, cols={self.cols}, pitch_x={self.pitch_x}, "
                f"pitch_y={self.pitch_y}, lens_radius={self.lens_radius}, "
                f"aperture_radius={self.aperture_radius}, cells={self.cells!r}, "
                f"concave={self.concave})")


class LensletRings(Surface):
    """Spherical elements on concentric rings (the microstructure of the RCSE paper [4]_).

    Element ``n`` of ring ``k`` is centred at radius ``ring_radii[k]`` and angle
    ``phase + 2 pi n / counts[k]``.  Each element is a spherical cap of plane radius
    ``element_radius`` and sag ``depth`` (radius of curvature
    ``(element_radius^2 + depth^2) / (2 depth)``) on a flat base at ``offset``: a dimple
    when ``concave``, else a bump.  Where elements overlap, the deeper (higher) one wins.

    Parameters
    ----------
    ring_radii : sequence of float
        Ring radii (mm), >= 0; a ring of radius 0 holds one element at the centre.
    counts : sequence of int
        Elements per ring (>= 1), one entry per ring.
    element_radius, depth : float
        Plane radius and sag of an element (mm), depth < element_radius.
    concave : bool
    phase_deg : float
        Angle of element 0 of every ring (degrees).
    offset : float
        Height of the base plane (mm).
    """
    kind = "lenslet_rings"

    def __init__(self, ring_radii, counts, element_radius, depth, concave=True, phase_deg=0.0,
                 offset=0.0):
        ring_radii = [float(r) for r in ring_radii]
        counts = [int(c) for c in counts]
        if not ring_radii or len(ring_radii) != len(counts):
            raise InputError(f"design.ring_radii and design.counts must be non-empty and of one "
                             f"length, received {len(ring_radii)} and {len(counts)}")
        if any(not (r >= 0 and math.isfinite(r)) for r in ring_radii):
            raise InputError(f"design.ring_radii must be >= 0, received {ring_radii}")
        if any(c < 1 for c in counts):
            raise InputError(f"design.counts must be >= 1, received {counts}")
        a = float(check_positive("design.element_radius", element_radius))
        if not 0 < depth < a:
            raise InputError(f"design.depth must be in (0, {a:g}) mm, received {depth!r}")
        self.ring_radii, self.counts = ring_radii, counts
        self.element_radius = self.aperture_radius = a
        self.depth = self.chord_height = float(depth)
        self.lens_radius = lens_radius_from_sag(a, self.depth)
        self.concave = bool(concave)
        self.phase = math.radians(float(phase_deg))
        self.offset = float(offset)
        self._sign = 1.0 if self.concave else -1.0

    def lateral_scale(self) -> float:
        """An element's diameter (mm)."""
        return 2 * self.element_radius

    def centers(self) -> list[tuple[int, int, float, float]]:
        """(ring index, element index, x_mm, y_mm) of every element."""
        out = []
        for k, (r, c) in enumerate(zip(self.ring_radii, self.counts)):
            for n in range(c):
                t = self.phase + 2 * math.pi * n / c
                out.append((k, n, r * math.cos(t), r * math.sin(t)))
        return out

    def _nearest(self, x, y):
        """Per point: offsets (dx, dy) to the element whose cap is deepest there, and a mask."""
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        x, y = np.broadcast_arrays(x, y)
        a2 = self.element_radius ** 2
        best_s2 = np.full(x.shape, np.inf)
        best_dx = np.zeros(x.shape)
        best_dy = np.zeros(x.shape)
        rho = np.hypot(x, y)
        phi = np.arctan2(y, x)
        for r, c in zip(self.ring_radii, self.counts):
            # only the points near the ring (a ring's band holds a few of them)
            near = np.flatnonzero(np.abs(rho - r) < self.element_radius)
            if near.size == 0:
                continue
            xn, yn = x.ravel()[near], y.ravel()[near]
            bs2, bdx, bdy = (b.reshape(-1)[near] for b in (best_s2, best_dx, best_dy))
            step = 2 * np.pi / c
            n0 = np.rint((phi.ravel()[near] - self.phase) / step)
            # neighbours too: elements on a tight ring may overlap
            for dn in ((0,) if c == 1 else (-1, 0, 1)):
                t = self.phase + (n0 + dn) * step
                dx = xn - r * np.cos(t)
                dy = yn - r * np.sin(t)
                s2 = dx * dx + dy * dy
                better = s2 < bs2
                bs2 = np.where(better, s2, bs2)
                bdx = np.where(better, dx, bdx)
                bdy = np.where(better, dy, bdy)
            best_s2.reshape(-1)[near] = bs2
            best_dx.reshape(-1)[near] = bdx
            best_dy.reshape(-1)[near] = bdy
        return best_dx, best_dy, best_s2 < a2

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        dx, dy, inside = self._nearest(x, y)
        s2 = np.where(inside, dx * dx + dy * dy, 0.0)
        depth = np.where(inside, self.depth - sphere_sag(s2, self.lens_radius), 0.0)
        return self.offset - self._sign * depth

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        dx, dy, inside = self._nearest(x, y)
        gx, gy, *_ = _cap_derivs(dx, dy, inside, self.lens_radius, self._sign)
        return gx, gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        dx, dy, inside = self._nearest(x, y)
        _, _, hxx, hxy, hyy = _cap_derivs(dx, dy, inside, self.lens_radius, self._sign)
        return hxx, hxy, hyy

    def max_slope(self, region: Sequence[float] | None = None, pixel: float | None = None) -> float:
        a2 = self.element_radius ** 2
        return float(math.sqrt(a2 / (self.lens_radius ** 2 - a2)))

    def __repr__(self):
        return (f"LensletRings(ring_radii={self.ring_radii}, counts={self.counts}, "
                f"element_radius={self.element_radius}, depth={self.depth}, "
                f"concave={self.concave})")


# ------------------------------------------------------------------ scene schema
class LensletArrayConfig(Section):
    """Spherical lenslets on a rectangular grid (Li et al. 2018, Table 4; Kong et al. 2020;
    Zhang et al. 2022).

    ``cells = "round"``: each lenslet is a spherical cap of aperture radius
    ``aperture_radius`` on a flat (base) surface at ``offset``; concave lenslets are
    dimples below it, convex ones bumps above it.  ``cells = "quad"``: sharp-edged
    quadrilateral cells filling the grid (Zhang et al. 2022),
    ``z = offset +- s^2/(r + sqrt(r^2 - s^2))`` (the cell centre at ``offset``), the blank
    outside the array at the corners' level.
    Give either ``lens_radius`` or (round cells) ``sag``, the chord height of one
    lenslet: ``lens_radius = (aperture_radius^2 + sag^2) / (2 sag)``.
    Centres: ``center + (j - (cols-1)/2) pitch_x``, ``center + (i - (rows-1)/2) pitch_y``."""
    type: Literal["lenslet_array"]
    rows: int = Field(2, ge=1, le=1000)
    cols: int = Field(2, ge=1, le=1000)
    pitch_x: float = Field(..., gt=0, le=MAX_LENGTH_MM, description="mm, centre spacing along x")
    pitch_y: float = Field(..., gt=0, le=MAX_LENGTH_MM, description="mm, centre spacing along y")
    lens_radius: float | None = Field(None, gt=0, description="mm, radius of curvature of each lenslet")
    sag: float | None = Field(None, gt=0, description="mm, chord height of a round lenslet "
                                                      "(instead of lens_radius)")
    aperture_radius: float | None = Field(None, gt=0, description="mm, round cells only")
    concave: bool = True
    cells: Literal["round", "quad"] = "round"
    center_x: Length = 0.0
    center_y: Length = 0.0
    offset: Length = 0.0

    @model_validator(mode="after")
    def _aperture(self):
        if (self.lens_radius is None) == (self.sag is None):
            raise ValueError("give exactly one of lens_radius (mm, radius of curvature) and sag "
                             f"(mm, chord height), received lens_radius={self.lens_radius}, "
                             f"sag={self.sag}")
        if self.cells == "round":
            if self.aperture_radius is None:
                raise ValueError("aperture_radius is required for cells = 'round'")
            half = min(self.pitch_x, self.pitch_y) / 2
            if self.aperture_radius > half:
                raise ValueError(f"aperture_radius must be <= half the smaller pitch ({half:g} mm: "
                                 f"pitch_x = {self.pitch_x:g}, pitch_y = {self.pitch_y:g}; round "
                                 f"lenslets may not overlap), received {self.aperture_radius}")
            if self.sag is not None and self.sag >= self.aperture_radius:
                raise ValueError(f"sag must be < aperture_radius ({self.aperture_radius} mm, a "
                                 f"lenslet is at most a hemisphere), received {self.sag}")
            if self.lens_radius is not None and self.aperture_radius >= self.lens_radius:
                raise ValueError(f"aperture_radius must be < lens_radius ({self.lens_radius}), "
                                 f"received {self.aperture_radius}")
        else:
            if self.sag is not None:
                raise ValueError("sag is only defined for cells = 'round' (give lens_radius for "
                                 f"quad cells), received sag={self.sag}")
            if self.aperture_radius is not None:
                raise ValueError("aperture_radius is only used with cells = 'round' (a quad cell's "
                                 f"aperture is the pitch), received {self.aperture_radius}")
            half_diag = 0.5 * (self.pitch_x ** 2 + self.pitch_y ** 2) ** 0.5
            if half_diag >= self.lens_radius:
                raise ValueError(f"lens_radius must be > half the cell diagonal ({half_diag:g} mm from "
                                 f"pitch_x = {self.pitch_x:g}, pitch_y = {self.pitch_y:g}) for "
                                 f"cells = 'quad', received {self.lens_radius}")
        return self


#: most elements a ``lenslet_rings`` design may have
MAX_RING_ELEMENTS = 1_000_000  # not a unit conversion


class LensletRingsConfig(Section):
    """Lenslets (spherical elements) on concentric rings (the RCSE paper, 2024)."""
    type: Literal["lenslet_rings"]
    ring_radii: list[Annotated[float, Field(ge=0, le=MAX_LENGTH_MM)]] = Field(
        ..., min_length=1, max_length=10_000, description="mm, ring radii")
    counts: list[Annotated[int, Field(ge=1)]] = Field(..., min_length=1, max_length=10_000,
                                                       description="elements per ring")
    element_radius: float = Field(..., gt=0, description="mm, plane (aperture) radius of an element")
    depth: float = Field(..., gt=0, description="mm, sag of an element")
    concave: bool = True
    phase_deg: float = Field(0.0, ge=-360, le=360)
    offset: Length = 0.0

    @model_validator(mode="after")
    def _lengths(self):
        if len(self.ring_radii) != len(self.counts):
            raise ValueError(f"ring_radii and counts must have the same length, received "
                             f"{len(self.ring_radii)} and {len(self.counts)}")
        if self.depth >= self.element_radius:
            raise ValueError(f"depth must be < element_radius ({self.element_radius}), received {self.depth}")
        if any(c > MAX_RING_ELEMENTS for c in self.counts) or sum(self.counts) > MAX_RING_ELEMENTS:
            raise ValueError(f"counts must add up to at most {MAX_RING_ELEMENTS} elements, received "
                             f"{sum(self.counts)}")
        a = self.element_radius
        for i, (r, n) in enumerate(zip(self.ring_radii, self.counts)):
            if r == 0 and n > 1:
                raise ValueError(f"counts must be 1 for a ring of radius 0 (ring {i}), received {n}")
            if n > 1 and 2 * r * math.sin(math.pi / n) < 2 * a * (1 - 1e-12):
                raise ValueError(
                    f"element_radius must let the {n} elements of ring {i} (radius {r} mm) sit "
                    f"side by side without overlapping: at most {r * math.sin(math.pi / n):.6g} "
                    f"mm, received {a}; use fewer elements or a larger ring radius")
        rs = sorted(self.ring_radii)
        for r0, r1 in zip(rs[:-1], rs[1:]):
            if r1 - r0 < 2 * a * (1 - 1e-12):
                raise ValueError(f"ring_radii must be at least 2 * element_radius = {2 * a:g} mm "
                                 f"apart (elements may not overlap), received rings at {r0} and "
                                 f"{r1} mm")
        return self


register_design(LensletArrayConfig, LensletArray)
register_design(LensletRingsConfig, LensletRings)
