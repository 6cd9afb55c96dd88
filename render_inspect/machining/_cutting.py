"""The machined surface with the cutting mechanics: each pass removes material only where
its uncut chip thickness reaches h_min; thinner material is ploughed, springs back by
kappa and the rest flows sideways onto the cusp it shares with the earlier cut.

Per pixel the passes are visited in cutting order (time).  With s the surface left so far
(+inf before the first cut) and z_j the nose arc of pass j at the pixel (h_min after Son et
al. 2005 [1]_, side flow after Liu & Melkote 2006 [2]_; :mod:`._material`):

* z_j < s, h = s - z_j >= h_min (or the first cut): a chip forms, s = z_j; pass j is
  the pixel's *cutting pass* and h its uncut chip thickness;
* z_j < s, h < h_min: ploughing, s = z_j + kappa h (elastic recovery);
* z_j >= s, g = z_j - s < h_min (the pixel lies just beyond the cusp of a later pass,
  on the side already machined): side flow, s += (1 - kappa)(h_min - g), once per cusp.

Near a cusp whose flanks meet at a slope difference ds, the ploughed band is h_min / ds
wide on the later pass's side and the side-flow pile as wide on the earlier side; both
are evaluated exactly at the pixel centres (point sampling, as for the feed scallops).
With kappa = 1 nothing is displaced and a flat face gets Brammertz's [3]_ peak-to-valley
f^2/(8R) + h_min/2 (1 + R h_min / f^2).  h_min = 0 gives the geometric envelope exactly.

Besides the surface, the kernel returns for each pixel its cutting pass (spindle angle
and tool radius), the position along the nose edge that cut it and the uncut chip
thickness, from which the machined edges (pass boundaries) and the groove texture
(:func:`groove_texture`) follow.

References
----------
.. [1] S. M. Son, H. S. Lim, J. H. Ahn, "Effects of the friction coefficient on the minimum
       cutting thickness in micro cutting," International Journal of Machine Tools and
       Manufacture 45(4-5), 529-535 (2005). :DOI:`10.1016/j.ijmachtools.2004.10.001`
.. [2] K. Liu, S. N. Melkote, "Effect of plastic side flow on surface roughness in
       micro-turning process," International Journal of Machine Tools and Manufacture 46,
       1778-1785 (2006). :DOI:`10.1016/j.ijmachtools.2005.11.014`
.. [3] W. Brammertz, Industrie-Anzeiger 83, 525 (1961).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from ..core.lazy import njit, prange  # numba, imported on first use

from ..core.errors import InputError, check_range
from ..core.toolpath import ToolPath
from ..core.units import MM_TO_NM
from ._burr_kernels import pass_jump_count, pass_jump_mask
from ._envelope import _pass_window
from ._envelope_path import _lookup_table, _nominal_spiral, _nose_arc, path_radial_slope
from ._envelope_step import _lookup

if TYPE_CHECKING:
    from ._material import MaterialResponse

__all__ = ["cut_turning_mechanics", "cut_lines_mechanics", "groove_texture", "machined_edges", "machined_edge_count",
           "finish_surface", "mechanics_facts", "CutResult"]

TWO_PI = 2 * math.pi


@njit(cache=True, inline="always")
def _gather(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, sgn, W, Rc, hw, bs, bz, br, bd):
    """Passes at angle phi within W of sgn * r, in time order, into the buffers
    (s, arc z, tool radius, signed edge position); returns the count."""
    j0, j1 = _pass_window(theta, a, cc, phi, r, sgn, W)
    n = 0
    Rc2 = Rc * Rc
    for j in range(j0, j1 + 1):
        if n >= bs.size:
            break
        s = phi + TWO_PI * j
        i = _lookup(theta, tab, tab_t0, tab_w, s)
        dt = theta[i + 1] - theta[i]
        fr = (s - theta[i]) / dt if dt > 0 else 0.0
        rj = rho[i] + fr * (rho[i + 1] - rho[i])
        d = sgn * r - rj
        if abs(d) <= hw:
            bs[n] = s
            bz[n] = z[i] + fr * (z[i + 1] - z[i]) + Rc - math.sqrt(Rc2 - d * d)
            br[n] = rj
            bd[n] = d * sgn
            n += 1
    return n


@njit(parallel=True, cache=True)
def _cut_kernel(theta, rho, z, tab, tab_t0, tab_w, a, cc, dev, f, x0, y0, pixel, nx, ny,
                Rc, hw, W, h_min, kappa, side_flow, nbuf, out, chip, s_win, r_win, d_win, added):
    for iy in prange(ny):
        b1s = np.empty(nbuf)
        b1z = np.empty(nbuf)
        b1r = np.empty(nbuf)
        b1d = np.empty(nbuf)
        b2s = np.empty(nbuf)
        b2z = np.empty(nbuf)
        b2r = np.empty(nbuf)
        b2d = np.empty(nbuf)
        y = y0 + iy * pixel
        for ix in range(nx):
            x = x0 + ix * pixel
            r = math.sqrt(x * x + y * y)
            phi = math.atan2(y, x)
            if phi < 0:
                phi += TWO_PI
            Wp = W + dev + (0.5 * f if r < 2.0 * f + dev else 0.0)
            n1 = _gather(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, Wp, Rc, hw,
                         b1s, b1z, b1r, b1d)
            n2 = 0
            if r < Wp + hw:
                phi2 = phi + math.pi
                if phi2 >= TWO_PI:
                    phi2 -= TWO_PI
                n2 = _gather(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, Wp, Rc, hw,
                             b2s, b2z, b2r, b2d)
            if n1 + n2 == 0 and Wp < hw + dev:
                n1 = _gather(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, hw + dev, Rc,
                             hw, b1s, b1z, b1r, b1d)
                if r < hw + dev:
                    phi2 = phi + math.pi
                    if phi2 >= TWO_PI:
                        phi2 -= TWO_PI
                    n2 = _gather(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, hw + dev,
                                 Rc, hw, b2s, b2z, b2r, b2d)
            surf = np.inf
            h_cut = np.nan
            sw = np.nan
            rw = np.nan
            dw = np.nan
            add = 0.0
            piled = False
            k1 = 0
            k2 = 0
            while k1 < n1 or k2 < n2:
                if k2 >= n2 or (k1 < n1 and b1s[k1] <= b2s[k2]):
                    sj, zj, rj, dj = b1s[k1], b1z[k1], b1r[k1], b1d[k1]
                    k1 += 1
                else:
                    sj, zj, rj, dj = b2s[k2], b2z[k2], b2r[k2], b2d[k2]
                    k2 += 1
                if zj < surf:
                    h = surf - zj
                    if h >= h_min or surf == np.inf:
                        surf = zj
                        h_cut = h
                        sw = sj
                        rw = rj
                        dw = dj
                        add = 0.0
                        piled = False
                    else:
                        surf = zj + kappa * h
                        add = kappa * h
                elif side_flow and not piled:
                    g = zj - surf
                    if g < h_min:
                        p = (1.0 - kappa) * (h_min - g)
                        surf += p
                        add += p
                        piled = True
            out[iy, ix] = surf if surf < np.inf else np.nan
            chip[iy, ix] = h_cut if h_cut < np.inf else np.nan
            s_win[iy, ix] = sw
            r_win[iy, ix] = rw
            d_win[iy, ix] = dw
            added[iy, ix] = add


class CutResult(dict):
    """Dict of (ny, nx) float64 maps: ``machined`` (mm), ``chip`` (uncut chip thickness
    of the cutting pass, mm; NaN where the pass was the first cut), ``pass_theta``
    (spindle angle of the cutting pass, rad cumulative), ``pass_rho`` (its tool radius,
    mm), ``edge_pos`` (signed position along the nose edge that cut the pixel, mm, >0
    towards larger radius), ``added`` (ploughed recovery + side flow, mm)."""


def mechanics_path(path: ToolPath, *, h_min: float,
                   kappa: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(theta, rho, z) of a turning path as contiguous float64 arrays, after checking the
    cutting mechanics' ``h_min`` and ``kappa`` and that the path has at least 2 points."""
    check_range("h_min", h_min, 0.0, 1e-2)
    check_range("kappa", kappa, 0.0, 1.0)
    theta = np.ascontiguousarray(path.theta, dtype=np.float64)
    rho = np.ascontiguousarray(path.rho, dtype=np.float64)
    z = np.ascontiguousarray(path.z, dtype=np.float64)
    if theta.size < 2:
        raise InputError("the cutting mechanics need a path of at least 2 points")
    return theta, rho, z


def cut_turning_mechanics(path: ToolPath, *, nose_radius: float, region: Sequence[float],
                          pixel: float, half_width: float | None = None,
                h_min: float = 0.0, kappa: float = 0.0, side_flow: bool = True,
                slope_bound: float | None = None) -> CutResult:
    """Turning envelope with the minimum-chip-thickness mechanics (module docstring).

    Parameters
    ----------
    path : object with ``theta`` (rad, cumulative), ``rho``, ``z`` (mm, tool tip)
    nose_radius, half_width : float, mm
    region : (x0, y0, x1, y1), mm;  pixel : float, mm
    h_min : float, mm (>= 0)
    kappa : float in [0, 1]
    side_flow : bool
    slope_bound : float, optional
        Bound on the path's radial slope (measured if None).

    Returns
    -------
    CutResult
    """
    theta, rho, z = mechanics_path(path, h_min=h_min, kappa=kappa)
    Rc, hw = _nose_arc(nose_radius, half_width)
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    a, cc, dev, f = _nominal_spiral(theta, rho)
    m = path_radial_slope(theta, rho, z) if slope_bound is None else float(slope_bound)
    # the geometric window, widened by one feed: the adjacent (cusp) pass is always visited
    W = min(hw, 2.1 * Rc * m + 1.5 * f + h_min * 4 * Rc / max(f, 1e-12) + 1e-9)
    nbuf = int(2 * (W + dev + f) / max(f, 1e-12)) + 8 if f > 0 else 64
    nbuf = min(nbuf, 1_000_000)
    tab, t0, w = _lookup_table(theta)
    out = {k: np.empty((ny, nx), dtype=np.float64)
           for k in ("machined", "chip", "pass_theta", "pass_rho", "edge_pos", "added")}
    _cut_kernel(theta, rho, z, tab, t0, w, a, cc, dev, f, float(x0), float(y0), float(pixel),
                nx, ny, Rc, hw, W, float(h_min), float(kappa), bool(side_flow), nbuf,
                out["machined"], out["chip"], out["pass_theta"], out["pass_rho"], out["edge_pos"],
                out["added"])
    return CutResult(out)


def cut_lines_mechanics(profiles: Sequence[np.ndarray] | np.ndarray, x_lines: np.ndarray,
                        x_grid: np.ndarray, *, tool_radius: float, half_width: float | None = None,
              h_min: float = 0.0, kappa: float = 0.0, side_flow: bool = True) -> CutResult:
    """Sculpturing envelope over target lines in cutting order with the same mechanics.

    Parameters
    ----------
    profiles : (n_lines, ny) array, mm
        Lowest tool-tip height along each line (``sculpt_line_profile``), in cutting order.
    x_lines : (n_lines,) mm;  x_grid : (nx,) mm
    tool_radius, half_width : float, mm
    h_min, kappa, side_flow : as :func:`cut_turning_mechanics`

    Returns
    -------
    CutResult with ``pass_theta`` replaced by ``pass_line`` (line index) and ``pass_rho``
    by ``pass_x`` (the line's x); ``edge_pos`` = x - x_line.
    """
    R = float(check_range("tool_radius", tool_radius, 0.0, None, lo_open=True))
    hw = R if half_width is None else min(float(half_width), R)
    check_range("h_min", h_min, 0.0, 1e-2)
    check_range("kappa", kappa, 0.0, 1.0)
    x_grid = np.asarray(x_grid, dtype=np.float64)
    profiles = np.asarray(profiles, dtype=np.float64)
    shape = (profiles.shape[1], x_grid.size)
    surf = np.full(shape, np.inf)
    chip = np.full(shape, np.nan)
    line = np.full(shape, np.nan)
    px = np.full(shape, np.nan)
    added = np.zeros(shape)
    piled = np.zeros(shape, dtype=bool)
    with np.errstate(invalid="ignore"):  # inf - inf where neither a line nor a cut reaches
        for k, (prof, xk) in enumerate(zip(profiles, np.asarray(x_lines, dtype=np.float64))):
            dx = x_grid - xk
            arc = np.where(np.abs(dx) <= hw + 1e-12, R - np.sqrt(np.maximum(R * R - dx * dx, 0.0)), np.inf)
            zj = np.where(np.isnan(prof), np.inf, prof)[:, None] + arc[None, :]
            lower = zj < surf
            h = surf - zj
            cut = lower & ((h >= h_min) | ~np.isfinite(surf))
            plough = lower & ~cut
            chip = np.where(cut, h, chip)
            line = np.where(cut, k, line)
            px = np.where(cut, xk, px)
            added = np.where(cut, 0.0, added)
            piled &= ~cut
            surf = np.where(cut, zj, surf)
            surf = np.where(plough, zj + kappa * h, surf)
            added = np.where(plough, added + kappa * h, added)
            if side_flow:
                g = zj - surf
                pile = ~lower & np.isfinite(zj) & np.isfinite(surf) & (g < h_min) & ~piled
                p = np.where(pile, (1.0 - kappa) * (h_min - g), 0.0)
                surf = surf + p
                added = added + p
                piled |= pile
    chip[~np.isfinite(chip)] = np.nan
    surf[~np.isfinite(surf)] = np.nan
    return CutResult({"machined": surf, "chip": chip, "pass_line": line, "pass_x": px,
                      "edge_pos": x_grid[None, :] - px, "added": added})


def groove_texture(edge_pos: np.ndarray, along: np.ndarray, *, rms: float, seed: int,
                   across_length: float = 0.001,
                   along_length: float = 0.05, modes: int = 128) -> np.ndarray:
    """Grooves the edge ploughs along the cut: a Gaussian-covariance random field of the
    position on the edge (``edge_pos``, mm) and of the cutting distance (``along``, mm)
    with correlation lengths ``across_length`` and ``along_length``, scaled to ``rms``.

    The same edge point draws the same groove while the asperity on it lasts, so the
    pattern runs along the cut and changes over ``along_length`` of cutting.  Random
    Fourier modes from ``seed``: positional, the same seed gives the same grooves on any
    grid.  NaN inputs give 0.
    """
    check_range("rms", rms, 0.0, 1.0)
    check_range("across_length", across_length, 0.0, None, lo_open=True)
    check_range("along_length", along_length, 0.0, None, lo_open=True)
    u = np.nan_to_num(np.asarray(edge_pos, dtype=np.float64))
    v = np.nan_to_num(np.asarray(along, dtype=np.float64))
    out = np.zeros(np.broadcast(u, v).shape)
    if rms == 0:
        return out
    rng = np.random.default_rng(seed)
    ku = rng.normal(0.0, 1.0 / across_length, size=modes)
    kv = rng.normal(0.0, 1.0 / along_length, size=modes)
    ph = rng.uniform(0.0, TWO_PI, size=modes)
    for i in range(modes):
        out += np.cos(ku[i] * u + kv[i] * v + ph[i])
    return out * (rms * math.sqrt(2.0 / modes))


def machined_edges(pass_map: np.ndarray, *, jump: float) -> np.ndarray:
    """Pixels on a machined edge: where a neighbouring pixel was cut by another pass
    (``pass_map`` differs by more than ``jump``: pi for spindle angles, 0.5 for line
    indices).  Returns an (ny, nx) bool mask."""
    p = np.asarray(pass_map, dtype=np.float64)
    if p.ndim == 2 and p.size:
        return pass_jump_mask(p, jump)              # the same mask, compiled and threaded
    m = np.zeros(p.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        dy = np.abs(np.diff(p, axis=0)) > jump
        dx = np.abs(np.diff(p, axis=1)) > jump
    m[1:] |= dy
    m[:-1] |= dy
    m[:, 1:] |= dx
    m[:, :-1] |= dx
    return m


def machined_edge_count(pass_map: np.ndarray, *, jump: float) -> int:
    """The number of pixels on a machined edge of a 2-D map (:func:`machined_edges`' mask
    summed, without the mask)."""
    return pass_jump_count(np.asarray(pass_map, dtype=np.float64), jump)


def finish_surface(cut: CutResult, response: MaterialResponse, *, along: np.ndarray, seed: int,
                   across_length: float = 0.001,
                   along_length: float = 0.05) -> tuple[np.ndarray, dict]:
    """The machined surface with the material's grooves added where a pass cut.

    Parameters
    ----------
    cut : CutResult
        From :func:`cut_turning_mechanics` or :func:`cut_lines_mechanics` run with ``response.h_min`` and
        ``response.kappa``.
    response : MaterialResponse
    along : (ny, nx) array, mm
        Cutting distance at which the cutting pass crossed each pixel (sets how the
        grooves change along the cut).
    seed : int
    across_length, along_length : float, mm
        Correlation lengths of the grooves across and along the cut.

    Returns
    -------
    machined : (ny, nx) float64, mm
    info : dict
        ``groove_rms_nm`` (requested), ``grooves_rms_nm`` (added, measured),
        ``side_flow_max_nm`` (largest ploughed recovery + side-flow pile on the grid),
        ``edge_pixels`` (machined-edge pixels), ``burr_height_nm`` (the model's ridge
        height on a machined edge, (1 - kappa) h_min).
    """
    m = np.array(cut["machined"], dtype=np.float64, copy=True)
    ok = np.isfinite(m) & np.isfinite(cut["edge_pos"])
    g = groove_texture(np.where(ok, cut["edge_pos"], 0.0), np.where(ok, along, 0.0),
                       rms=response.groove_rms, seed=seed, across_length=across_length,
                       along_length=along_length)
    m[ok] += g[ok]
    key = "pass_theta" if "pass_theta" in cut else "pass_line"
    edges = machined_edges(cut[key], jump=math.pi if key == "pass_theta" else 0.5)
    added = cut["added"]
    gk = g[ok]
    info = mechanics_facts(response, grooves_sumsq=float(np.sum(gk * gk)), grooves_n=int(gk.size),
                           added_max=float(np.nanmax(added)) if np.isfinite(added).any() else 0.0,
                           edge_pixels=int(edges.sum()))
    return m, info


def mechanics_facts(response: MaterialResponse, *, grooves_sumsq: float, grooves_n: int,
                    added_max: float,
                    edge_pixels: int) -> dict:
    """The material facts of a cut (``metrics["material"]`` besides the response's own):
    ``groove_rms_nm`` (requested), ``grooves_rms_nm`` (added, measured: from the sum of
    their squares over the ``grooves_n`` pixels that got them), ``side_flow_max_nm``
    (largest ploughed recovery + side-flow pile, at least 0), ``edge_pixels`` (machined-edge
    pixels), ``burr_height_nm`` (the model's ridge height on a machined edge,
    (1 - kappa) h_min)."""
    return {"groove_rms_nm": response.groove_rms * MM_TO_NM,
            "grooves_rms_nm": (math.sqrt(grooves_sumsq / grooves_n) * MM_TO_NM if grooves_n else 0.0),
            "side_flow_max_nm": max(float(added_max), 0.0) * MM_TO_NM,
            "edge_pixels": int(edge_pixels), "burr_height_nm": response.burr_height * MM_TO_NM}
