"""Closed-form surfaces: sinusoidal grid, plane, sphere, toric, biconic.

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566`
.. [2] L. Kong, Y. Ma, M. Ren, M. Xu, C.-F. Cheung, "Generation and characterization of
       ultra-precision compound freeform surfaces," Science Progress 103(1), 1-12 (2020).
       :DOI:`10.1177/0036850419880112`
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from ..core import trig
from ..core.errors import InputError
from ..core.section import Length, Phase, Section
from ._base import Surface
from ._registry import register_design

#: largest |radius of curvature| of the analytic designs, mm (10 km: a flat, for all purposes)
MAX_RADIUS_MM = 1e7

TWO_PI = 2 * np.pi


class SinusoidalGrid(Surface):
    """z = Ax cos(2 pi x / lx + px) + Ay cos(2 pi y / ly + py) + offset (Li et al. 2018 [1]_)."""
    kind = "sinusoidal_grid"

    def __init__(self, amplitude_x, amplitude_y, wavelength_x, wavelength_y, phase_x=0.0,
                 phase_y=0.0, offset=0.0):
        self.ax, self.ay = float(amplitude_x), float(amplitude_y)
        self.kx, self.ky = TWO_PI / float(wavelength_x), TWO_PI / float(wavelength_y)
        self.wavelength_x, self.wavelength_y = float(wavelength_x), float(wavelength_y)
        self.px, self.py = float(phase_x), float(phase_y)
        self.offset = float(offset)

    def lateral_scale(self) -> float:
        """The longer of the two wavelengths (mm)."""
        return max(self.wavelength_x, self.wavelength_y)

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        return self.ax * trig.cos(self.kx * x + self.px) + self.ay * trig.cos(self.ky * y + self.py) + self.offset

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        gx = -self.ax * self.kx * trig.sin(self.kx * x + self.px)
        gy = -self.ay * self.ky * trig.sin(self.ky * y + self.py)
        gx, gy = np.broadcast_arrays(gx, gy)
        return gx, gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        hxx = -self.ax * self.kx ** 2 * trig.cos(self.kx * x + self.px)
        hyy = -self.ay * self.ky ** 2 * trig.cos(self.ky * y + self.py)
        hxx, hyy = np.broadcast_arrays(hxx, hyy)
        return hxx, np.zeros_like(hxx), hyy

    def max_slope(self, region: Sequence[float] | None = None, pixel: float | None = None) -> float:
        return float(np.hypot(self.ax * self.kx, self.ay * self.ky))


class Plane(Surface):
    kind = "plane"

    def __init__(self, slope_x=0.0, slope_y=0.0, offset=0.0):
        self.sx, self.sy, self.offset = float(slope_x), float(slope_y), float(offset)

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        return self.sx * np.asarray(x, dtype=np.float64) + self.sy * np.asarray(y, dtype=np.float64) + self.offset

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        shape = np.broadcast(np.asarray(x), np.asarray(y)).shape
        return np.full(shape, self.sx), np.full(shape, self.sy)

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        shape = np.broadcast(np.asarray(x), np.asarray(y)).shape
        z = np.zeros(shape)
        return z, z.copy(), z.copy()

    def max_slope(self, region: Sequence[float] | None = None, pixel: float | None = None) -> float:
        return float(np.hypot(self.sx, self.sy))


def _f64(a):
    return np.asarray(a, dtype=np.float64)


class Biconic(Surface):
    """Biconic sag ``z = offset - (cx u^2 + cy v^2) / (1 + sqrt(1 - (1+kx) cx^2 u^2 - (1+ky) cy^2 v^2))``
    with ``u = x - x0``, ``v = y - y0``, ``cx = 1/radius_x``, ``cy = 1/radius_y``.

    ``radius`` > 0: convex (apex up, height falls away from the apex);
    ``radius`` < 0: concave.  ``conic = 0`` gives sections close to circles (equal radii:
    a sphere), ``conic = -1`` a paraboloid ``z = offset - u^2/(2 Rx) - v^2/(2 Ry)``.
    The apex curvatures are ``-1/radius_x`` and ``-1/radius_y`` (d2z/dx2, d2z/dy2).
    Points outside the surface's domain raise InputError on evaluation (NaN would be
    silent).
    """
    kind = "biconic"

    def __init__(self, radius_x, radius_y, conic_x=0.0, conic_y=0.0, x0=0.0, y0=0.0, offset=0.0):
        if radius_x == 0 or radius_y == 0:
            raise InputError(f"design.radius_x and design.radius_y must be non-zero (> 0 convex, "
                             f"< 0 concave), received {radius_x}, {radius_y}")
        self.radius_x, self.radius_y = float(radius_x), float(radius_y)
        self.cx, self.cy = 1.0 / radius_x, 1.0 / radius_y
        self.kx, self.ky = float(conic_x), float(conic_y)
        self.x0, self.y0, self.offset = float(x0), float(y0), float(offset)

    def _parts(self, x, y):
        u = _f64(x) - self.x0
        v = _f64(y) - self.y0
        num = self.cx * u * u + self.cy * v * v
        arg = 1 - (1 + self.kx) * self.cx ** 2 * u * u - (1 + self.ky) * self.cy ** 2 * v * v
        if np.any(arg < 0):
            raise InputError("design point outside the surface's aperture (sqrt of a negative "
                             "number); shrink simulation.region or increase the radius")
        return u, v, num, np.sqrt(arg)

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        _, _, num, s = self._parts(x, y)
        return -num / (1 + s) + self.offset

    def _derivs(self, x, y):
        u, v, num, s = self._parts(x, y)
        d = 1 + s
        ax = (1 + self.kx) * self.cx ** 2
        ay = (1 + self.ky) * self.cy ** 2
        # f = num / d ;  num_u = 2 cx u ;  s_u = -ax u / s
        nu, nv = 2 * self.cx * u, 2 * self.cy * v
        with np.errstate(divide="ignore", invalid="ignore"):
            inv_s = np.where(s > 0, 1.0 / s, 0.0)
        su, sv = -ax * u * inv_s, -ay * v * inv_s
        return u, v, num, s, d, ax, ay, nu, nv, su, sv, inv_s

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        _, _, num, _, d, _, _, nu, nv, su, sv, _ = self._derivs(x, y)
        gx = -(nu * d - num * su) / d ** 2
        gy = -(nv * d - num * sv) / d ** 2
        return gx, gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u, v, num, s, d, ax, ay, nu, nv, su, sv, inv_s = self._derivs(x, y)
        # second derivatives of s = sqrt(arg): s_uu = -ax/s - su^2/s, s_uv = -su sv / s
        suu = (-ax - su * su) * inv_s
        svv = (-ay - sv * sv) * inv_s
        suv = -su * sv * inv_s
        d2, d3 = d * d, d * d * d
        fuu = 2 * self.cx / d - 2 * nu * su / d2 - num * suu / d2 + 2 * num * su * su / d3
        fvv = 2 * self.cy / d - 2 * nv * sv / d2 - num * svv / d2 + 2 * num * sv * sv / d3
        fuv = -nu * sv / d2 - nv * su / d2 - num * suv / d2 + 2 * num * su * sv / d3
        return -fuu, -fuv, -fvv


class Sphere(Biconic):
    """Sphere of radius ``radius`` with its apex at (x0, y0, offset); > 0 convex (cap up),
    < 0 concave.  ``z = offset -+ r^2 / (R + sqrt(R^2 - r^2))`` (the sag form, exact near
    the apex); the apex curvature d2z/dx2 = -1/radius."""
    kind = "sphere"

    def __init__(self, radius, x0=0.0, y0=0.0, offset=0.0):
        super().__init__(radius, radius, 0.0, 0.0, x0, y0, offset)
        self.radius = float(radius)
        self._sgn = -1.0 if self.radius > 0 else 1.0

    def _uvw(self, x, y):
        u = _f64(x) - self.x0
        v = _f64(y) - self.y0
        r2 = u * u + v * v
        R = abs(self.radius)
        if np.any(r2 > R * R):
            raise InputError(f"design point outside the sphere (design.radius = {self.radius} mm, "
                             f"farthest point at {float(np.sqrt(np.max(r2))):.6g} mm from the apex); "
                             "shrink simulation.region or process.workpiece_radius")
        return u, v, r2, np.sqrt(R * R - r2)

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        _, _, r2, w = self._uvw(x, y)
        sag = r2 / (abs(self.radius) + w)
        return self._sgn * sag + self.offset

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        u, v, _, w = self._uvw(x, y)
        w = np.maximum(w, 1e-300)
        return self._sgn * u / w, self._sgn * v / w

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        u, v, _, w = self._uvw(x, y)
        w = np.maximum(w, 1e-300)
        w3 = w ** 3
        return (self._sgn * (1 / w + u * u / w3), self._sgn * u * v / w3,
                self._sgn * (1 / w + v * v / w3))


class Toric(Surface):
    """Toric surface with principal radii ``radius_x`` (section y = 0) and ``radius_y``
    (section x = 0) at the apex (0, 0, offset); sign as for the sphere: > 0 convex.

    Construction: the circular x-section of radius |radius_x| is swept about an axis
    parallel to x at distance |radius_y| from the apex, so every section x = const is a
    circle (radius |radius_y| -+ sag_x(x)).  The base of Kong et al. (2020) [2]_: R1 = 500,
    R2 = 250 mm.
    Apex curvatures: d2z/dx2 = -1/radius_x, d2z/dy2 = -1/radius_y.
    """
    kind = "toric"

    def __init__(self, radius_x, radius_y, offset=0.0):
        if radius_x == 0 or radius_y == 0:
            raise InputError(f"design.radius_x and design.radius_y must be non-zero (> 0 convex, "
                             f"< 0 concave), received {radius_x}, {radius_y}")
        self.rx, self.ry, self.offset = float(radius_x), float(radius_y), float(offset)
        self.radius_x, self.radius_y = self.rx, self.ry
        self._sx = 1.0 if self.rx > 0 else -1.0
        self._sy = 1.0 if self.ry > 0 else -1.0

    def _parts(self, x, y):
        x = _f64(x)
        y = _f64(y)
        Rx, Ry = abs(self.rx), abs(self.ry)
        if np.any(np.abs(x) >= Rx):
            raise InputError(f"design point outside the toric surface (|x| must be < "
                             f"|design.radius_x| = {Rx} mm); shrink simulation.region")
        qx = np.sqrt(Rx * Rx - x * x)
        sx = x * x / (Rx + qx)                       # sag of the x-section (>= 0)
        rr = Ry - self._sx * self._sy * sx           # radius of the y-section at this x
        if np.any(np.abs(y) >= np.abs(rr)) or np.any(rr <= 0):
            raise InputError("design point outside the toric surface (|y| must be < the local "
                             f"y-section radius, about |design.radius_y| = {Ry} mm); shrink "
                             "simulation.region")
        q = np.sqrt(rr * rr - y * y)
        return x, y, qx, sx, rr, q

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        x, y, qx, sx, rr, q = self._parts(x, y)
        sy = y * y / (rr + q)
        return -(self._sx * sx + self._sy * sy) + self.offset

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        x, y, qx, sx, rr, q = self._parts(x, y)
        sig = self._sx * self._sy
        sx_x = x / qx
        rr_x = -sig * sx_x
        sy_x = rr_x * (1 - rr / q)
        sy_y = y / q
        gx = -(self._sx * sx_x + self._sy * sy_x)
        gy = -self._sy * sy_y
        gx, gy = np.broadcast_arrays(gx, gy)
        return gx, gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        x, y, qx, sx, rr, q = self._parts(x, y)
        sig = self._sx * self._sy
        Rx = abs(self.rx)
        sx_x = x / qx
        sx_xx = Rx * Rx / qx ** 3
        rr_x = -sig * sx_x
        rr_xx = -sig * sx_xx
        q3 = q ** 3
        sy_xx = rr_xx * (1 - rr / q) + rr_x * rr_x * y * y / q3
        sy_xy = -y * rr * rr_x / q3
        sy_yy = rr * rr / q3
        hxx = -(self._sx * sx_xx + self._sy * sy_xx)
        hxy = -self._sy * sy_xy
        hyy = -self._sy * sy_yy
        hxx, hxy, hyy = np.broadcast_arrays(hxx, hxy, hyy)
        return hxx, hxy, hyy


# ------------------------------------------------------------------ scene schema
class SinusoidalGridConfig(Section):
    """z = Ax cos(2 pi x / lx + px) + Ay cos(2 pi y / ly + py) + offset (Li et al. 2018)."""
    type: Literal["sinusoidal_grid"]
    amplitude_x: float = Field(0.002, ge=0, le=1.0, description="mm")
    amplitude_y: float = Field(0.002, ge=0, le=1.0, description="mm")
    wavelength_x: float = Field(2.5, gt=0, description="mm")
    wavelength_y: float = Field(2.5, gt=0, description="mm")
    phase_x: Phase = Field(0.0, description="rad")
    phase_y: Phase = Field(0.0, description="rad")
    offset: Length = Field(0.0, description="mm")


class PlaneConfig(Section):
    """z = slope_x x + slope_y y + offset."""
    type: Literal["plane"]
    slope_x: float = Field(0.0, ge=-10, le=10, description="dz/dx")
    slope_y: float = Field(0.0, ge=-10, le=10, description="dz/dy")
    offset: Length = 0.0


class SphereConfig(Section):
    """Sphere with apex at (x0, y0, offset); radius > 0 convex (cap up), < 0 concave."""
    type: Literal["sphere"]
    radius: float = Field(..., ge=-MAX_RADIUS_MM, le=MAX_RADIUS_MM,
                          description="mm; > 0 convex, < 0 concave; |radius| > 0")
    x0: Length = 0.0
    y0: Length = 0.0
    offset: Length = 0.0

    @model_validator(mode="after")
    def _nonzero(self):
        if self.radius == 0:
            raise ValueError("radius must be non-zero (> 0 convex, < 0 concave), received 0")
        return self


class ToricConfig(Section):
    """Toric surface with principal radii along x (radius_x) and y (radius_y).
    Sign as for sphere: > 0 convex, < 0 concave."""
    type: Literal["toric"]
    radius_x: float = Field(..., ge=-MAX_RADIUS_MM, le=MAX_RADIUS_MM, description="mm")
    radius_y: float = Field(..., ge=-MAX_RADIUS_MM, le=MAX_RADIUS_MM, description="mm")
    offset: Length = 0.0

    @model_validator(mode="after")
    def _nonzero(self):
        for k in ("radius_x", "radius_y"):
            if getattr(self, k) == 0:
                raise ValueError(f"{k} must be non-zero, received 0")
        return self


class BiconicConfig(Section):
    """Biconic sag; conic 0 = sphere-like sections, -1 = paraboloid.
    Sign as for sphere: > 0 convex, < 0 concave.  ``type = "paraboloid"`` is the biconic
    with conic_x = conic_y = -1 (the default there; other conics are rejected)."""
    type: Literal["biconic", "paraboloid"]
    radius_x: float = Field(..., ge=-MAX_RADIUS_MM, le=MAX_RADIUS_MM, description="mm")
    radius_y: float = Field(..., ge=-MAX_RADIUS_MM, le=MAX_RADIUS_MM, description="mm")
    conic_x: float = 0.0
    conic_y: float = 0.0
    offset: Length = 0.0

    @model_validator(mode="before")
    @classmethod
    def _paraboloid(cls, data):
        if isinstance(data, dict) and data.get("type") == "paraboloid":
            data = dict(data)
            for k in ("conic_x", "conic_y"):
                v = data.setdefault(k, -1.0)
                if v != -1:
                    raise ValueError(f"{k} must be -1 for type = 'paraboloid' (use type = "
                                     f"'biconic' for other conics), received {v!r}")
        return data

    @model_validator(mode="after")
    def _nonzero(self):
        for k in ("radius_x", "radius_y"):
            if getattr(self, k) == 0:
                raise ValueError(f"{k} must be non-zero, received 0")
        return self


register_design(SinusoidalGridConfig, SinusoidalGrid)
register_design(PlaneConfig, Plane)
register_design(SphereConfig, Sphere)
register_design(ToricConfig, Toric)
register_design(BiconicConfig, Biconic)
