"""Outliers, templates and 6-DOF rigid registration of a measured map to a design, after
the template-based characterisation of Kong et al. (2020) [1]_.

Convention: a rigid transform ``(tx, ty, tz, alpha, beta, gamma)`` moves the *design* into
the measured frame, ``p_measured = R q_design + t`` with ``R = Rz(gamma) Ry(beta) Rx(alpha)``
(rotations about the fixed x, y, z axes, in that order; radians; translations mm).

References
----------
.. [1] L. Kong, Y. Ma, M. Ren, M. Xu, C.-F. Cheung, "Generation and characterization of
       ultra-precision compound freeform surfaces," Science Progress 103(1), 1-12 (2020).
       :DOI:`10.1177/0036850419880112`
"""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import warnings

import numpy as np
from numpy.typing import ArrayLike
from ..core.lazy import lazy_attr, lazy_module

from ..core.blas import one_blas_thread
from ..core.errors import InputError
from ._filters import pixel_xy, valid_mask
from ._outliers import detect_outliers
from ._params import autocorrelation

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")
least_squares = lazy_attr("scipy.optimize", "least_squares")
fftconvolve = lazy_attr("scipy.signal", "fftconvolve")
Rotation = lazy_attr("scipy.spatial.transform", "Rotation")

__all__ = ["RIGID_KEYS", "rotation_matrix", "rigid_resample", "MovedSurface", "detect_outliers",
           "GridSurface", "template_surface", "register_lsq", "register_icp",
           "registration_covariance"]

#: keys of a rigid transform dict, in parameter order
RIGID_KEYS = ("tx_mm", "ty_mm", "tz_mm", "alpha_rad", "beta_rad", "gamma_rad")
_SHORT = {"tx": 0, "ty": 1, "tz": 2, "alpha": 3, "beta": 4, "gamma": 5}


def _vec(params) -> np.ndarray:
    if params is None:
        return np.zeros(6)
    if isinstance(params, dict):
        return np.array([float(params.get(k, 0.0)) for k in RIGID_KEYS])
    v = np.asarray(params, dtype=np.float64).ravel()
    if v.shape != (6,):
        raise InputError(f"a rigid transform needs 6 numbers {RIGID_KEYS}, got {v.shape[0]}")
    return v


def rotation_matrix(alpha: float, beta: float, gamma: float) -> np.ndarray:
    """``Rz(gamma) @ Ry(beta) @ Rx(alpha)`` (radians)."""
    return Rotation.from_euler("xyz", [alpha, beta, gamma]).as_matrix()


def _grid(shape, pixel, origin):
    ny, nx = shape
    px, py = pixel_xy(pixel)
    x = origin[0] + px * np.arange(nx)
    y = origin[1] + py * np.arange(ny)
    return np.meshgrid(x, y)


def rigid_resample(surface: Any, params: dict | Sequence[float], x: np.ndarray, y: np.ndarray, *,
                   iterations: int = 30) -> np.ndarray:
    """Heights at (``x``, ``y``) of ``surface`` moved by the rigid transform ``params``.

    This is the forward model of a (virtual) measurement of a misaligned part: solves
    ``[R q + t]_xy = (x, y)`` with ``q`` on the surface by fixed-point iteration (converges
    for the small angles of a set-up error; the result is exact to ~1e-12 mm).

    Parameters
    ----------
    surface : object with ``height(x, y)``
    params : dict with :data:`RIGID_KEYS` or sequence of 6 numbers
    x, y : arrays (broadcast), mm
    """
    v = _vec(params)
    r = rotation_matrix(*v[3:])
    t = v[:3]
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    x, y = np.broadcast_arrays(x, y)
    z = np.asarray(surface.height(x, y), dtype=np.float64) + t[2]
    for _ in range(iterations):
        px, py, pz = x - t[0], y - t[1], z - t[2]
        u = r[0, 0] * px + r[1, 0] * py + r[2, 0] * pz
        w = r[0, 1] * px + r[1, 1] * py + r[2, 1] * pz
        h = surface.height(u, w)
        znew = r[2, 0] * u + r[2, 1] * w + r[2, 2] * h + t[2]
        if np.nanmax(np.abs(znew - z)) < 1e-13:
            z = znew
            break
        z = znew
    return z


class MovedSurface:
    """``surface`` moved by a rigid transform (heights by :func:`rigid_resample`): the design
    as it lies in the measured frame after registration."""

    kind = "moved"

    def __init__(self, surface, params):
        self.surface = surface
        self.params = _vec(params)
        self._rot = rotation_matrix(*self.params[3:])

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return rigid_resample(self.surface, self.params, x, y)

    def gradient(self, x: np.ndarray, y: np.ndarray,
                 h: float = 1e-4) -> tuple[np.ndarray, np.ndarray]:
        return ((self.height(np.asarray(x) + h, y) - self.height(np.asarray(x) - h, y)) / (2 * h),
                (self.height(x, np.asarray(y) + h) - self.height(x, np.asarray(y) - h)) / (2 * h))

    def to_design(self, x: ArrayLike, y: ArrayLike,
                  z: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Design-frame coordinates ``R^T (p - t)`` of measured-frame points: (u, v, w)."""
        r, t = self._rot, self.params[:3]
        px, py, pz = np.asarray(x) - t[0], np.asarray(y) - t[1], np.asarray(z) - t[2]
        return (r[0, 0] * px + r[1, 0] * py + r[2, 0] * pz,
                r[0, 1] * px + r[1, 1] * py + r[2, 1] * pz,
                r[0, 2] * px + r[1, 2] * py + r[2, 2] * pz)

    def move_point(self, x: float, y: float) -> tuple[float, float, float]:
        """Where the design point above (``x``, ``y``) lies after the move: (x', y', z')."""
        q = np.array([x, y, float(self.surface.height(np.float64(x), np.float64(y)))])
        p = self._rot @ q + self.params[:3]
        return float(p[0]), float(p[1]), float(p[2])


class GridSurface:
    """A design template given as heights on a grid, interpolated by bicubic splines
    (``height``/``gradient`` like a design :class:`~render_inspect.design.Surface`)."""

    kind = "template"

    def __init__(self, z, *, pixel, origin=(0.0, 0.0)):
        from scipy.interpolate import RectBivariateSpline

        z = np.asarray(z, dtype=np.float64)
        px, py = pixel_xy(pixel)
        if z.ndim != 2 or min(z.shape) < 4:
            raise InputError(f"template must be a 2-D map of at least 4 x 4 points, got {z.shape}")
        if not np.isfinite(z).all():
            raise InputError("template must not contain NaN (sample the design where it is defined)")
        self.pixel = (px, py)
        self.origin = (float(origin[0]), float(origin[1]))
        x = self.origin[0] + px * np.arange(z.shape[1])
        y = self.origin[1] + py * np.arange(z.shape[0])
        self._spl = RectBivariateSpline(y, x, z, kx=3, ky=3)
        self._bounds = (x[0], x[-1], y[0], y[-1])

    def height(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        h = self._spl.ev(y, x)
        x0, x1, y0, y1 = self._bounds
        out = (x < x0) | (x > x1) | (y < y0) | (y > y1)
        return np.where(out, np.nan, h)

    def gradient(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return self._spl.ev(y, x, dy=1), self._spl.ev(y, x, dx=1)


def template_surface(design: Any, *, region: Sequence[float], pixel: float | tuple[float, float],
                     oversample: int = 10) -> GridSurface:
    """Sample ``design`` (a Surface) on ``region`` = (x0, y0, x1, y1) at ``pixel / oversample``
    in x and y (Kong et al. 2020: the template is at least 10 x denser than the
    measurement)."""
    ppx, ppy = pixel_xy(pixel)
    if oversample < 10:
        warnings.warn(f"template oversample={oversample}: Kong et al. (2020) ask for >= 10 x "
                      f"the measured density; registration accuracy may suffer", stacklevel=2)
    qx, qy = ppx / oversample, ppy / oversample
    x0, y0, x1, y1 = region
    nx = int(np.ceil((x1 - x0) / qx)) + 1
    ny = int(np.ceil((y1 - y0) / qy)) + 1
    if nx * ny > 25_000_000:
        raise InputError(f"template of {ny} x {nx} points is too large; reduce the region or oversample")
    x = x0 + qx * np.arange(nx)
    y = y0 + qy * np.arange(ny)
    z = np.broadcast_to(design.height(x[None, :], y[:, None]), (ny, nx))
    return GridSurface(z, pixel=(qx, qy), origin=(x0, y0))


def _prepare(z, pixel, origin, mask, max_points, rng):
    z = np.asarray(z, dtype=np.float64)
    pixel_xy(pixel)
    ok = valid_mask(z, mask)
    if ok.sum() < 6:
        raise InputError(f"registration needs at least 6 valid points, got {int(ok.sum())} "
                         f"(is the map all NaN or fully masked?)")
    xx, yy = _grid(z.shape, pixel, origin)
    px, py, pz = xx[ok], yy[ok], z[ok]
    if px.size > max_points:
        idx = np.random.default_rng(rng).choice(px.size, max_points, replace=False)
        idx.sort()
        px, py, pz = px[idx], py[idx], pz[idx]
    return px, py, pz


def _result(v, rms, n, method, **extra):
    d = {k: float(x) for k, x in zip(RIGID_KEYS, v)}
    d.update({"rms_mm": float(rms), "n_points": int(n), "method": method})
    d.update(extra)
    return d


@one_blas_thread()  # (products of points x 6: one thread each; docs/performance.md)
def register_lsq(z: np.ndarray, design: Any, *, pixel: float | tuple[float, float],
                 origin: Sequence[float] = (0.0, 0.0), mask: np.ndarray | None = None,
                 init: dict | Sequence[float] | None = None,
                 fit: Sequence[str] = ("tx", "ty", "tz", "alpha", "beta", "gamma"),
                 max_points: int = 200_000,
                 seed: int = 0) -> dict:
    """Least-squares 6-DOF rigid registration of a measured map to a design (Kong et al.
    2020, step 3).

    Minimises, over the transform, the vertical distances in the design frame
    ``[R^T (p - t)]_z - F([R^T (p - t)]_x, [R^T (p - t)]_y)`` of the measured points ``p``.

    Parameters
    ----------
    z : (ny, nx) array
        Measured heights, mm (NaN = missing; remove outliers first, see :func:`detect_outliers`).
    design : object with ``height(x, y)``
        The design surface or a :class:`GridSurface` template.
    pixel : float or (pixel_x, pixel_y)
        mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    mask : bool array, optional
        Points to use (``False`` leaves out, e.g. the lenslets when matching the base).
    init : dict or 6 numbers, optional
        Starting transform (default identity).
    fit : sequence of {"tx", "ty", "tz", "alpha", "beta", "gamma"}
        Parameters to fit; the others stay at ``init``.  Leave out those the design cannot
        determine (a plane fixes only tz, alpha, beta; a sphere has no gamma).
    max_points : int
        At most this many points are used (a seeded random subset).

    Returns
    -------
    dict
        :data:`RIGID_KEYS`, ``rms_mm`` (residual RMS), ``n_points``, ``method`` = "lsq",
        ``fitted``, ``sigma_formal`` (standard errors of the fitted parameters from the
        Jacobian, assuming independent residuals: ``s^2 (J^T J)^-1``; see
        :func:`registration_covariance` for residuals that are spatially correlated).
    """
    px, py, pz = _prepare(z, pixel, origin, mask, max_points, seed)
    v0 = _vec(init)
    idx = _fit_indices(fit)
    scale = np.full(len(idx), 1e-3)
    use_jac = hasattr(design, "gradient")
    coarse = 20_000
    if px.size > 4 * coarse:
        # coarse to fine: most iterations on a seeded subset, the last ones on all points
        sub = np.sort(np.random.default_rng(seed + 1).choice(px.size, coarse, replace=False))
        r_c, j_c = _lsq_problem(px[sub], py[sub], pz[sub], design, v0, idx)
        sol_c = least_squares(r_c, v0[idx], x_scale=scale, method="trf",
                              jac=j_c if use_jac else "2-point", diff_step=1e-7,
                              xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=200)
        v0 = v0.copy()
        v0[idx] = sol_c.x
    resid, jac = _lsq_problem(px, py, pz, design, v0, idx)
    # after the coarse stage a map of the design converges in a few steps; a map of
    # something else does not converge at all, and more steps would not change that
    sol = least_squares(resid, v0[idx], x_scale=scale, method="trf",
                        jac=jac if use_jac else "2-point", diff_step=1e-7,
                        xtol=1e-12, ftol=1e-14, gtol=1e-14,
                        max_nfev=15 if px.size > 4 * coarse else 200)
    v = v0.copy()
    v[idx] = sol.x
    rms = np.sqrt(np.mean(sol.fun ** 2))
    sig = _formal_sigma(sol.jac, sol.fun)
    return _result(v, rms, px.size, "lsq", fitted=[k for k in _SHORT if _SHORT[k] in idx],
                   sigma_formal={RIGID_KEYS[i]: float(e) for i, e in zip(idx, sig)})


def _fit_indices(fit):
    idx = []
    for name in fit:
        if name not in _SHORT:
            raise InputError(f"fit entries must be among {tuple(_SHORT)}, got {name!r}")
        idx.append(_SHORT[name])
    idx = sorted(set(idx))
    if not idx:
        raise InputError("fit must name at least one parameter")
    return idx


def _lsq_problem(px, py, pz, design, v0, idx):
    """Residual and Jacobian functions of the registration over the parameters ``idx``."""

    def resid(p):
        v = v0.copy()
        v[idx] = p
        r = rotation_matrix(*v[3:])
        qx, qy, qz = px - v[0], py - v[1], pz - v[2]
        u = r[0, 0] * qx + r[1, 0] * qy + r[2, 0] * qz
        w = r[0, 1] * qx + r[1, 1] * qy + r[2, 1] * qz
        h = r[0, 2] * qx + r[1, 2] * qy + r[2, 2] * qz
        res = h - design.height(u, w)
        return np.where(np.isfinite(res), res, 0.0)

    def jac(p):
        # r = q_z - F(q_x, q_y), q = R^T (p - t): dr = dq_z - Fx dq_x - Fy dq_y with
        # dq/dt = -R^T and dq/dangle = (dR/dangle)^T (p - t) (dR by central differences)
        v = v0.copy()
        v[idx] = p
        r = rotation_matrix(*v[3:])
        d = np.stack([px - v[0], py - v[1], pz - v[2]])
        q = r.T @ d
        gx, gy = design.gradient(q[0], q[1])
        gx, gy = np.nan_to_num(np.asarray(gx, float)), np.nan_to_num(np.asarray(gy, float))
        cols = []
        for k in idx:
            if k < 3:
                dq = -r.T[:, k][:, None] * np.ones_like(px)
            else:
                h = 1e-7
                a = v[3:].copy()
                a[k - 3] += h
                b = v[3:].copy()
                b[k - 3] -= h
                dr = (rotation_matrix(*a) - rotation_matrix(*b)) / (2 * h)
                dq = dr.T @ d
            cols.append(dq[2] - gx * dq[0] - gy * dq[1])
        return np.column_stack(cols)

    return resid, jac


def _normal_inverse(j) -> np.ndarray:
    """``(J^T J)^-1`` that stays honest when J is (nearly) rank deficient: the columns are
    scaled to unit norm and the eigenvalues of the scaled normal matrix floored at 1e-16 of
    the largest, so an undetermined parameter gets a huge variance instead of a truncated
    (zero) one."""
    j = np.asarray(j, dtype=np.float64)
    norm = np.linalg.norm(j, axis=0)
    norm = np.where(norm > 0, norm, 1.0)
    a = (j / norm).T @ (j / norm)
    w, v = np.linalg.eigh(0.5 * (a + a.T))
    w = np.maximum(w, max(float(w.max()), 1e-300) * 1e-16)
    inv = (v / w) @ v.T
    return inv / np.outer(norm, norm)


def _formal_sigma(j, fun) -> np.ndarray:
    """Standard errors ``sqrt(diag(s^2 (J^T J)^-1))``, ``s^2 = |r|^2 / (n - p)``."""
    j = np.asarray(j, dtype=np.float64)
    n, p = j.shape
    s2 = float(np.sum(np.asarray(fun) ** 2)) / max(n - p, 1)
    return np.sqrt(np.maximum(np.diag(s2 * _normal_inverse(j)), 0.0))


@one_blas_thread()
def registration_covariance(z: np.ndarray, design: Any, reg: dict, *,
                            pixel: float | tuple[float, float],
                            origin: Sequence[float] = (0.0, 0.0), mask: np.ndarray | None = None,
                            residual: np.ndarray | None = None, max_points: int = 250_000) -> dict:
    """Standard uncertainties of a registration (an LSQ or ICP result).

    With independent residuals the covariance of the fitted parameters is the formal
    ``s^2 (J^T J)^-1``.  Measured residuals are spatially correlated (roughness,
    waviness, form error), which that underestimates.  Given the residual map, the
    covariance is the sandwich ``(J^T J)^-1 J^T C J (J^T J)^-1`` with ``C`` the residual
    autocovariance: ``s^2`` times the residual's autocorrelation (:func:`autocorrelation`)
    over its positive central lobe, applied to each Jacobian column as a convolution on
    the grid.  For white residuals it reduces to the formal value.

    Parameters
    ----------
    z : (ny, nx) array
        Measured heights, mm.
    design : object with ``height`` (and ``gradient``)
    reg : dict
        Result of :func:`register_lsq` / :func:`register_icp` (``fitted`` names the free
        parameters; all six when absent).
    pixel, origin
        mm.
    mask : bool array, optional
        Points used by the registration.
    residual : (ny, nx) array, optional
        Measured minus registered design (NaN where not used).
    max_points : int
        Larger maps are evaluated on every k-th row and column (k the smallest stride that
        leaves at most this many valid points): the uncertainty of a fit to that subgrid,
        a little conservative for the full map.

    Returns
    -------
    dict
        ``sigma`` (per fitted key of :data:`RIGID_KEYS`; mm or rad), ``sigma_formal``,
        ``inflation`` (sigma / sigma_formal per key), ``method``, ``n_points``.
    """
    z = np.asarray(z, dtype=np.float64)
    sx, sy = pixel_xy(pixel)
    ok = valid_mask(z, mask)
    if ok.sum() < 6:
        raise InputError(f"registration_covariance: need at least 6 valid points, got {int(ok.sum())}")
    stride = max(1, int(np.ceil(np.sqrt(ok.sum() / max_points))))
    if stride > 1:
        z, ok = z[::stride, ::stride], ok[::stride, ::stride]
        residual = None if residual is None else np.asarray(residual)[::stride, ::stride]
        sx, sy = sx * stride, sy * stride
    xx, yy = _grid(z.shape, (sx, sy), origin)
    pts = (xx[ok], yy[ok], z[ok])
    idx = _fit_indices(reg.get("fitted") or list(_SHORT))
    v = _vec({k: reg.get(k, 0.0) for k in RIGID_KEYS})
    resid, jac = _lsq_problem(*pts, design, v, idx)
    fun = resid(v[idx])
    if hasattr(design, "gradient"):
        j = jac(v[idx])
    else:
        h = 1e-7
        j = np.column_stack([(resid(v[idx] + h * e) - resid(v[idx] - h * e)) / (2 * h)
                             for e in np.eye(len(idx))])
    n, p = j.shape
    s2 = float(np.sum(fun ** 2)) / max(n - p, 1)
    a_inv = _normal_inverse(j)
    formal = np.sqrt(np.maximum(np.diag(s2 * a_inv), 0.0))
    cov = s2 * a_inv
    method = "formal (independent residuals)"
    if residual is not None and np.isfinite(residual).sum() >= 16:
        acf, _ = autocorrelation(residual)
        cy, cx = acf.shape[0] // 2, acf.shape[1] // 2
        lab, _ = ndimage.label(np.nan_to_num(acf, nan=-1.0) > 0)
        lobe = lab == lab[cy, cx]
        rows, cols = np.nonzero(lobe)
        hr = int(max(cy - rows.min(), rows.max() - cy))
        hc = int(max(cx - cols.min(), cols.max() - cx))
        kern = np.where(lobe, np.nan_to_num(acf), 0.0)[cy - hr:cy + hr + 1, cx - hc:cx + hc + 1]
        m = np.empty((p, p))
        grids = []
        for c in range(p):
            g = np.zeros(z.shape)
            g[ok] = j[:, c]
            grids.append(g)
        for b_ in range(p):
            conv = fftconvolve(grids[b_], kern, mode="same")
            for a_ in range(p):
                m[a_, b_] = np.sum(grids[a_][ok] * conv[ok])
        m = 0.5 * (m + m.T)
        cov = s2 * a_inv @ m @ a_inv
        method = "sandwich with the residual autocovariance"
    sig = np.sqrt(np.maximum(np.diag(cov), np.diag(s2 * a_inv)))
    keys = [RIGID_KEYS[i] for i in idx]
    return {"sigma": {k: float(e) for k, e in zip(keys, sig)},
            "sigma_formal": {k: float(e) for k, e in zip(keys, formal)},
            "inflation": {k: float(e / f) if f > 0 else 1.0 for k, e, f in zip(keys, sig, formal)},
            "method": method, "n_points": int(n), "stride": stride}


def register_icp(z: np.ndarray, design: Any, *, pixel: float | tuple[float, float],
                 origin: Sequence[float] = (0.0, 0.0), mask: np.ndarray | None = None,
                 init: dict | Sequence[float] | None = None,
                 fit: Sequence[str] = ("tx", "ty", "tz", "alpha", "beta", "gamma"),
                 oversample: int = 10, max_iter: int = 50, tol: float = 1e-10,
                 max_points: int = 100_000, seed: int = 0) -> dict:
    """Point-to-plane ICP registration of a measured map to a dense design template.

    The design is sampled at ``pixel / oversample`` over the measured area (plus a margin);
    each iteration pairs every measured point with its nearest template point (k-d tree),
    leaves out pairs farther than 5 robust sigma, and solves the linearised point-to-plane
    least squares for the parameters named in ``fit``; the others stay at ``init`` (each
    step is solved without them and the transform then set back to ``init`` in them).
    Same conventions and result keys as :func:`register_lsq` (``method`` = "icp", plus
    ``iterations``, ``fitted`` and ``template_pixel_mm``).
    """
    template = _icp_template(design, np.shape(z), pixel=pixel, origin=origin,
                             oversample=oversample)
    px, py, pz = _prepare(z, pixel, origin, mask, max_points, seed)
    return _icp_solve(np.column_stack([px, py, pz]), template, init=init, fit=fit,
                      max_iter=max_iter, tol=tol)


#: the most points an ICP template may have (its points, their normals and its k-d tree
#: are held together)
_ICP_TEMPLATE_POINTS = 6_000_000


def _icp_template(design, shape, *, pixel, origin, oversample):
    """The ICP template of ``design`` over a map of ``shape`` (plus a margin): its k-d
    tree, points, unit normals and spacing (mm)."""
    from scipy.spatial import cKDTree  # scipy.spatial loads slowly; only ICP needs a tree

    ny, nx = shape
    sx, sy = pixel_xy(pixel)
    margin = 0.05 * max(nx * sx, ny * sy) + 3 * max(sx, sy)
    region = (origin[0] - margin, origin[1] - margin,
              origin[0] + (nx - 1) * sx + margin, origin[1] + (ny - 1) * sy + margin)
    def points(k: float) -> float:  # the template's points at an oversampling of k
        t = min(sx, sy) / k
        return ((region[2] - region[0]) / t + 1) * ((region[3] - region[1]) / t + 1)

    tp = min(sx, sy) / oversample
    n_t = points(oversample)
    if n_t > _ICP_TEMPLATE_POINTS:
        fits = max((k for k in range(1, int(oversample)) if points(k) <= _ICP_TEMPLATE_POINTS),
                   default=None)
        room = (f"must be at most {fits}" if fits is not None else
                "cannot be small enough (crop the map)")
        raise InputError(f"metrology.template_oversample (the ICP template's density) {room} "
                         f"for a map of {ny} x {nx} pixels (its template would have "
                         f"{n_t:.3g} points, more than {_ICP_TEMPLATE_POINTS:,}), received "
                         f"{oversample}")
    tx = np.arange(region[0], region[2] + tp / 2, tp)
    ty = np.arange(region[1], region[3] + tp / 2, tp)
    txx, tyy = np.meshgrid(tx, ty)
    tz = np.asarray(design.height(txx, tyy), dtype=np.float64)
    gx, gy = design.gradient(txx, tyy)
    keep = np.isfinite(tz) & np.isfinite(gx) & np.isfinite(gy)
    tpts = np.column_stack([txx[keep], tyy[keep], tz[keep]])
    nrm = np.column_stack([-np.asarray(gx)[keep], -np.asarray(gy)[keep], np.ones(keep.sum())])
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    return cKDTree(tpts), tpts, nrm, float(tp)


@one_blas_thread()
def _icp_solve(pts, template, *, init=None, fit=tuple(_SHORT), max_iter=50, tol=1e-10):
    """ICP iterations of the measured points ``pts`` (n x 3) against ``template``
    (:func:`_icp_template`), fitting the parameters ``fit``."""
    tree, tpts, nrm, tp = template
    idx = _fit_indices(fit)
    v0 = _vec(init)
    held_t = [k for k in range(3) if k not in idx]
    held_a = [k for k in range(3) if k + 3 not in idx]
    # unknowns: rotation vector (3) and translation (3) of the step, in the design frame;
    # a held parameter's column is left out (for the small tilts of a set-up that is the
    # step's own component), and the transform is set back to ``init`` in it after the step
    cols = [k for k in range(6) if (k + 3 if k < 3 else k - 3) in idx]
    v = v0.copy()
    rot = rotation_matrix(*v[3:])
    t = v[:3].copy()
    it = 0
    rms = np.nan
    for it in range(1, max_iter + 1):
        q = (pts - t) @ rot  # R^T (p - t), row-wise
        _, j = tree.query(q, workers=1)
        d = tpts[j]
        n = nrm[j]
        r = np.einsum("ij,ij->i", q - d, n)
        med = np.median(r)
        sig = 1.4826 * np.median(np.abs(r - med)) + 1e-15
        use = np.abs(r - med) < 5 * sig + 1e-9
        a = np.column_stack([np.cross(q[use], n[use]), n[use]])[:, cols]
        part, *_ = np.linalg.lstsq(a, -r[use], rcond=None)
        sol = np.zeros(6)
        sol[cols] = part
        w, dt = sol[:3], sol[3:]
        dr = Rotation.from_rotvec(w).as_matrix()
        # inverse map q = R^T (p - t) becomes dR R^T (p - t) + dt
        rot_new = rot @ dr.T
        t = rot_new @ (dr @ rot.T @ t - dt)
        rot = rot_new
        if held_a:
            ang = Rotation.from_matrix(rot).as_euler("xyz")
            ang[held_a] = v0[3:][held_a]
            rot = rotation_matrix(*ang)
        t[held_t] = v0[held_t]
        rms = float(np.sqrt(np.mean(r[use] ** 2)))
        if np.linalg.norm(w) < tol and np.linalg.norm(dt) < tol:
            break
    ang = Rotation.from_matrix(rot).as_euler("xyz")
    ang[held_a] = v0[3:][held_a]
    return _result(np.concatenate([t, ang]), rms, pts.shape[0], "icp", iterations=it,
                   fitted=[k for k in _SHORT if _SHORT[k] in idx], template_pixel_mm=tp)
