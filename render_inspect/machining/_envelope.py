"""The machined surface of a turning path: the envelope of the tool-nose arcs.

In each radial section (angle phi) the tool passes once per revolution.  Pass j is at
cumulative angle theta_j = phi + 2 pi j; between programmed points the C, X and Z axes
interpolate linearly, giving the tool tip (rho_j, z_j).  Its nose arc cuts
z_j + Rc - sqrt(Rc^2 - (r - rho_j)^2) for |r - rho_j| <= the arc's half-width, and the
machined height at (r, phi) is the minimum over all passes (Li et al. 2018 [1]_, section
3).  Turning marks (feed scallops) and, without compensation, overcut waviness come out of
this.

Only passes that can win are visited: an arc at distance d from the pixel is at least
d^2 / (2 Rc) above its tip, and tips differ by at most m |d - d0| between passes (m the
path's radial slope bound), so passes with |d| > 2 Rc m + f / 2 (f the feed per rev) never
win.  Passes on the far side of the axis (angle phi + pi) are included near the centre.

Two kernels compute this envelope:

- the fast kernel (``simulate_turning``, ``envelope_fill``) works through the grid in
  square blocks of ``BLOCK`` pixels.  It advances the polar angle along a block row with
  the angle-difference series atan(t) = t - t^3/3 + t^5/5 - t^7/7 (|t| < 0.01: truncation
  below 1e-19 rad) and one exact atan2 per block row, visits a fixed number of passes
  per pixel (the passes in the proven window, counted in revolutions from the pixel's
  nominal pass, rounded up: no data-dependent loop lengths), and, on a constant-angle
  path, finds each pass's segment by index arithmetic (pass j + 1 is N points after
  pass j and shares its interpolation fraction).  It visits a superset of the reference
  kernel's passes, so its minimum is the same (the fall-back to every pass beyond the
  path's ends is decided, as there, by the passes inside the window alone); the heights differ from the reference
  only by the rounding of the interpolation fraction (tested: |difference| < 1e-12 mm);
- the reference kernel (``simulate_turning(..., reference=True)``) is the direct
  per-pixel form, kept to check the fast one.

A measured cutting edge (``toolpath.EdgeProfile``, nose radius Rc + delta(angle)) enters
as a table of its height above the circular arc over the signed radial offset from the tool
axis (``EnvelopePath.edge``, :func:`_edge_dz`), added to each arc's height; the pass window
grows by sqrt(2 Rc (max g - min g)) for it.  Without an edge the table is empty and the
arithmetic is the circle's, bit for bit.

A tile of the grid needs only the passes whose nose arcs reach it:
``EnvelopePath.slice_for(region)`` keeps those (a contiguous run of the spiral, plus the
innermost passes for tiles near the axis) and carries the whole path's constants, so a
tile computed from its slice equals the same pixels of the whole-grid run bit for bit.

This module holds the two CPU kernels and their drivers; the per-pixel step they share
with the GPU kernel is in :mod:`._envelope_step`, the path preparation
(:class:`EnvelopePath`, :func:`prepare_envelope`) in :mod:`._envelope_path`.

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566`
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from ..core.lazy import njit, prange  # numba, imported on first use
from ..core.threads import over_rows

from ..core.errors import InputError
from ..core.progress import report
from ..core.toolpath import ToolPath
# the path preparation (EnvelopePath, prepare_envelope and path_radial_slope are this
# module's names too) and the per-pixel step
from ._envelope_path import EnvelopePath, _lookup_table, path_radial_slope, prepare_envelope  # noqa: F401
from ._envelope_step import TWO_PI, _edge_dz, _lookup, _pass_count, _pass_windows, _pixel_height

log = logging.getLogger("render_inspect")

#: side (pixels) of the square blocks the fast kernel works through
BLOCK = 64
#: grids at least this large go to a CUDA GPU when one is present (simulate_turning): below
#: it, starting CUDA and loading the compiled kernel cost more than the GPU saves (about
#: 1 s a process, measured; docs/performance.md)
GPU_MIN_SAMPLES = 1 << 27
#: samples of one band of rows of the CPU kernel (a fraction of a second): the progress
#: is reported, and a stop asked by a signal honoured, between bands
BAND_SAMPLES = 1 << 20  # not a unit conversion
#: grids of at most this many samples (two blocks, milliseconds of work) run on the
#: calling thread: the thread pool and the parallel kernel's first compile would cost more
#: than they save (the same code: the same heights bit for bit)
SERIAL_MAX_SAMPLES = 2 * BLOCK * BLOCK


# ------------------------------------------------------------------ the reference kernel
@njit(cache=True, inline="always")
def _polar_step(phi, xp, x, y, exact):
    """The polar angle in [0, 2 pi) of (x, y), from ``phi``, that of the previous pixel
    (xp, y) of the row: atan's difference series while the step is small, the exact
    atan2 when ``exact`` or otherwise (the CPU kernels' walk along a row)."""
    dot = xp * x + y * y
    t = y * (xp - x) / dot if not exact and dot > 0 else 1.0
    if -0.01 < t < 0.01:
        t2 = t * t
        phi += t * (1.0 - t2 * (1.0 / 3.0 - t2 * (0.2 - t2 * (1.0 / 7.0))))
        if phi < 0:
            phi += TWO_PI
        elif phi >= TWO_PI:
            phi -= TWO_PI
    else:
        phi = math.atan2(y, x)
        if phi < 0:
            phi += TWO_PI
    return phi


@njit(cache=True, inline="always")
def _pass_window(theta, a, cc, phi, r, sgn, W):
    """First and last pass j (at cumulative angle phi + 2 pi j on the path) whose nominal
    radius is within W of sgn * r."""
    t_first = theta[0]
    t_last = theta[theta.size - 1]
    # nominal rho(s) = a - cc (s - t_first); want |sgn r - rho| <= W with rho >= 0
    if cc > 0:
        s_lo = t_first + (a - (r * sgn + W)) / cc
        s_hi = t_first + (a - (r * sgn - W)) / cc
    else:
        s_lo = t_first
        s_hi = t_last
    if s_lo < t_first:
        s_lo = t_first
    if s_hi > t_last:
        s_hi = t_last
    return math.ceil((s_lo - phi) / TWO_PI), math.floor((s_hi - phi) / TWO_PI)


@njit(cache=True, inline="always")
def _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, sgn, W, Rc, Rc2, hw, best, edge):
    """Visit the passes at angle phi whose nominal radius is within W of sgn * r."""
    j0, j1 = _pass_window(theta, a, cc, phi, r, sgn, W)
    for j in range(j0, j1 + 1):
        s = phi + TWO_PI * j
        i = _lookup(theta, tab, tab_t0, tab_w, s)
        dt = theta[i + 1] - theta[i]
        fr = (s - theta[i]) / dt if dt > 0 else 0.0
        rj = rho[i] + fr * (rho[i + 1] - rho[i])
        d = sgn * r - rj
        if d < 0:
            d = -d
        if d <= hw:
            zj = z[i] + fr * (z[i + 1] - z[i]) + Rc - math.sqrt(Rc2 - d * d)
            if edge.size > 0:
                zj += _edge_dz(edge, sgn * r - rj)
            if zj < best:
                best = zj
    return best


@njit(parallel=True, cache=True)
def _reference_kernel(theta, rho, z, tab, tab_t0, tab_w, a, cc, dev, f, x0, y0, pixel, nx, ny,
                     Rc, hw, W, out, edge):
    Rc2 = Rc * Rc
    Wd = W + dev
    for iy in prange(ny):
        y = y0 + iy * pixel
        for ix in range(nx):
            x = x0 + ix * pixel
            r = math.sqrt(x * x + y * y)
            phi = math.atan2(y, x)
            if phi < 0:
                phi += TWO_PI
            # near the axis the spiral ends: the nearest pass can be up to ~0.75 f away
            Wp = Wd + 0.5 * f if r < 2.0 * f + dev else Wd
            best = np.inf
            best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, Wp, Rc, Rc2, hw, best, edge)
            if r < Wp + hw:
                phi2 = phi + math.pi
                if phi2 >= TWO_PI:
                    phi2 -= TWO_PI
                best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, Wp, Rc, Rc2, hw, best, edge)
            if best == np.inf and Wp < hw + dev:
                # no pass within the window (beyond the path's ends): visit every pass that reaches
                best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi, r, 1.0, hw + dev, Rc, Rc2, hw, best, edge)
                if r < hw + dev:
                    phi2 = phi + math.pi
                    if phi2 >= TWO_PI:
                        phi2 -= TWO_PI
                    best = _arc_min(theta, rho, z, tab, tab_t0, tab_w, a, cc, phi2, r, -1.0, hw + dev, Rc, Rc2,
                                    hw, best, edge)
            out[iy, ix] = best if best < np.inf else np.nan


# ------------------------------------------------------------------ the fast kernel (CPU)
def _fill_impl(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a, cc,
               dev, f, Rc, hw, W, x0, y0, pixel, iy_off, ix_off, out, edge, b0, b1):
    """The BLOCK x BLOCK blocks b0 .. b1 - 1 of ``out`` (row by row of blocks)."""
    ny, nx = out.shape
    Rc2 = Rc * Rc
    Wd = W + dev
    icc, jw_a, jw_b, jw_c = _pass_windows(cc, Wd, f, hw, dev)
    K_a = _pass_count(jw_a)
    K_b = _pass_count(jw_b)
    K_c = _pass_count(jw_c)
    bx = (nx + BLOCK - 1) // BLOCK
    by = (ny + BLOCK - 1) // BLOCK
    for b in range(b0, b1):
        iy0 = (b // bx) * BLOCK
        ix0 = (b % bx) * BLOCK
        ix1 = min(ix0 + BLOCK, nx)
        for iy in range(iy0, min(iy0 + BLOCK, ny)):
            y = y0 + (iy_off + iy) * pixel
            phi = 0.0
            xp = 0.0
            for ix in range(ix0, ix1):
                x = x0 + (ix_off + ix) * pixel
                r = math.sqrt(x * x + y * y)
                # polar angle: series step from the previous pixel, exact atan2 otherwise
                phi = _polar_step(phi, xp, x, y, ix == ix0)
                xp = x
                out[iy, ix] = _pixel_height(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset,
                                            n_total, t0, a, icc, dev, f, Rc, Rc2, hw, Wd, jw_a, jw_b,
                                            jw_c, K_a, K_b, K_c, phi, r, edge)


#: the fast kernel, without the GIL: on one core (tiles run side by side by a scheduler;
#: grids of at most SERIAL_MAX_SAMPLES), or on runs of blocks on threads (whole grids:
#: :func:`~render_inspect.core.threads.over_rows`; numba's parallel loop of the same code
#: took 4-5 CPU-s more to compile, for the same heights)
_fill_serial = njit(nogil=True, cache=True)(_fill_impl)


def envelope_fill(ep: EnvelopePath, origin: Sequence[float], pixel: float, out: np.ndarray, *,
                  start: Sequence[int] = (0, 0),
                  parallel: bool = True) -> np.ndarray:
    """Machined heights (mm) written into ``out`` in place; NaN where no pass reaches.

    Parameters
    ----------
    ep : EnvelopePath
        The prepared path (or its slice for this tile).
    origin : (x, y)
        Centre of pixel [0, 0] of the whole grid, mm.
    pixel : float
        Grid spacing, mm.
    out : (ny, nx) float64 array
        Pixels [start[0]:start[0] + ny, start[1]:start[1] + nx] of the whole grid.
    start : (row, col)
        Index of ``out[0, 0]`` in the whole grid.  When both are multiples of ``BLOCK``
        the tile equals the same pixels of a whole-grid run bit for bit.
    parallel : bool
        Runs of blocks on threads, as many as numba's parallel kernels use; False runs on
        the calling thread without the GIL (for tiles that a scheduler runs side by side).
    """
    if ep.cc <= 0:
        raise ValueError("envelope_fill: the path must feed towards the axis (use simulate_turning)")
    args = (ep.seg, ep.theta, ep.tab, ep.tab_t0, ep.tab_w, ep.uniform, ep.inv, ep.nrev, ep.offset, ep.n_total,
            ep.t0, ep.a, ep.cc, ep.dev, ep.f, ep.nose_radius, ep.half_width, ep.window,
            float(origin[0]), float(origin[1]), float(pixel), int(start[0]), int(start[1]), out, ep.edge)
    ny, nx = out.shape
    blocks = -(-ny // BLOCK) * -(-nx // BLOCK)
    if parallel:
        over_rows(_fill_serial, blocks, *args)
    else:
        _fill_serial(*args, 0, blocks)
    return out


#: why the GPU kernel failed in this process ("auto" then stays on the CPU), or None
_GPU_FAILED: str | None = None


def _on_gpu(ep: EnvelopePath, origin: Sequence[float], pixel: float, out: np.ndarray, *,
            required: bool) -> bool:
    """``out`` filled by the GPU kernel and checked against the CPU kernel on the first
    block and on the block that holds the spindle axis; False (the caller fills it on the
    CPU) where the path is not one the GPU kernel handles, no CUDA device is present, the
    GPU's stack fails (said once, with why) or the check disagrees (said).  ``required``:
    a missing device or a failing stack raises."""
    global _GPU_FAILED
    # the GPU module builds on this one (a top-level import would be circular)
    from ._envelope_gpu import cuda_available, envelope_fill_gpu, gpu_supports

    # the cheap test first: asking for a device starts CUDA's driver
    if not (gpu_supports(ep) and cuda_available()):
        if required:
            raise ValueError("simulate_turning: device='gpu' needs a CUDA device and a constant-angle path")
        return False
    try:
        envelope_fill_gpu(ep, origin, pixel, out)
    except Exception as e:  # the optional GPU stack (driver, toolkit, numba.cuda) broken
        if required:
            raise
        _GPU_FAILED = f"{type(e).__name__}: {e}"
        log.warning("the GPU envelope kernel failed (%s); the CPU kernel runs instead", _GPU_FAILED)
        return False
    # checked on the CPU on the first block and on the block that holds the spindle axis
    # (where the height depends on the pixel's radial section, so a rounding of its
    # position shows)
    ny, nx = out.shape
    axis = (int(round(-origin[1] / pixel)), int(round(-origin[0] / pixel)))
    corners = {(0, 0)} | ({(axis[0] // BLOCK * BLOCK, axis[1] // BLOCK * BLOCK)}
                          if 0 <= axis[0] < ny and 0 <= axis[1] < nx else set())
    agree = True
    for i0, j0 in sorted(corners):
        got = out[i0:i0 + BLOCK, j0:j0 + BLOCK]
        probe = envelope_fill(ep, origin, pixel, np.empty(got.shape), start=(i0, j0), parallel=False)
        agree &= bool(np.array_equal(np.isnan(probe), np.isnan(got))
                      and np.nanmax(np.abs(probe - got), initial=0.0) < 1e-9)
    if agree:
        return True
    log.warning("the GPU envelope kernel disagrees with the CPU kernel; the CPU kernel runs instead")
    return False


def simulate_turning(path: ToolPath, *, nose_radius: float, region: Sequence[float], pixel: float,
                     half_width: float | None = None,
                     slope_bound: float | None = None, window: float | None = None,
                     out: np.ndarray | None = None, reference: bool = False, device: str = "auto",
                     edge: Any = None) -> np.ndarray:
    """Machined height (mm) on the grid of ``region`` / ``pixel`` from a turning path.

    Parameters
    ----------
    path : ToolPath
        theta cumulative (rad), rho, z of the tool tip (mm).
    nose_radius : float
        Rc, mm.
    region : (x0, y0, x1, y1)
        mm; pixel centres at x0 + i pixel, y0 + j pixel.
    pixel : float
        mm.
    half_width : float, optional
        Radial half-width of the nose arc (Rc sin(included / 2)); Rc if None.
    slope_bound : float, optional
        Bound on the path's radial slope dz/drho; measured from the path if None.
    window : float, optional
        Radial window (mm) of passes visited around each pixel; by default the proven
        bound 2 Rc m + f / 2 (pass ``half_width`` to visit every pass that reaches).
    out : (ny, nx) float64 array, optional
        Written in place (saves one allocation).
    reference : bool
        Use the direct per-pixel kernel (slower; the fast kernel is checked against it).
    device : "auto", "cpu" or "gpu"
        "auto" runs grids of at least ``GPU_MIN_SAMPLES`` samples on a CUDA GPU when one is
        present (``_envelope_gpu``), after checking it against the CPU kernel on the
        grid's first block and on the block that holds the spindle axis (the CPU's result
        where they disagree, with a warning); a GPU stack that
        fails (driver, toolkit, numba.cuda) is said once in a warning and the process stays
        on the CPU.  "gpu" requires a device and a working stack.
    edge : EdgeProfile, optional
        The measured cutting edge (``toolpath.EdgeProfile``): the nose's height at each
        radial offset is the edge's instead of the circle's; None: the circular nose.

    Returns
    -------
    (ny, nx) float64: NaN where no pass reaches.
    """
    n_points = int(np.size(path.theta))
    if n_points < 2:
        raise InputError(f"the tool path over simulation.region {list(region)} has "
                         f"{n_points} point(s), at least 2 are needed: the region lies off the "
                         f"turned part (process.workpiece_radius, process.inner_radius)")
    ep = prepare_envelope(path, nose_radius=nose_radius, half_width=half_width, slope_bound=slope_bound,
                          window=window, edge=edge)
    x0, y0, x1, y1 = region
    nx = int(round((x1 - x0) / pixel)) + 1
    ny = int(round((y1 - y0) / pixel)) + 1
    if out is None:
        out = np.empty((ny, nx), dtype=np.float64)
    if reference or ep.cc <= 0:
        theta = np.ascontiguousarray(path.theta, dtype=np.float64)
        rho = np.ascontiguousarray(path.rho, dtype=np.float64)
        z = np.ascontiguousarray(path.z, dtype=np.float64)
        tab, t0, w = _lookup_table(theta)
        _reference_kernel(theta, rho, z, tab, t0, w, ep.a, ep.cc, ep.dev, ep.f, float(x0), float(y0),
                          float(pixel), nx, ny, ep.nose_radius, ep.half_width, ep.window, out, ep.edge)
        return out
    if device not in ("auto", "cpu", "gpu"):
        raise ValueError(f"simulate_turning: device must be 'auto', 'cpu' or 'gpu', got {device!r}")
    if device == "gpu" or (device == "auto" and out.size >= GPU_MIN_SAMPLES and _GPU_FAILED is None):
        if _on_gpu(ep, (x0, y0), pixel, out, required=device == "gpu"):
            return out
    # in bands of rows (whole blocks: each band equals the same rows of one whole-grid
    # call bit for bit), reporting the progress and stopping when asked between bands
    rows = BLOCK * max(1, BAND_SAMPLES // max(BLOCK * nx, 1))
    for r0 in range(0, ny, rows):
        r1 = min(r0 + rows, ny)
        envelope_fill(ep, (x0, y0), pixel, out[r0:r1], start=(r0, 0),
                      parallel=out.size > SERIAL_MAX_SAMPLES)
        report(r1, ny)
    return out


def load_kernels() -> None:
    """Compile (or load from numba's cache) the fast kernel for tile workers: one call on a
    2 x 2 grid of a three-revolution spiral."""
    theta = np.linspace(0.0, 6 * math.pi, 97)
    rho = 0.05 - 0.01 * theta / TWO_PI
    seg = np.empty((theta.size - 1, 4))
    seg[:, 0], seg[:, 1] = rho[:-1], np.diff(rho)
    seg[:, 2], seg[:, 3] = 0.0, 0.0
    ep = EnvelopePath(seg, theta, np.zeros(1, dtype=np.int64), 0.0, 1.0, True, 96 / (6 * math.pi), 32, 0,
                      theta.size, 0.0, float(theta[-1]), 0.05, 0.01 / TWO_PI, 0.0, 0.01, 0.1, 0.05, 0.0101)
    envelope_fill(ep, (0.0, 0.0), 0.001, np.empty((2, 2)), parallel=False)