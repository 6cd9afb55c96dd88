"""Imaging model of the interference microscope: surface -> camera intensities.  The
instrument it images with (:class:`Microscope`, :class:`Disturbances`) is
:mod:`._microscope`'s; the PSI and CSI frames made from it are :mod:`._modes`'s.

Input: heights and normals of the surface at ``s x s`` sub-samples per camera pixel (what
the ray tracer returns; NaN heights = no surface reached).  Output: PSI or CSI frames
(:class:`Frames`) with the instrument's settings and no truth.

Per frame (scanner position ``z``: the focus and the zero path difference move together,
as in a Mirau or Linnik objective scanned along its axis) and per camera pixel::

    I(z) = rho_R + B + 2 sqrt(rho_R) Re X(z)

* ``X`` is the interference term, the 3-D linear filter of :mod:`._transfer` (Coupland et
  al. 2013 [1]_; the signal model of de Groot and Colonna de Lega [2]_) applied to
  the Kirchhoff field ``r exp(i K h)`` of the sub-samples, summed over the source's
  wavenumbers and the illumination directions, defocus included (the ``K``-dependence
  of the filter), integrated over the pixel's sensitive area (a box filter in the
  frequency domain) and sampled at the pixel centre;
* ``B`` is the light from the object alone, ``sum over k, q_i of |E|^2``: for each
  sub-sample, the geometric fraction of the illumination its facet (the normal) reflects
  into the pupil (:func:`acceptance_table`), averaged over the pixel's sensitive area.  It
  is raised to ``|X|^2`` where diffraction makes that larger (Cauchy-Schwarz), so
  ``I >= 0``;
* ``rho_R`` is the reference mirror's reflectance (unit illumination);
* sub-samples with no surface (NaN height), facing away from every illumination
  direction, or too steep for any reflected ray to enter the pupil, are dark (``r = 0``);
  facets beyond the slope limit whose phase the sub-sample grid begins to lose (from a
  quarter to half a fringe per sub-sample) fade to dark (a raised cosine in their tilt),
  so that no sharp edge diffracts false fringes into the pupil; a surface that reaches
  the limit gets sub-samples that carry its facets' phase with a quarter of a fringe at
  the limit (:func:`~._microscope.recommended_subsamples`), so the fade lies beyond it.

Frames are periodic over the array (FFT); ``crop`` drops a margin of pixels around the
field, where the wrap-around would otherwise show.

References
----------
.. [1] J. M. Coupland, R. Mandal, K. Palodhi, R. K. Leach, "Coherence scanning
       interferometry: linear theory of surface measurement," Applied Optics 52(16),
       3662-3670 (2013).
.. [2] P. de Groot, X. Colonna de Lega, "Signal modeling for low-coherence height-scanning
       interference microscopy," Applied Optics 43, 4821-4830 (2004).
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np
from ..core.lazy import lazy_attr, lazy_module

from ..core import cancel
from ..core.errors import InputError, MemoryBudgetError, check_range
from ..core.limits import usable_cpus
from ..core.units import GIB_TO_BYTES, NM_TO_MM
from ._kernels import (facets, filter_fold, frames_from_field, heights_about, radial_index,
                       smoothed_cosine, steps_over)
# the instrument's description (importable from here as before)
from ._microscope import Disturbances, Microscope, recommended_subsamples
from ._transfer import (
    acceptance_table,
    axial_step,
    flat_moments,
    transfer_function,
)

#: SciPy, imported on first use (render_inspect.core.lazy)
sfft = lazy_module("scipy.fft")
gaussian_filter = lazy_attr("scipy.ndimage", "gaussian_filter")

__all__ = [
    "MAX_STACK_BYTES",
    "Disturbances",
    "Microscope",
    "interference_intensity",
    "normals_from_heights",
    "recommended_subsamples",
]

#: A frame stack (float32) larger than this is refused.
MAX_STACK_BYTES = 3 * GIB_TO_BYTES


# ------------------------------------------------------------------------------ helpers
def normals_from_heights(heights: np.ndarray, spacing: float) -> np.ndarray:
    """Unit normals ``(-h_x, -h_y, 1) / norm`` from central differences (NaN-aware).

    Parameters
    ----------
    heights : (H, W) float, mm (NaN = no surface)
    spacing : float, mm

    Returns
    -------
    (H, W, 3) float32 (NaN where a neighbour is missing)
    """
    h = np.asarray(heights, dtype=np.float64)
    gy, gx = np.gradient(h, spacing)
    n = np.stack([-gx, -gy, np.ones_like(gx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return n.astype(np.float32)


def _exp_i(phase: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    if out is None:
        out = np.empty(phase.shape, dtype=np.complex64)
    out.real = np.cos(phase)
    out.imag = np.sin(phase)
    return out


def _threads_allowed() -> bool:
    """Whether the imaging model may start threads of its own: only in a process's main
    thread.  Called from another thread (a Dask worker runs its tasks in one), the steps
    run one after the other, with the same results: threads started there, beside the
    worker's own and the compiled kernels' thread pools, ended the worker processes of a
    LocalCluster in segmentation faults."""
    return threading.current_thread() is threading.main_thread()


class _Serial:
    """An executor that runs what it is given at once, in the calling thread (where the
    imaging model starts no threads of its own)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def submit(self, fn, *args, **kwargs) -> Future:
        fut: Future = Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except Exception as e:  # delivered by result(), as a thread's would be
            fut.set_exception(e)
        return fut


def _row_blocks(rows: int, workers: int) -> list[slice]:
    """``rows`` split into about ``2 workers`` blocks of whole rows."""
    n = max(1, min(rows, 2 * int(workers)))
    edges = [rows * i // n for i in range(n + 1)]
    return [slice(a, b) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def _by_rows(pool, blocks, fn) -> None:
    """``fn(rows)`` for every block of rows, in ``pool``'s threads (in turn without one)."""
    if pool is None:
        for r in blocks:
            fn(r)
    else:
        # (handed out before a stop is raised: see core.threads.over_rows)
        with cancel.deferred():
            futures = [pool.submit(fn, r) for r in blocks]
        for f in futures:
            f.result()


def _box_weights(s: int, fill_factor: float) -> np.ndarray:
    """Weight of each of the ``s`` sub-cells (per axis) in a pixel whose sensitive area is
    a centred square of side ``sqrt(fill_factor)`` pixels."""
    half = 0.5 * math.sqrt(fill_factor)
    edges = np.arange(s + 1) / s - 0.5
    w = np.clip(np.minimum(edges[1:], half) - np.maximum(edges[:-1], -half), 0.0, None)
    return w / w.sum()


#: Tilt (rad) by which every facet must stay below the fade's start for the fade to be
#: left out (far above the float32 arccosine's error of a few 1e-8 rad).
_FADE_MARGIN_RAD = 1e-3  # not a unit conversion: 1 mrad


def _below_tilt(cos_t: np.ndarray, alpha: float) -> bool:
    """Whether every facet with a cosine (NaN: no surface) tilts less than ``alpha`` by
    :data:`_FADE_MARGIN_RAD`: the fade is then 1 on every facet that returns light (its
    ``t`` is negative) and multiplying by it changes nothing, so it need not be made."""
    if alpha <= _FADE_MARGIN_RAD or cos_t.size == 0:
        return False
    lo = float(np.fmin.reduce(cos_t, axis=None))
    return math.isfinite(lo) and lo >= math.cos(alpha - _FADE_MARGIN_RAD)


# ------------------------------------------------------------------------- the model
def interference_intensity(heights: np.ndarray, normals: np.ndarray | None = None, *,
                           pixel: float, subsamples: int = 1,
                           microscope: Microscope | None = None, z_positions: np.ndarray,
                           crop: int = 0, reference_figure: np.ndarray | None = None,
                           kz_tolerance: float = 0.5, workers: int | None = None,
                           return_field: bool = False) -> tuple[np.ndarray, dict]:
    """Noise-free intensities of the interference microscope (the imaging model).

    Parameters
    ----------
    heights : (H*s, W*s) float array, mm
        Surface height at the sub-sample centres (NaN where no surface was reached).
        Sub-sample ``(i, j)`` of pixel ``(r, c)`` sits at ``(i - r s - (s - 1) / 2) pixel/s``
        from the pixel centre (row = y).
    normals : (H*s, W*s, 3) float array, optional
        Surface normals (any length, z > 0 facing the objective); default from the
        heights' central differences.
    pixel : float
        Camera pixel on the part, mm.
    subsamples : int
        ``s``, sub-samples per pixel side.
    microscope : Microscope, optional
    z_positions : (N,) or (N, T) float array, mm
        Scanner position (focus and zero path difference) of each frame; with T columns
        the intensity is averaged over the T positions (motion during the exposure).
    crop : int
        Pixels dropped on each side of the output (the FFT wraps around the array).
    reference_figure : (H - 2 crop, W - 2 crop) float array, optional
        Figure error of the reference mirror on the output grid, mm.
    kz_tolerance : float
        Accuracy of the axial binning (:func:`axial_step`), rad.
    workers : int, optional
        Threads of the FFTs and of the field's element-wise updates (default the usable
        CPUs, :func:`~render_inspect.core.limits.usable_cpus`); the result is the same
        for any number.
    return_field : bool
        Also return the complex interference term ``X`` (``info["field"]``, (N, H', W')
        complex64), e.g. to check the model against a direct summation.

    Returns
    -------
    intensity : (N, H - 2 crop, W - 2 crop) float32
        In units of the illumination (a perfect mirror's object beam alone gives 1).
    info : dict
        ``effective_wavelength_nm``, ``coherence_sigma_per_mm``, ``axial_bins``,
        ``axial_step_per_mm``, ``light`` ((H', W') float32: the object beam alone, B),
        ``undersampled_fraction`` (returning sub-samples whose phase changes by more than
        pi to the next sub-sample at the shortest wavelength).
    """
    mic = Microscope() if microscope is None else microscope
    s = int(subsamples)
    if s != subsamples or s < 1:
        raise InputError(f"subsamples must be an integer >= 1, got {subsamples!r}")
    check_range("pixel", pixel, 0, 1.0, lo_open=True)
    check_range("kz_tolerance", kz_tolerance, 0.05, 1.5)
    h = np.asarray(heights, dtype=np.float64)
    if h.ndim != 2 or h.shape[0] % s or h.shape[1] % s or h.shape[0] < s or h.shape[1] < s:
        raise InputError(f"heights must be an (H*s, W*s) array with s = subsamples = {s}, got "
                         f"shape {h.shape}")
    hc, wc = h.shape[0] // s, h.shape[1] // s
    crop = int(crop)
    if crop < 0 or 2 * crop >= min(hc, wc):
        raise InputError(f"crop must be in [0, {(min(hc, wc) - 1) // 2}] pixels for a "
                         f"{wc} x {hc} pixel field, got {crop}")
    ho, wo = hc - 2 * crop, wc - 2 * crop
    zpos = np.asarray(z_positions, dtype=np.float64)
    if zpos.ndim == 1:
        zpos = zpos[:, None]
    if zpos.ndim != 2 or zpos.shape[0] < 1 or not np.all(np.isfinite(zpos)):
        raise InputError(f"z_positions must be a finite (N,) or (N, T) array, got shape {zpos.shape}")
    nfr = zpos.shape[0]
    if nfr * ho * wo * 4 > MAX_STACK_BYTES:
        raise MemoryBudgetError(f"{nfr} frames of {wo} x {ho} pixels need "
                                f"{nfr * ho * wo * 4 / GIB_TO_BYTES:.1f} GiB "
                                f"(> {MAX_STACK_BYTES / GIB_TO_BYTES:.0f} "
                                f"GiB): use fewer frames or a smaller field")
    if normals is None:
        nrm = normals_from_heights(h, pixel / s)
    else:
        nrm = np.asarray(normals, dtype=np.float32)
        if nrm.shape != h.shape + (3,):
            raise InputError(f"normals must have shape {h.shape + (3,)} (heights' shape + 3), "
                             f"got {nrm.shape}")
    if reference_figure is not None:
        reference_figure = np.asarray(reference_figure, dtype=np.float64)
        if reference_figure.shape != (ho, wo):
            raise InputError(f"reference_figure must have the output shape {(ho, wo)}, got "
                             f"{reference_figure.shape}")
    threaded = _threads_allowed()
    workers = (workers or usable_cpus()) if threaded else 1
    na, na_ill, obs = mic.na, mic.na_ill, mic.obscuration

    # --- which sub-samples reflect: reached, facing the objective, and not a facet that
    # is both too steep to return any light (geometric optics) and too steep for the
    # sub-sample grid to carry its phase (it would alias into the pupil)
    # (the facets' cosine and unit normal, in one compiled pass: _kernels.facets)
    cos_t, fin, reached, unit = facets(nrm, h)  # reached: NaN compares False
    k_src, w_src = mic.source.sample(dk=mic._dk_fine())
    k99 = float(k_src[min(int(np.searchsorted(np.cumsum(w_src), 0.99)), k_src.size - 1)])
    alpha, frac = acceptance_table(na, na_ill, obs)
    a = pixel / s
    alpha_lim = float(alpha[np.nonzero(frac > 1e-9)[0].max()]) if (frac > 1e-9).any() else 0.0
    alpha_dark = max(alpha_lim, math.atan(math.pi / (2 * k99 * a)))
    returns = reached & (cos_t >= np.float32(math.cos(alpha_dark)))
    # facets beyond the slope limit return no light.  Those whose phase the sub-sample
    # grid carries (less than half a fringe of K h between sub-samples) take part as they
    # are: the transfer function rejects them (Kirchhoff).  Where the grid begins to fail
    # (from a quarter of a fringe per sub-sample, ``alpha_half``, to half a fringe,
    # ``alpha_dark``) they fade out smoothly (a raised cosine in the facet's tilt) instead
    # of ending at a sharp edge, whose diffraction would put a false ring of fringes
    # beyond the slope limit into the pupil.  (Where every facet tilts less than
    # ``alpha_half`` the fade is 1 wherever light returns, and is not made.)
    alpha_half = max(alpha_lim, math.atan(math.pi / (4 * k99 * a)))
    fade = None
    if alpha_dark > alpha_half and not _below_tilt(cos_t, alpha_half):
        with np.errstate(invalid="ignore"):
            t = (np.arccos(np.clip(cos_t, -1.0, 1.0)) - np.float32(alpha_half)) \
                / np.float32(alpha_dark - alpha_half)
        t = np.where(np.isfinite(t), t, np.float32(1.0))  # no surface: dark anyway
        fade = np.where(t <= 0, np.float32(1.0),
                        np.cos(np.float32(math.pi / 2) * np.clip(t, 0, 1)) ** 2).astype(np.float32)
        del t
    # the object beam's own intensity: geometric acceptance of the facets, with the normals
    # averaged over the point-spread function (sub-resolution texture scatters, it does not
    # make dark facets)
    lam_c = 2 * math.pi / float(np.sum(k_src * w_src))
    sig = lam_c / (4 * (na + na_ill)) / a
    del cos_t
    # the smoothing (SciPy's Gaussian filter, wrapped) and the cosine of the smoothed
    # facets in two compiled passes, the same numbers (_kernels.smoothed_cosine)
    # (the unit normal's arrays, not used after it, hold its passes: overwrite)
    cos_s = smoothed_cosine(unit[0], unit[1], unit[2], sig, overwrite=True) if sig > 0.3 else None
    if cos_s is None:
        if sig > 0.3 and threaded:
            # the three components at once (SciPy's filter lets go of the interpreter)
            with ThreadPoolExecutor(max_workers=min(3, usable_cpus())) as pool:
                unit = list(pool.map(lambda u: gaussian_filter(u, sig, mode="wrap"), unit))
        elif sig > 0.3:
            unit = [gaussian_filter(u, sig, mode="wrap") for u in unit]
        cos_s = unit[2] / np.maximum(np.sqrt(unit[0] ** 2 + unit[1] ** 2 + unit[2] ** 2), 1e-12)
    del unit
    # the tilt, its index into the table and the object beam over the sub-samples, each
    # step written over the last one's array (the same float32 operations; a fresh array
    # of the sub-sample grid for each costs the system its pages)
    tilt = np.arccos(np.clip(cos_s, -1.0, 1.0, out=cos_s), out=cos_s)
    del cos_s
    tilt = np.rint(np.multiply(tilt, np.float32((alpha.size - 1) / alpha[-1]), out=tilt), out=tilt)
    acc = np.take(frac.astype(np.float32), tilt.astype(np.int32))
    del tilt
    # (0 where no light returns: the table's fractions are finite and >= 0, so the product
    # with False is +0 as the assignment of 0 was)
    acc *= returns
    refl = float(mic.reflectance)
    wy = _box_weights(s, mic.camera.fill_factor)
    b_sub = np.multiply(acc, np.float32(refl), out=acc).reshape(hc, s, wc, s)
    light = np.einsum("asbt,s,t->ab", b_sub, wy, wy)[crop:hc - crop, crop:wc - crop]
    del b_sub, acc
    amp = np.where(returns, np.float32(math.sqrt(refl)), np.float32(0.0))
    if fade is not None:
        amp *= fade
        del fade

    # --- heights relative to a reference plane, the range of z - h the frames need
    any_ret = bool(returns.any())
    zbar = float(np.mean(h[returns])) if any_ret else (float(np.mean(h[fin])) if fin.any() else 0.0)
    # (the heights about it, 0 where no light returns, and their range where it returns,
    # in one compiled pass: _kernels.heights_about)
    dh32, hmin, hmax = heights_about(h, returns, zbar)
    zrel = zpos - zbar
    zeta = max(abs(float(zrel.max()) - hmin), abs(float(zrel.min()) - hmax))
    if reference_figure is not None:
        zeta += float(np.max(np.abs(reference_figure)))
    k_fine, w_fine = mic.source.sample(dk=mic._dk_fine())
    k_eff, sigma_k = flat_moments(na, na_ill, obs, k_fine, w_fine)
    dK = axial_step(sigma_k, zeta, tolerance=kz_tolerance)
    dK = 1.25 ** math.floor(math.log(dK, 1.25))  # quantised: repeated renders share a table
    tf = _cached_tf(na, na_ill, obs, mic.source, dK)

    # undersampling diagnostic: phase step to the next sub-sample at the largest K
    k_top = float(tf.K[np.nonzero(tf.support >= 0)[0].max()]) if (tf.support >= 0).any() else 0.0
    lim = np.float32(math.pi / k_top) if k_top > 0 else np.float32(np.inf)
    # (pairs of returning neighbours along rows and columns, in one compiled pass)
    under = steps_over(dh32, returns, lim)
    under_frac = under / max(2 * int(returns.sum()), 1)

    # --- frequency grids (fine).  Only frequencies inside each axial bin's support (a
    # disc, at most k_max (NA + NA_ill)) are filtered and folded onto the camera grid.
    hs, ws = h.shape
    qy = 2 * math.pi * sfft.fftfreq(hs, d=a)
    qx = 2 * math.pi * sfft.fftfreq(ws, d=a)
    wbox = math.sqrt(mic.camera.fill_factor) * pixel
    shift = (s - 1) * a / 2
    sepy = (np.sinc(qy * wbox / (2 * math.pi)) * np.exp(1j * qy * shift)).astype(np.complex64)
    sepx = (np.sinc(qx * wbox / (2 * math.pi)) * np.exp(1j * qx * shift)).astype(np.complex64)
    qy2 = (qy ** 2).astype(np.float32)
    qx2 = (qx ** 2).astype(np.float32)
    inv_dq = np.float32(1.0 / tf.dq)
    active = np.nonzero(tf.support >= 0)[0] if returns.any() else np.zeros(0, dtype=np.int64)
    nb = active.size
    cstack = np.empty((nb, ho * wo), dtype=np.complex64)
    kb = tf.K[active]
    coarse = np.empty((hc, wc), dtype=np.complex64)
    # the field's element-wise updates run over blocks of rows in threads (NumPy lets go
    # of the interpreter; each element is computed as in one pass)
    rows_pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None
    blocks = _row_blocks(hs, workers)
    grid = (hs, ws) if nb else (0, 0)
    cur = np.empty(grid, dtype=np.complex64)
    specbuf = np.empty(grid, dtype=np.complex64)
    step = np.empty(grid if nb > 1 else (0, 0), dtype=np.complex64)
    if nb > 1:
        _by_rows(rows_pool, blocks, lambda r: _exp_i(np.float32(tf.dK) * dh32[r], out=step[r]))
    # each fine frequency's radial sample of the table, the same for every bin
    ridx = radial_index(qy2, qx2, inv_dq, tf.table.shape[1]) if nb else None
    for j, b in enumerate(active):
        Kb = float(tf.K[b])
        if j % 16 == 0 or b != active[j - 1] + 1:

            def restart(r, kb32=np.float32(Kb)):
                _exp_i(kb32 * dh32[r], out=cur[r])
                cur[r] *= amp[r]  # amp is real: it survives the recursion below

            _by_rows(rows_pool, blocks, restart)
        else:
            _by_rows(rows_pool, blocks, lambda r: np.multiply(cur[r], step[r], out=cur[r]))
        qb = float(tf.support[b]) * (1 + 1e-6)
        cols = np.nonzero(np.abs(qx) <= qb)[0]
        # the FFT into a buffer kept for all bins (the same transform; a fresh 3072^2
        # array for each bin costs the system its pages again)
        row_ok = np.abs(qy) <= qb
        spec = _fft2_into(cur, specbuf, workers, rows_pool, blocks, rows=row_ok)
        filter_fold(spec, row_ok, qy2, sepy, cols, cols % wc, qx2, sepx, tf.table[b],
                    inv_dq, s, coarse, index=ridx)
        del spec
        img = sfft.ifft2(coarse, workers=workers, overwrite_x=True)
        img = img[crop:hc - crop, crop:wc - crop] * np.float32(1.0 / (s * s))
        if reference_figure is not None:
            img *= _exp_i((-Kb * reference_figure).astype(np.float32))
        cstack[j] = img.ravel()
    del cur, step, specbuf, ridx
    if rows_pool is not None:
        rows_pool.shutdown()

    # --- frames: X_f = sum_b coef[f, b] C_b, coef = <exp(-i K_b (z - zbar))> over the exposure
    coef = np.exp(-1j * kb[None, None, :] * zrel[:, :, None]).mean(axis=1).astype(np.complex64)
    rho_r = float(mic.reference_reflectance)
    two_sr = np.float32(2 * math.sqrt(rho_r))
    out = np.empty((nfr, ho * wo), dtype=np.float32)
    lightf = light.astype(np.float32).ravel()
    chunk = max(1, int(2 ** 24 // max(nfr, nb)))
    xfield = np.empty((nfr, ho * wo), dtype=np.complex64) if return_field else None
    for p0 in range(0, ho * wo, chunk):
        x = coef @ cstack[:, p0:p0 + chunk]
        if xfield is not None:
            xfield[:, p0:p0 + chunk] = x
        # max(B, max_f |X_f|^2) + rho_R + 2 sqrt(rho_R) Re X_f, floored at 0, in one pass
        frames_from_field(x, lightf[p0:p0 + chunk], np.float32(rho_r), two_sr,
                          out[:, p0:p0 + chunk])
    info = {"effective_wavelength_nm": 4 * math.pi / k_eff / NM_TO_MM,
            "coherence_sigma_per_mm": sigma_k, "axial_bins": int(nb),
            "axial_step_per_mm": float(dK), "light": light.astype(np.float32),
            "undersampled_fraction": float(under_frac), "reference_plane_mm": zbar}
    if xfield is not None:
        info["field"] = xfield.reshape(nfr, ho, wo)
    return out.reshape(nfr, ho, wo), info


def _pocketfft():
    """SciPy's own FFT module (what ``scipy.fft.fft2`` calls: pocketfft in SciPy 1.15,
    ducc in 1.18, with the same ``c2c``), or None."""
    try:
        from scipy.fft._duccfft import pyduccfft as module
    except ImportError:
        try:
            from scipy.fft._pocketfft import pypocketfft as module
        except ImportError:  # (another SciPy's layout)
            return None
    return module if hasattr(module, "c2c") else None


def _runs(mask: np.ndarray) -> list[slice]:
    """The runs of True in a 1-D boolean array, as slices."""
    m = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.flatnonzero(m[1:] != m[:-1])
    return [slice(int(a), int(b)) for a, b in zip(edges[::2], edges[1::2])]


def _fft2_into(x, out, workers, pool=None, blocks=(), rows=None):
    """``scipy.fft.fft2(x)`` written into ``out`` (complex64, x's shape), ``x`` left as
    it is: SciPy's own transform (``fft2`` hands pocketfft's ``c2c`` the same axes, the
    same normalisation and an output array), read from ``x`` instead of from a copy of
    it (with SciPy's ducc module, which rounds otherwise out of place, from the copy in
    ``out``, in place); a copy and ``fft2`` in place where neither module is found.

    ``rows`` (boolean, one per row of the result), when given: only those rows of the
    result are wanted.  pocketfft transforms the axes in turn, the columns (axis 0) first
    and then each row of their result in place, each row on its own; the rows' pass is
    then made over the wanted rows alone (the wanted rows hold the same numbers; the
    others hold the columns' pass only)."""
    def copy_in():
        _by_rows(pool, blocks or [slice(0, x.shape[0])], lambda r: np.copyto(out[r], x[r]))
        return out

    pfft = _pocketfft()
    if (pfft is not None and x.dtype == np.complex64 and out.dtype == np.complex64
            and x.shape == out.shape and x.ndim == 2 and x.flags.c_contiguous
            and out.flags.c_contiguous):
        # ducc's transform from one array into another rounds otherwise than in place (as
        # ``fft2`` transforms its copy): the copy, then in place
        src = copy_in() if "ducc" in pfft.__name__ else x
        if rows is None or bool(np.all(rows)):
            return pfft.c2c(src, (0, 1), True, 0, out, int(workers))
        pfft.c2c(src, (0,), True, 0, out, int(workers))
        for r in _runs(rows):
            pfft.c2c(out[r], (1,), True, 0, out[r], int(workers))
        return out
    return sfft.fft2(copy_in(), workers=workers, overwrite_x=True)


_TF_CACHE: dict = {}


def _cached_tf(na, na_ill, obs, source, dK):
    key = (na, na_ill, obs, source, round(dK, 9))
    tf = _TF_CACHE.get(key)
    if tf is None:
        if len(_TF_CACHE) >= 8:
            _TF_CACHE.pop(next(iter(_TF_CACHE)))
        tf = _TF_CACHE[key] = transfer_function(na, na_ill, obs, source, dK=dK)
    return tf
