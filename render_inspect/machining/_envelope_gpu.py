"""The envelope kernel on a CUDA GPU (numba.cuda), used when one is present; never required.

One GPU thread per pixel runs the fast kernel's per-pixel step (``_envelope.py``): the
same proven pass window, the same fixed pass count, constant-angle paths indexed by
arithmetic.  The polar angle is an exact atan2 per pixel (GPUs have no use for the CPU
kernel's series step), so results equal the CPU kernel's up to the rounding of the
angle (tested against it: |difference| < 1e-12 mm).  Paths that are not constant-angle
and paths that do not feed towards the axis stay on the CPU.

Without a GPU the kernel can be checked in numba's CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1``), which runs it thread by thread in Python.
"""

from __future__ import annotations

import math

import numpy as np

from ._envelope import INV_2PI, TWO_PI, EnvelopePath

_KERNEL = None
#: numba.cuda, imported on first use (a module global, so the CUDA simulator can swap it)
cuda = None


def cuda_available() -> bool:
    """True when numba sees a usable CUDA device (or its simulator is switched on)."""
    try:
        from numba import cuda

        return bool(cuda.is_available())
    except Exception:  # no driver, no toolkit: the CPU kernels run
        return False


def _build():
    global cuda
    from numba import cuda

    @cuda.jit(device=True, inline=True)
    def passes(seg, inv, nrev, offset, n_total, t0, a, icc, jw, K, phi, r, sgn, Rc, Rc2, hw, best, win):
        jc = (t0 + (a - r * sgn) * icc - phi) * INV_2PI
        j0 = math.ceil(jc - jw)
        kmax = math.floor(jc + jw) - j0
        sr = sgn * r
        nseg = seg.shape[0]
        u = (phi - t0) * inv
        fl = math.floor(u)
        g0 = int(fl) + j0 * nrev
        fr0 = u - fl
        for k in range(K):
            g = g0 + k * nrev
            fr = fr0
            if g == -1 and fr > 1.0 - 1e-9:
                g = 0
                fr = 0.0
            elif g == n_total - 1 and fr < 1e-9:
                g = n_total - 2
                fr = 1.0
            ii = g - offset
            if g >= 0 and g < n_total - 1 and ii >= 0 and ii < nseg:
                rj = seg[ii, 0] + fr * seg[ii, 1]
                d = abs(sr - rj)
                if d <= hw:
                    zj = seg[ii, 2] + fr * seg[ii, 3] + Rc - math.sqrt(Rc2 - d * d)
                    best = min(best, zj)
                    if k <= kmax:
                        win = min(win, zj)
        return best, win

    @cuda.jit
    def fill(seg, inv, nrev, offset, n_total, t0, a, cc, dev, f, Rc, hw, W, x0, y0, pixel, iy_off, ix_off, out):
        iy, ix = cuda.grid(2)
        ny, nx = out.shape
        if iy >= ny or ix >= nx:
            return
        Rc2 = Rc * Rc
        Wd = W + dev
        icc = 1.0 / cc
        jw_a = Wd * icc * INV_2PI
        jw_b = (Wd + 0.5 * f) * icc * INV_2PI
        jw_c = (hw + dev) * icc * INV_2PI
        K_a = int(math.floor(2.0 * jw_a)) + 1
        K_b = int(math.floor(2.0 * jw_b)) + 1
        K_c = int(math.floor(2.0 * jw_c)) + 1
        y = y0 + (iy_off + iy) * pixel
        x = x0 + (ix_off + ix) * pixel
        r = math.sqrt(x * x + y * y)
        phi = math.atan2(y, x)
        if phi < 0:
            phi += TWO_PI
        near = r < 2.0 * f + dev
        Wp = Wd + 0.5 * f if near else Wd
        jw = jw_b if near else jw_a
        K = K_b if near else K_a
        inf = math.inf
        best, win = passes(seg, inv, nrev, offset, n_total, t0, a, icc, jw, K, phi, r, 1.0, Rc, Rc2, hw, inf, inf)
        phi2 = phi + math.pi
        if phi2 >= TWO_PI:
            phi2 -= TWO_PI
        if r < Wp + hw:
            best, win = passes(seg, inv, nrev, offset, n_total, t0, a, icc, jw, K, phi2, r, -1.0, Rc, Rc2, hw,
                               best, win)
        if win == inf and Wp < hw + dev:
            best, win = passes(seg, inv, nrev, offset, n_total, t0, a, icc, jw_c, K_c, phi, r, 1.0, Rc, Rc2, hw,
                               best, win)
            if r < hw + dev:
                best, win = passes(seg, inv, nrev, offset, n_total, t0, a, icc, jw_c, K_c, phi2, r, -1.0, Rc,
                                   Rc2, hw, best, win)
        out[iy, ix] = best if best < inf else math.nan

    return fill


def gpu_supports(ep: EnvelopePath) -> bool:
    """The GPU kernel handles constant-angle paths that feed towards the axis."""
    return bool(ep.uniform and ep.cc > 0)


def envelope_fill_gpu(ep: EnvelopePath, origin, pixel: float, out: np.ndarray, *, start=(0, 0)) -> np.ndarray:
    """:func:`render_inspect.machining._envelope.envelope_fill` on the GPU (same arguments)."""
    global _KERNEL
    if not gpu_supports(ep):
        raise ValueError("envelope_fill_gpu: only constant-angle paths that feed towards the axis")
    if _KERNEL is None:
        _KERNEL = _build()
    ny, nx = out.shape
    threads = (8, 32)
    blocks = ((ny + threads[0] - 1) // threads[0], (nx + threads[1] - 1) // threads[1])
    d_seg = cuda.to_device(np.ascontiguousarray(ep.seg))
    d_out = cuda.device_array((ny, nx), dtype=np.float64)
    _KERNEL[blocks, threads](d_seg, ep.inv, ep.nrev, ep.offset, ep.n_total, ep.t0, ep.a, ep.cc, ep.dev, ep.f,
                             ep.nose_radius, ep.half_width, ep.window, float(origin[0]), float(origin[1]),
                             float(pixel), int(start[0]), int(start[1]), d_out)
    d_out.copy_to_host(out)
    return out
