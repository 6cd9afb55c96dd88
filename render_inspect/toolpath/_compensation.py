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
import queue
from concurrent.futures import ThreadPoolExecutor

import numpy as np
from ..core import trig
from ..core.cancel import check
from ..core.lazy import njit  # numba, imported on first use
from ..core.limits import usable_cpus
from ._edge import EdgeProfile

_GOLD = (math.sqrt(5) - 1) / 2


# The golden-section search of z_compensation, written as loops over the points: the same
# operations, in the same order, as the array form it replaced (a value of numpy.where
# here is the branch taken), so the tool path is the same to the last bit.  The surface
# itself is evaluated by its own (numpy) code between the stages of the search: one
# kernel (:func:`_search`) takes the heights of the points of one stage and gives the
# points of the next, so that one compiled kernel is loaded on the first plan and no
# temporary arrays are made between the stages (the loops it calls are put inside it
# when it is compiled: one function, not one for each loop, to load).

#: rows of the search's state (``_search``'s ``st``): the best coarse sample, the bracket
#: (lo, hi), its inner points (c, d), their values (gc, gd), the point evaluated next and
#: the value there
_BEST, _LO, _HI, _C, _D, _GC, _GD, _X, _V = range(9)


@njit(cache=True, nogil=True, inline="always")
def _bracket(g, offs, step, w, G, best, lo, hi, c, d):
    """From the coarse samples g (samples, n) at offsets ``offs``: the best value and the
    golden-section bracket (lo, hi) around it and its two inner points (c, d)."""
    for i in range(best.size):
        k = 0
        for j in range(1, g.shape[0]):
            if g[j, i] > g[k, i]:
                k = j
        best[i] = g[k, i]
        lo[i] = max(offs[k] - step, -w)
        hi[i] = min(offs[k] + step, w)
        c[i] = hi[i] - G * (hi[i] - lo[i])
        d[i] = lo[i] + G * (hi[i] - lo[i])


@njit(cache=True, nogil=True, inline="always")
def _golden_step(gc, gd, lo, hi, c, d, G, left, x):
    """One step of the search in place: keep the better half, and the point ``x`` to
    evaluate next (``left``: the maximum lies in [lo, d])."""
    for i in range(gc.size):
        lf = gc[i] > gd[i]
        left[i] = lf
        if lf:
            hi[i] = d[i]
            cn = hi[i] - G * (hi[i] - lo[i])
            dn = c[i]
            x[i] = cn
        else:
            lo[i] = c[i]
            cn = d[i]
            dn = lo[i] + G * (hi[i] - lo[i])
            x[i] = dn
        c[i] = cn
        d[i] = dn


@njit(cache=True, nogil=True, inline="always")
def _golden_take(left, g_eval, gc, gd):
    for i in range(gc.size):
        if left[i]:
            gd[i] = gc[i]
            gc[i] = g_eval[i]
        else:
            gc[i] = gd[i]
            gd[i] = g_eval[i]


@njit(cache=True, nogil=True, inline="always")
def _points(rho, cs, sn, d, X, Y):
    """The points u (cos, sin) at u = rho + d along each radial section."""
    for i in range(rho.size):
        u = rho[i] + d[i]
        X[i] = u * cs[i]
        Y[i] = u * sn[i]


@njit(cache=True, nogil=True, inline="always")
def _offset_points(rho, cs, sn, o, X, Y):
    """The points u (cos, sin) at u = rho + o along each radial section."""
    for i in range(rho.size):
        u = rho[i] + o
        X[i] = u * cs[i]
        Y[i] = u * sn[i]


@njit(cache=True, nogil=True, inline="always")
def _minus_arc(h, d, Rc, out):
    """h - (Rc - sqrt(Rc^2 - d^2)): the design less the nose arc at offset d."""
    for i in range(h.size):
        out[i] = h[i] - (Rc - np.sqrt(Rc * Rc - d[i] * d[i]))


@njit(cache=True, nogil=True, inline="always")
def _edge_height(d, Rc, edge):
    """Rc - sqrt(Rc^2 - d^2) + g(d): the measured edge's height at offset d (``edge``:
    the height table [d0, 1 / step, lowest, g_0 ..], linearly interpolated)."""
    n = edge.size - 3
    u = (d - edge[0]) * edge[1]
    if u <= 0.0:
        g = edge[3]
    elif u >= n - 1:
        g = edge[n + 2]
    else:
        k = int(u)
        g = edge[3 + k] + (u - k) * (edge[4 + k] - edge[3 + k])
    return Rc - np.sqrt(Rc * Rc - d * d) + g


@njit(cache=True, nogil=True, inline="always")
def _minus_edge(h, d, Rc, edge, out):
    """h - (Rc - sqrt(Rc^2 - d^2) + g(d)): the design less the measured edge at offset d."""
    for i in range(h.size):
        out[i] = h[i] - _edge_height(d[i], Rc, edge)


@njit(cache=True, nogil=True, inline="always")
def _minus_nose(h, d, Rc, edge, out):
    """The design less the nose (``edge`` None: the circular arc; else the measured
    edge) at the offsets d."""
    if edge is None:
        _minus_arc(h, d, Rc, out)
    else:
        _minus_edge(h, d, Rc, edge, out)


@njit(cache=True, nogil=True, inline="always")
def _minus_offset(h, o, Rc, edge, out):
    """The design less the nose at the one offset o: h - (Rc - sqrt(Rc^2 - o^2)) (or
    the measured edge's height there)."""
    if edge is None:
        q = Rc - np.sqrt(Rc * Rc - o * o)
    else:
        q = _edge_height(o, Rc, edge)
    for i in range(h.size):
        out[i] = h[i] - q


@njit(cache=True, nogil=True)
def _search(stage, h, rho, cs, sn, offs, step, w, G, Rc, edge, iterations, g, st, left,
            X, Y, out):
    """Stage ``stage`` of the search of one chunk of points: ``h`` holds the design's
    heights at the points (X, Y) the stage before gave (none at stage 0); the points of
    the next stage are written into X, Y.  Stages 0 .. S - 1 sample the window at the
    coarse offsets ``offs`` (S of them; rows of ``g``), stage S brackets the best sample
    and asks for its inner point c, S + 1 for d, and each stage after that takes the
    value of the point it asked for and moves the bracket (golden section), ``iterations``
    times; the last writes the result into ``out`` and returns True."""
    ns = offs.size
    m = rho.size
    best, lo, hi, c, d = st[_BEST, :m], st[_LO, :m], st[_HI, :m], st[_C, :m], st[_D, :m]
    gc, gd, x, v = st[_GC, :m], st[_GD, :m], st[_X, :m], st[_V, :m]
    if stage > 0 and stage <= ns:  # the coarse sample at offset offs[stage - 1]
        _minus_offset(h, offs[stage - 1], Rc, edge, g[stage - 1, :m])
    if stage < ns:
        _offset_points(rho, cs, sn, offs[stage], X, Y)
        return False
    if stage == ns:
        _bracket(g, offs, step, w, G, best, lo, hi, c, d)
        _points(rho, cs, sn, c, X, Y)
        return False
    if stage == ns + 1:
        _minus_nose(h, c, Rc, edge, gc)
        _points(rho, cs, sn, d, X, Y)
        return False
    k = stage - ns - 2  # the steps done
    if k == 0:
        _minus_nose(h, d, Rc, edge, gd)
    else:
        _minus_nose(h, x, Rc, edge, v)
        _golden_take(left, v, gc, gd)
    if k == iterations:
        for i in range(m):
            out[i] = max(best[i], max(gc[i], gd[i]))
        return True
    _golden_step(gc, gd, lo, hi, c, d, G, left, x)
    _points(rho, cs, sn, x, X, Y)
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
                   ccp_height: np.ndarray | None = None,
                   cos_sin: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
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
    cos_sin : ((n,) array, (n,) array), optional
        cos theta and sin theta, where the caller has them.

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

    # (None: the circular nose; the kernel compiled for it has no code of the edge's)
    etab = None if etab is None else np.ascontiguousarray(etab, dtype=np.float64)
    # the design's heights at the points themselves, where the caller has them: the
    # coarse sample at offset 0 is those points (u = rho + 0 = rho), bit for bit
    z0 = None
    if ccp_height is not None and not np.signbit(rho).any():
        z0 = np.ascontiguousarray(ccp_height, dtype=np.float64)
        if z0.shape != rho.shape:
            raise ValueError(f"ccp_height has {z0.shape} points, rho {rho.shape}")
    at_zero = [k for k in range(samples) if offs[k] == 0.0] if z0 is not None else []
    cs_sn = None
    if cos_sin is not None:
        cs_sn = tuple(np.ascontiguousarray(a, dtype=np.float64) for a in cos_sin)
        if any(a.shape != rho.shape for a in cs_sn):
            raise ValueError(f"cos_sin has {[a.shape for a in cs_sn]} points, rho {rho.shape}")

    starts = list(range(0, rho.size, chunk))
    workers = max(1, min(len(starts), usable_cpus()))
    todo: queue.SimpleQueue[int] = queue.SimpleQueue()
    for a in starts:
        todo.put(a)

    def chunks():  # the chunks not yet taken by a thread, in order
        while True:
            # (a stop asked for ends every thread here: the pool's end waits for them)
            check()
            try:
                yield todo.get_nowait()
            except queue.Empty:
                return

    def run(_):
        # the chunks this thread takes, one after the other, in arrays made once (what
        # the processor has just written stays in its caches, the memory is not mapped
        # anew); a thread that gets less of the processor takes fewer
        size = min(chunk, rho.size)
        X_, Y_ = np.empty(size), np.empty(size)
        cs_, sn_ = (np.empty(size if cs_sn is None else 0) for _ in range(2))
        # (rows a little longer than the chunk: rows whose starts lie a power of two
        # apart would share the processor's cache sets)
        g = np.empty((samples, size + 8))
        st = np.empty((9, size + 8))
        left_ = np.empty(size, dtype=np.bool_)
        for a in chunks():
            th1 = theta[a:a + chunk]
            rh1 = rho[a:a + chunk]
            m = rh1.size
            X, Y, left = X_[:m], Y_[:m], left_[:m]
            if cs_sn is None:
                cs, sn = cs_[:m], sn_[:m]
                trig.cos(th1, out=cs)
                trig.sin(th1, out=sn)
            else:
                cs, sn = cs_sn[0][a:a + chunk], cs_sn[1][a:a + chunk]
            o1 = out[a:a + chunk]
            h = X  # (no heights before the first stage)
            stage = 0
            while not _search(stage, h, rh1, cs, sn, offs, step, w, _GOLD, Rc, etab,
                              iterations, g, st, left, X, Y, o1):
                h = z0[a:a + chunk] if stage in at_zero else surface.height(X, Y)
                stage += 1

    if workers == 1:
        run(0)
    else:  # numpy and the loops above release the GIL: one thread per core
        with ThreadPoolExecutor(max_workers=workers) as ex:
            list(ex.map(run, range(workers)))
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
    c, s = trig.cos_sin(theta)
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
