"""Closed-form surfaces: sinusoidal grid, plane, sphere, toric, biconic."""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ._base import Surface

TWO_PI = 2 * np.pi


class SinusoidalGrid(Surface):
    """z = Ax cos(2 pi x / lx + px) + Ay cos(2 pi y / ly + py) + offset (seed 000)."""
    kind = "sinusoidal_grid"

    def __init__(self, amplitude_x, amplitude_y, wavelength_x, wavelength_y, phase_x=0.0,
                 phase_y=0.0, offset=0.0):
        self.ax, self.ay = float(amplitude_x), float(amplitude_y)
        self.kx, self.ky = TWO_PI / float(wavelength_x), TWO_PI / float(wavelength_y)
        self.px, self.py = float(phase_x), float(phase_y)
        self.offset = float(offset)

    def height(self, x, y):
        return self.ax * np.cos(self.kx * x + self.px) + self.ay * np.cos(self.ky * y + self.py) + self.offset

    def gradient(self, x, y):
        gx = -self.ax * self.kx * np.sin(self.kx * x + self.px)
        gy = -self.ay * self.ky * np.sin(self.ky * y + self.py)
        return np.broadcast_arrays(gx, gy)

    def hessian(self, x, y):
        hxx = -self.ax * self.kx ** 2 * np.cos(self.kx * x + self.px)
        hyy = -self.ay * self.ky ** 2 * np.cos(self.ky * y + self.py)
        hxx, hyy = np.broadcast_arrays(hxx, hyy)
        return hxx, np.zeros_like(hxx), hyy

    def max_slope(self, region=None, pixel=None):
        return float(np.hypot(self.ax * self.kx, self.ay * self.ky))


class Plane(Surface):
    kind = "plane"

    def __init__(self, slope_x=0.0, slope_y=0.0, offset=0.0):
        self.sx, self.sy, self.offset = float(slope_x), float(slope_y), float(offset)

    def height(self, x, y):
        return self.sx * np.asarray(x, dtype=np.float64) + self.sy * np.asarray(y, dtype=np.float64) + self.offset

    def gradient(self, x, y):
        shape = np.broadcast(np.asarray(x), np.asarray(y)).shape
        return np.full(shape, self.sx), np.full(shape, self.sy)

    def hessian(self, x, y):
        shape = np.broadcast(np.asarray(x), np.asarray(y)).shape
        z = np.zeros(shape)
        return z, z.copy(), z.copy()

    def max_slope(self, region=None, pixel=None):
        return float(np.hypot(self.sx, self.sy))


class Biconic(Surface):
    """Biconic sag z = s * c r'^2 / (1 + sqrt(1 - (1+kx) cx^2 x^2 - (1+ky) cy^2 y^2)) form.

    ``radius`` > 0: convex (apex up, height falls away from the apex);
    ``radius`` < 0: concave.  Sphere and toric-like surfaces are special cases.
    Points outside the surface's domain raise InputError on evaluation (NaN would be
    silent).
    """
    kind = "biconic"

    def __init__(self, radius_x, radius_y, conic_x=0.0, conic_y=0.0, x0=0.0, y0=0.0, offset=0.0):
        if radius_x == 0 or radius_y == 0:
            raise InputError(f"radius_x and radius_y must be non-zero, received {radius_x}, {radius_y}")
        self.cx, self.cy = 1.0 / radius_x, 1.0 / radius_y
        self.kx, self.ky = float(conic_x), float(conic_y)
        self.x0, self.y0, self.offset = float(x0), float(y0), float(offset)

    def _parts(self, x, y):
        u = np.asarray(x, dtype=np.float64) - self.x0
        v = np.asarray(y, dtype=np.float64) - self.y0
        num = self.cx * u * u + self.cy * v * v
        arg = 1 - (1 + self.kx) * self.cx ** 2 * u * u - (1 + self.ky) * self.cy ** 2 * v * v
        if np.any(arg < 0):
            raise InputError("design point outside the surface's aperture (sqrt of a negative "
                             "number); shrink simulation.region or increase the radius")
        return u, v, num, np.sqrt(arg)

    def height(self, x, y):
        _, _, num, s = self._parts(x, y)
        return -num / (1 + s) + self.offset

    def gradient(self, x, y):
        u, v, num, s = self._parts(x, y)
        d = 1 + s
        # z = -num / d ; dnum/du = 2 cx u ; ds/du = -(1+kx) cx^2 u / s
        dnum_u, dnum_v = 2 * self.cx * u, 2 * self.cy * v
        with np.errstate(divide="ignore", invalid="ignore"):
            ds_u = np.where(s > 0, -(1 + self.kx) * self.cx ** 2 * u / s, 0.0)
            ds_v = np.where(s > 0, -(1 + self.ky) * self.cy ** 2 * v / s, 0.0)
        gx = -(dnum_u * d - num * ds_u) / d ** 2
        gy = -(dnum_v * d - num * ds_v) / d ** 2
        return gx, gy


class Sphere(Biconic):
    kind = "sphere"

    def __init__(self, radius, x0=0.0, y0=0.0, offset=0.0):
        super().__init__(radius, radius, 0.0, 0.0, x0, y0, offset)
        self.radius = float(radius)

    def height(self, x, y):
        u = np.asarray(x, dtype=np.float64) - self.x0
        v = np.asarray(y, dtype=np.float64) - self.y0
        r2 = u * u + v * v
        R = abs(self.radius)
        if np.any(r2 > R * R):
            raise InputError(f"design point outside the sphere (radius {self.radius} mm); "
                             "shrink simulation.region")
        sag = r2 / (R + np.sqrt(R * R - r2))
        return (-sag if self.radius > 0 else sag) + self.offset

    def gradient(self, x, y):
        u = np.asarray(x, dtype=np.float64) - self.x0
        v = np.asarray(y, dtype=np.float64) - self.y0
        R = abs(self.radius)
        w = np.sqrt(np.maximum(R * R - u * u - v * v, 1e-300))
        sgn = -1.0 if self.radius > 0 else 1.0
        return sgn * u / w, sgn * v / w


class Toric(Surface):
    """Torus section: circular section of radius ``radius_x`` along x; the y section
    radius ``radius_y`` (seed 002's R1 = 500, R2 = 250 mm).  Sign: > 0 convex."""
    kind = "toric"

    def __init__(self, radius_x, radius_y, offset=0.0):
        if radius_x == 0 or radius_y == 0:
            raise InputError(f"radius_x and radius_y must be non-zero, received {radius_x}, {radius_y}")
        self.rx, self.ry, self.offset = float(radius_x), float(radius_y), float(offset)

    def height(self, x, y):
        # sag of the x-section, then the ring of radius (Ry - sag_x) swept about the x-parallel axis
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        Rx, Ry = abs(self.rx), abs(self.ry)
        sx = x * x / (Rx + np.sqrt(np.maximum(Rx * Rx - x * x, 0)))
        sgn_x = 1.0 if self.rx > 0 else -1.0
        sgn_y = 1.0 if self.ry > 0 else -1.0
        # signed sag along x relative to the y-section's own radius
        rr = Ry - sgn_x * sgn_y * sx
        if np.any(np.abs(y) > np.abs(rr)) or np.any(np.abs(x) > Rx):
            raise InputError("design point outside the toric surface; shrink simulation.region")
        sy = rr - np.sqrt(rr * rr - y * y)
        total = sgn_x * sx + sgn_y * sy
        return -total + self.offset
