"""The envelope kernel on a CUDA GPU (numba.cuda), used when one is present; never required.

One GPU thread per pixel runs the fast kernel's per-pixel step, the very functions the
CPU kernel runs (``_envelope_step.DEVICE_FUNCTIONS``: the same proven pass window, the same
fixed pass count, constant-angle paths indexed by arithmetic), compiled a second time for
the CUDA target by :func:`_build`.  Only the walk over the pixels is the GPU's own: the
polar angle is an exact atan2 per pixel (GPUs have no use for the CPU kernel's series
step along a block row).  The pixels' positions are computed on the host, as the CPU
kernel computes them: CUDA's compiler fuses a multiply and an add into one rounding, and
x0 + i * pixel fused put the pixel on the spindle axis 2e-17 mm off it, into another
radial section, where the model's height depends on the section (13.6 nm at the axis of
the shipped grid, measured on an H200).  The fused roundings left in the step and the
angle's rounding keep results within 1e-12 mm of the CPU kernel's (tested against it).
Paths that are not constant-angle
and paths that do not feed towards the axis stay on the CPU: their segment lookup's
data-dependent loop would diverge between the threads of a warp.

Without a GPU the kernel can be checked in numba's CUDA simulator
(``NUMBA_ENABLE_CUDASIM=1``), which runs it thread by thread in Python.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
import types
from typing import Any

import numpy as np

from . import _envelope_step
from ._envelope_path import EnvelopePath
# the CPU versions of the per-pixel step: :func:`_build` compiles _fill against their CUDA
# versions instead
from ._envelope_step import DEVICE_FUNCTIONS, TWO_PI, _pass_count, _pass_windows, _pixel_height

_KERNEL = None
#: numba.cuda, imported on first use (a module global, so the CUDA simulator can swap it)
cuda: Any = None


def cuda_available() -> bool:
    """True when numba sees a usable CUDA device (or its simulator is switched on)."""
    try:
        from numba import cuda

        return bool(cuda.is_available())
    except Exception:  # no driver, no toolkit: the CPU kernels run
        return False


def _fill(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total, t0, a, cc, dev, f,
          Rc, hw, W, xs, ys, out, edge):
    """The GPU kernel: one thread per pixel of ``out`` (compiled by :func:`_build` in the
    namespace of the CUDA versions of the per-pixel step)."""
    iy, ix = cuda.grid(2)
    ny, nx = out.shape
    if iy >= ny or ix >= nx:
        return
    Rc2 = Rc * Rc
    Wd = W + dev
    icc, jw_a, jw_b, jw_c = _pass_windows(cc, Wd, f, hw, dev)
    K_a = _pass_count(jw_a)
    K_b = _pass_count(jw_b)
    K_c = _pass_count(jw_c)
    y = ys[iy]
    x = xs[ix]
    r = math.sqrt(x * x + y * y)
    phi = math.atan2(y, x)
    if phi < 0:
        phi += TWO_PI
    out[iy, ix] = _pixel_height(seg, theta, tab, tab_t0, tab_w, uniform, inv, nrev, offset, n_total,
                                t0, a, icc, dev, f, Rc, Rc2, hw, Wd, jw_a, jw_b, jw_c, K_a, K_b, K_c,
                                phi, r, edge)


def _build():
    """Compile the per-pixel step and :func:`_fill` for CUDA.

    Each function of ``_envelope_step.DEVICE_FUNCTIONS`` is rebuilt from its Python source with
    its module's names, except that the names of the step's functions resolve to their
    CUDA versions (numba reads a function's globals when it compiles it), so one source
    serves both targets."""
    global cuda
    from numba import cuda

    ns = dict(vars(_envelope_step))
    ns["cuda"] = cuda
    for name in DEVICE_FUNCTIONS:
        py = getattr(_envelope_step, name).py_func
        ns[name] = cuda.jit(device=True, inline=True)(types.FunctionType(py.__code__, ns, name))
    # kept in numba's cache like the CPU kernels (compiling takes about 12 s)
    return cuda.jit(types.FunctionType(_fill.__code__, ns, "_fill"), cache=True)


def gpu_supports(ep: EnvelopePath) -> bool:
    """The GPU kernel handles constant-angle paths that feed towards the axis."""
    return bool(ep.uniform and ep.cc > 0)


def envelope_fill_gpu(ep: EnvelopePath, origin: Sequence[float], pixel: float, out: np.ndarray, *,
                      start: Sequence[int] = (0, 0)) -> np.ndarray:
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
    d_theta = cuda.to_device(np.ascontiguousarray(ep.theta))
    d_tab = cuda.to_device(np.ascontiguousarray(ep.tab))
    d_out = cuda.device_array((ny, nx), dtype=np.float64)
    # a circular nose: a one-entry table (the step adds exactly 0.0; no empty device array)
    d_edge = cuda.to_device(np.ascontiguousarray(ep.edge) if ep.edge.size else np.zeros(1))
    # the pixels' positions as the CPU kernel computes them (two roundings, not one fused)
    xs = float(origin[0]) + (int(start[1]) + np.arange(nx)) * float(pixel)
    ys = float(origin[1]) + (int(start[0]) + np.arange(ny)) * float(pixel)
    _KERNEL[blocks, threads](d_seg, d_theta, d_tab, ep.tab_t0, ep.tab_w, ep.uniform, ep.inv, ep.nrev,
                             ep.offset, ep.n_total, ep.t0, ep.a, ep.cc, ep.dev, ep.f, ep.nose_radius,
                             ep.half_width, ep.window, cuda.to_device(xs), cuda.to_device(ys), d_out, d_edge)
    d_out.copy_to_host(out)
    return out
