"""Tool-radius compensation of turning paths (Li et al. 2018 [1]_, eq. 6-8; the compound
sinusoidal grid paper [2]_, eq. 5-8).

``none``: the tool tip follows the design, z_tip = F(rho).
``normal``: the tool centre sits at CCP + Rc n along the surface normal projected into
    the cutting (radial) plane; rho moves as well as z.  The 3-D form of the compound
    sinusoidal grid paper (n_o = n_c - (n_c . n_p) n_p) reduces to the radial form of Li et
    al. (2018), rho' = rho - Rc sin(phi), z' = F + Rc cos(phi) - Rc (tan phi = dF/drho),
    because the tangential part of the normal is exactly what the projection removes.
``z``: rho is kept; the tool is lifted in Z until the nose arc touches the radial section:
    z' = max_u [F(u) - (Rc - sqrt(Rc^2 - (u - rho)^2))], |u - rho| <= w.  This is the
    paper's implicit equation solved robustly (several competing contacts are handled
    because the global maximum is taken).

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566`
.. [2] "Compound sinusoidal grid surface" machined by slow tool servo diamond turning
       (the project's copy lacks authors, journal and year: docs/references.md).
"""

from __future__ import annotations

import math

import numpy as np

_GOLD = (math.sqrt(5) - 1) / 2


def contact_window(nose_radius: float, max_slope: float, half_width: float | None = None) -> float:
    """Half-width (mm) of the radial window holding the tool/surface contact: the contact
    on a section of slope angle phi lies at Rc sin(phi) from the tool axis."""
    w = nose_radius * math.sin(math.atan(max(max_slope, 0.0))) * 1.25 + 1e-6
    if half_width is not None:
        w = min(w, half_width)
    return min(w, nose_radius)


def z_compensation(surface, theta, rho, nose_radius: float, *, max_slope: float | None = None,
                   half_width: float | None = None, samples: int = 9, iterations: int | None = None,
                   chunk: int = 32_768) -> np.ndarray:
    """Tool-tip Z for Z-direction compensation (Li et al. 2018, eq. 7-8), mm.

    Parameters
    ----------
    surface : Surface
    theta, rho : (n,) arrays, rad and mm (CCP angle and radius; the tool stays at rho)
    nose_radius : float, mm
    max_slope : float, optional
        Bound on |grad F| (sets the search window); estimated from the surface if None.
    half_width : float, optional
        Radial half-width of the nose arc (included angle); contacts beyond are ignored.
    samples, iterations : int
        Coarse samples of the window, then golden-section refinement of the best bracket;
        by default enough iterations to bring the height error below 1e-10 mm.

    Returns
    -------
    z_tip : (n,) float64
    """
    theta = np.asarray(theta, dtype=np.float64)
    rho = np.asarray(rho, dtype=np.float64)
    Rc = float(nose_radius)
    if max_slope is None:
        r = float(np.max(np.abs(rho))) + Rc
        max_slope = surface.max_slope((-r, -r, r, r))
    w = contact_window(Rc, max_slope, half_width)
    out = np.empty_like(rho)
    offs = np.linspace(-w, w, samples)
    step = offs[1] - offs[0]
    if iterations is None:
        # height error ~ g'' du^2 / 2 with g'' <~ 1 / Rc + curvature: aim at 1e-10 mm
        du = math.sqrt(2e-10 * Rc)
        iterations = max(4, int(math.ceil(math.log(du / (2 * step)) / math.log(_GOLD))))
    def run(a):
        th1 = theta[a:a + chunk]
        rh1 = rho[a:a + chunk]
        cs, sn = np.cos(th1), np.sin(th1)

        def gfun(d):
            u = rh1 + d
            return surface.height(u * cs, u * sn) - (Rc - np.sqrt(Rc * Rc - d * d))

        g = np.empty((rh1.size, samples))
        for k, o in enumerate(offs):
            g[:, k] = gfun(o)
        k = np.argmax(g, axis=1)
        best = g[np.arange(g.shape[0]), k]
        lo = np.maximum(offs[k] - step, -w)
        hi = np.minimum(offs[k] + step, w)
        c = hi - _GOLD * (hi - lo)
        d = lo + _GOLD * (hi - lo)
        gc, gd = gfun(c), gfun(d)
        for _ in range(iterations):
            left = gc > gd  # the maximum lies in [lo, d]
            hi = np.where(left, d, hi)
            lo = np.where(left, lo, c)
            c_new = np.where(left, hi - _GOLD * (hi - lo), d)
            d_new = np.where(left, c, lo + _GOLD * (hi - lo))
            g_eval = gfun(np.where(left, c_new, d_new))
            gc, gd = np.where(left, g_eval, gd), np.where(left, gc, g_eval)
            c, d = c_new, d_new
        out[a:a + chunk] = np.maximum(best, np.maximum(gc, gd))

    starts = list(range(0, rho.size, chunk))
    if len(starts) == 1:
        run(0)
    else:  # numpy releases the GIL in its ufuncs: one thread per core
        import os
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as ex:
            list(ex.map(run, starts))
    return out


def normal_compensation(surface, theta, rho, nose_radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Normal-direction compensation (the compound sinusoidal grid paper, eq. 5-8; in a
    turning set-up the same as Li et al. 2018, eq. 6).

    Returns (rho_tip, z_tip): the tool centre is P + Rc n_o / |n_o| with
    n_c = (-Fx, -Fy, 1), n_p = (-sin theta, cos theta, 0), n_o = n_c - (n_c . n_p) n_p;
    the tip is Rc below the centre."""
    theta = np.asarray(theta, dtype=np.float64)
    rho = np.asarray(rho, dtype=np.float64)
    c, s = np.cos(theta), np.sin(theta)
    x, y = rho * c, rho * s
    fx, fy = surface.gradient(x, y)
    nc = np.stack([-fx, -fy, np.ones_like(fx)])
    npl = np.stack([-s, c, np.zeros_like(s)])
    dot = np.sum(nc * npl, axis=0)
    no = nc - dot * npl
    no /= np.linalg.norm(no, axis=0)
    Rc = float(nose_radius)
    xc = x + Rc * no[0]
    yc = y + Rc * no[1]
    zc = surface.height(x, y) + Rc * no[2]
    # the centre stays in the radial plane: its signed radius along (cos, sin)
    rho_c = xc * c + yc * s
    return rho_c, zc - Rc


def gouge_depth(surface, theta, rho_tip, z_tip, nose_radius, *, max_slope=None, half_width=None):
    """How far (mm, >= 0) each programmed tool position cuts below the design section:
    the Z lift it would need to touch without gouging minus the lift it has."""
    need = z_compensation(surface, theta, rho_tip, nose_radius, max_slope=max_slope,
                          half_width=half_width)
    return np.maximum(need - np.asarray(z_tip), 0.0)
