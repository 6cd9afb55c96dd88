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
``edge``: ``z`` against the measured cutting edge (``[tool] edge_profile`` / ``waviness``):
    the nose's height at the offset u - rho is the edge's, Rc - sqrt(Rc^2 - (u - rho)^2)
    + g(u - rho) (g from ``EdgeProfile.height_table``), so the tool is lifted until the real
    edge touches.  Where the edge bulges (delta > 0) at the contact angle the path rises by
    delta / cos(theta), and the form error the edge would imprint cancels: the tool-edge
    waviness compensation of diamond turning (docs/references.md: tool waviness
    compensation).

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

from typing import Any
import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from ..core.lazy import njit  # numba, imported on first use
from ._edge import EdgeProfile

_GOLD = (math.sqrt(5) - 1) / 2


# The golden-section search of z_compensation, written as loops over the points: the same
# operations, in the same order, as the array form it replaced (a value of numpy.where
# here is the branch taken), so the tool path is the same to the last bit.  The surface
# itself is evaluated by its own (numpy) code between the stages of the search: one
# kernel takes the heights of the points of one stage and gives the points of the next
# (one compiled kernel to load, no temporary arrays between the stages).

#: columns of the search's state (``_search``'s ``st``): the best coarse sample, the bracket
#: (lo, hi), its inner points (c, d) and their values (gc, gd), the point evaluated next
#: and which half was kept (1: the maximum lies in [lo, d])
_BEST, _LO, _HI, _C, _D, _GC, _GD, _X, _LEFT = range(9)


@njit(cache=True, nogil=True)
def _less_nose(h, d, Rc, edge):
    """h - (Rc - sqrt(Rc^2 - d^2)): the design less the nose arc at offset d; with an
    ``edge`` (the height table [d0, 1 / step, lowest, g_0 ..], linearly interpolated),
    less the measured edge, h - (Rc - sqrt(Rc^2 - d^2) + g(d))."""
    if edge.size == 0:
        return h - (Rc - np.sqrt(Rc * Rc - d * d))
    n = edge.size - 3
    u = (d - edge[0]) * edge[1]
    if u <= 0.0:
        g = edge[3]
    elif u >= n - 1:
        g = edge[n + 2]
    else:
        k = int(u)
        g = edge[3 + k] + (u - k) * (edge[4 + k] - edge[3 + k])
    return h - (Rc - np.sqrt(Rc * Rc - d * d) + g)


@njit(cache=True, nogil=True)
def _search(stage, h, rho, cs, sn, offs, step, w, G, Rc, edge, iterations, g, st, X, Y, out):
    """Stage ``stage`` of the search of one chunk of points: ``h`` holds the design's
    heights at the points (X, Y) the stage before gave (none at stage 0); the points of
    the next stage are written into X, Y.  Stages 0 .. S - 1 sample the window at the
    coarse offsets ``offs`` (S of them; columns of ``g``), stage S brackets the best sample
    and asks for its inner point c, S + 1 for d, and each stage after that takes the
    value of the point it asked for and moves the bracket (golden section), ``iterations``
    times; the last writes the result into ``out`` and returns True."""
    ns = offs.size
    m = rho.size
    if stage <= ns:
        if stage > 0:  # the coarse sample at offset offs[stage - 1]
            o = offs[stage - 1]
            for i in range(m):
                g[i, stage - 1] = _less_nose(h[i], o, Rc, edge)
        if stage < ns:
            o = offs[stage]
            for i in range(m):
                u = rho[i] + o
                X[i] = u * cs[i]
                Y[i] = u * sn[i]
            return False
        # the best coarse sample, the golden-section bracket around it and its inner points
        for i in range(m):
            k = 0
            for j in range(1, ns):
                if g[i, j] > g[i, k]:
                    k = j
            st[i, _BEST] = g[i, k]
            lo = max(offs[k] - step, -w)
            hi = min(offs[k] + step, w)
            st[i, _LO] = lo
            st[i, _HI] = hi
            st[i, _C] = hi - G * (hi - lo)
            st[i, _D] = lo + G * (hi - lo)
            st[i, _X] = st[i, _C]
    elif stage == ns + 1:
        for i in range(m):
            st[i, _GC] = _less_nose(h[i], st[i, _C], Rc, edge)
            st[i, _X] = st[i, _D]
    else:
        k = stage - ns - 2  # the iterations done
        for i in range(m):
            v = _less_nose(h[i], st[i, _X], Rc, edge)
            if k == 0:
                st[i, _GD] = v
            elif st[i, _LEFT] != 0.0:
                st[i, _GD] = st[i, _GC]
                st[i, _GC] = v
            else:
                st[i, _GC] = st[i, _GD]
                st[i, _GD] = v
            if k == iterations:
                out[i] = max(st[i, _BEST], max(st[i, _GC], st[i, _GD]))
                continue
            # one step: keep the better half, and the point to evaluate next
            lo, hi, c, d = st[i, _LO], st[i, _HI], st[i, _C], st[i, _D]
            if st[i, _GC] > st[i, _GD]:
                st[i, _LEFT] = 1.0
                hi = d
                cn = hi - G * (hi - lo)
                dn = c
                st[i, _X] = cn
            else:
                st[i, _LEFT] = 0.0
                lo = c
                cn = d
                dn = lo + G * (hi - lo)
                st[i, _X] = dn
            st[i, _LO], st[i, _HI], st[i, _C], st[i, _D] = lo, hi, cn, dn
        if k == iterations:
            return True
    for i in range(m):
        u = rho[i] + st[i, _X]
        X[i] = u * cs[i]
        Y[i] = u * sn[i]
    return False


def contact_window(nose_radius: float, max_slope: float, half_width: float | None = None) -> float:
    """Half-width (mm) of the radial window holding the tool/surface contact: the contact
    on a section of slope angle phi lies at Rc sin(phi) from the tool axis."""
    w = nose_radius * math.sin(math.atan(max(max_slope, 0.0))) * 1.25 + 1e-6
    if half_width is not None:
        w = min(w, half_width)
    return min(w, nose_radius)


def z_compensation(surface: Any, theta: np.ndarray, rho: np.ndarray, nose_radius: float, *,
                   max_slope: float | None = None,
                   half_width: float | None = None, samples: int = 9, iterations: int | None = None,
                   chunk: int = 32_768, edge: EdgeProfile | None = None,
                   ccp_height: np.ndarray | None = None) -> np.ndarray:
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
    edge : EdgeProfile, optional
        Compensate against the measured cutting edge instead of the circular nose (the
        ``edge`` compensation); the window is then widened by the edge's height range and
        sampled at 129 points at least, so that the search brackets the global contact.
    ccp_height : (n,) array, optional
        The design's heights at the points themselves (rho cos theta, rho sin theta),
        where the caller has them: the search's sample at offset 0 takes them instead of
        evaluating the design there again.

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
    etab = None
    if edge is not None:
        hw = Rc if half_width is None else min(float(half_width), Rc)
        etab = edge if isinstance(edge, np.ndarray) else edge.height_table(Rc, hw)
        # the edge's deviation can move the contact within the whole window: sample it finely
        samples = max(samples, 129)
        w = min(hw, w + math.sqrt(2.0 * Rc * float(etab[3:].max() - etab[3:].min())))
    out = np.empty_like(rho)
    offs = np.linspace(-w, w, samples)
    step = offs[1] - offs[0]
    if iterations is None:
        # height error ~ g'' du^2 / 2 with g'' <~ 1 / Rc + curvature: aim at 1e-10 mm
        du = math.sqrt(2e-10 * Rc)
        iterations = max(4, int(math.ceil(math.log(du / (2 * step)) / math.log(_GOLD))))

    etab = np.zeros(0) if etab is None else np.ascontiguousarray(etab, dtype=np.float64)
    # the design's heights at the points themselves, where the caller has them: the
    # coarse sample at offset 0 is those points (u = rho + 0 = rho), bit for bit
    z0 = None
    if ccp_height is not None and not np.signbit(rho).any():
        z0 = np.ascontiguousarray(ccp_height, dtype=np.float64)
        if z0.shape != rho.shape:
            raise ValueError(f"ccp_height has {z0.shape} points, rho {rho.shape}")
    at_zero = [k for k in range(samples) if offs[k] == 0.0] if z0 is not None else []

    def run(a):
        th1 = theta[a:a + chunk]
        rh1 = rho[a:a + chunk]
        cs, sn = np.cos(th1), np.sin(th1)
        m = rh1.size
        X, Y = np.empty(m), np.empty(m)
        g = np.empty((m, samples))
        st = np.empty((m, 9))
        o1 = out[a:a + chunk]
        h = X  # (no heights before the first stage)
        stage = 0
        while not _search(stage, h, rh1, cs, sn, offs, step, w, _GOLD, Rc, etab, iterations,
                          g, st, X, Y, o1):
            h = z0[a:a + chunk] if stage in at_zero else surface.height(X, Y)
            stage += 1

    starts = list(range(0, rho.size, chunk))
    if len(starts) == 1:
        run(0)
    else:  # numpy and the loops above release the GIL: one thread per core
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as ex:
            list(ex.map(run, starts))
    return out


def normal_compensation(surface: Any, theta: np.ndarray, rho: np.ndarray,
                        nose_radius: float) -> tuple[np.ndarray, np.ndarray]:
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


def gouge_depth(surface: Any, theta: np.ndarray, rho_tip: np.ndarray, z_tip: np.ndarray,
                nose_radius: float, *, max_slope: float | None = None,
                half_width: float | None = None) -> np.ndarray:
    """How far (mm, >= 0) each programmed tool position cuts below the design section:
    the Z lift it would need to touch without gouging minus the lift it has."""
    need = z_compensation(surface, theta, rho_tip, nose_radius, max_slope=max_slope,
                          half_width=half_width)
    return np.maximum(need - np.asarray(z_tip), 0.0)
