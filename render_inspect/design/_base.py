"""The design-surface interface: height, gradient, Hessian and curvature of z = F(x, y).

Every length is in mm.  Arrays broadcast like numpy ufuncs.
"""

from __future__ import annotations

from collections.abc import Sequence
import abc

import numpy as np


class Surface(abc.ABC):
    """Base class of design surfaces.

    Subclasses implement :meth:`height` and, where they can, analytic :meth:`gradient`
    and :meth:`hessian`; the defaults here are central differences with step ``fd_step``.
    """

    #: finite-difference step (mm) for the default gradient/Hessian
    fd_step: float = 1e-4
    #: human-readable name, and the config that built it (provenance)
    kind: str = "surface"

    @abc.abstractmethod
    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        """F(x, y) in mm; ``x`` and ``y`` (mm) broadcast like numpy ufuncs."""

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(dz/dx, dz/dy)."""
        h = self.fd_step
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        gx = (self.height(x + h, y) - self.height(x - h, y)) / (2 * h)
        gy = (self.height(x, y + h) - self.height(x, y - h)) / (2 * h)
        return gx, gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(d2z/dx2, d2z/dxdy, d2z/dy2)."""
        h = max(self.fd_step, 1e-3)
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        gxp, gyp = self.gradient(x + h, y)
        gxm, gym = self.gradient(x - h, y)
        _, gyyp = self.gradient(x, y + h)
        _, gyym = self.gradient(x, y - h)
        hxx = (gxp - gxm) / (2 * h)
        hxy = (gyp - gym) / (2 * h)
        hyy = (gyyp - gyym) / (2 * h)
        return hxx, hxy, hyy

    # ---- derived quantities ---------------------------------------------------------
    def lateral_scale(self) -> float | None:
        """The design's own lateral scale (mm): the length over which its shape changes,
        on which the waviness a process leaves on it lies (a sinusoid's wavelength, a
        lenslet pitch, an element's diameter); None for a design without one (a plane, a
        sphere, a free form).  The S/L filters of a comparison are chosen around it."""
        return None

    def radial_slope(self, rho: np.ndarray | float, theta: np.ndarray | float) -> np.ndarray:
        """dF/drho along the radial section at angle ``theta`` (rad)."""
        c, s = np.cos(theta), np.sin(theta)
        gx, gy = self.gradient(rho * c, rho * s)
        return gx * c + gy * s

    def radial_profile(self, rho: np.ndarray | float, theta: np.ndarray | float) -> np.ndarray:
        """F along the radial section at angle ``theta``."""
        return self.height(rho * np.cos(theta), rho * np.sin(theta))

    def section_curvature(self, x: np.ndarray | float, y: np.ndarray | float,
                          direction: np.ndarray | float) -> np.ndarray:
        """Signed curvature (1/mm) of the section through (x, y) along the unit direction
        angle ``direction`` (rad): F_uu / (1 + F_u^2)^1.5; > 0 where the section is concave
        (bowl-like, the tool nose must fit inside)."""
        c, s = np.cos(direction), np.sin(direction)
        gx, gy = self.gradient(x, y)
        hxx, hxy, hyy = self.hessian(x, y)
        fu = gx * c + gy * s
        fuu = hxx * c * c + 2 * hxy * c * s + hyy * s * s
        return fuu / (1 + fu * fu) ** 1.5

    def curvature(self, x: np.ndarray | float,
                  y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        """(mean, Gaussian) curvature of the graph surface, 1/mm and 1/mm^2."""
        gx, gy = self.gradient(x, y)
        hxx, hxy, hyy = self.hessian(x, y)
        w = 1 + gx * gx + gy * gy
        gauss = (hxx * hyy - hxy * hxy) / (w * w)
        mean = ((1 + gx * gx) * hyy - 2 * gx * gy * hxy + (1 + gy * gy) * hxx) / (2 * w ** 1.5)
        return mean, gauss

    def max_slope(self, region: Sequence[float], pixel: float | None = None) -> float:
        """Largest |grad F| over ``region`` = (x0, y0, x1, y1), sampled on 257 rows of up to
        1025 points (finer along x when ``pixel`` is small)."""
        x0, y0, x1, y1 = region
        nx = 257 if not pixel else int(min(1025, max(257, (x1 - x0) / pixel / 4)))
        xs = np.linspace(x0, x1, nx)
        ys = np.linspace(y0, y1, 257)
        gx, gy = self.gradient(xs[None, :], ys[:, None])
        return float(np.nanmax(np.hypot(gx, gy)))

    def sample(self, region: Sequence[float],
               pixel: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Heights on the grid of ``region``/``pixel`` (row 0 = smallest y): (x, y, z)."""
        x0, y0, x1, y1 = region
        nx = int(round((x1 - x0) / pixel)) + 1
        ny = int(round((y1 - y0) / pixel)) + 1
        x = x0 + pixel * np.arange(nx)
        y = y0 + pixel * np.arange(ny)
        z = self.height(x[None, :], y[:, None])
        return x, y, np.broadcast_to(z, (ny, nx)).copy()

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
