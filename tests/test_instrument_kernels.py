"""The imaging model's compiled pass gives, bit for bit, what the array expressions it
replaces give (the frames from the interference term); the camera, its deviates drawn
into one buffer, gives the frames of its array expressions with the same random stream;
the model's field updated over blocks of rows in threads and transformed in place gives
the frames of one pass."""

from __future__ import annotations

import numpy as np
import pytest

from render_inspect.instruments import Camera
from render_inspect.instruments._camera import POISSON_EXACT_BELOW, _fixed_patterns, expose
from render_inspect.instruments._kernels import frames_from_field


def _frames_by_array_expressions(x, light, rho_r, two_sr):
    mag2 = np.max(x.real ** 2 + x.imag ** 2, axis=0)
    bg = np.maximum(light, mag2) + np.float32(rho_r)
    out = bg[None, :] + two_sr * x.real
    np.maximum(out, 0.0, out=out)
    return out


def _same(a, b):
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


@pytest.mark.parametrize("nfr, m", [(1, 7), (5, 1000), (95, 3001)])
def test_frames_from_the_field_equal_the_array_expressions(nfr, m):
    rng = np.random.default_rng(nfr)
    x = (rng.normal(0, 0.6, (nfr, m)) + 1j * rng.normal(0, 0.6, (nfr, m))).astype(np.complex64)
    light = rng.uniform(0, 1.2, m).astype(np.float32)
    light[::5] = 0.0
    rho_r = -0.6  # (not a reflectance: it takes some values below the floor at 0)
    two_sr = np.float32(1.8)
    expect = _frames_by_array_expressions(x, light, rho_r, two_sr)
    assert (expect == 0).any() or m < 10  # the floor is exercised
    full = np.full((nfr, m + 4), -1.0, dtype=np.float32)
    got = frames_from_field(x, light, np.float32(rho_r), two_sr, full[:, 2:m + 2])
    assert _same(np.ascontiguousarray(got), expect)
    assert (full[:, :2] == -1).all() and (full[:, m + 2:] == -1).all()  # only its block


def test_frames_from_the_field_keep_a_nan_where_the_arrays_do():
    x = np.ones((3, 4), dtype=np.complex64)
    x[1, 1] = np.nan
    light = np.array([0.5, 0.5, np.nan, 0.5], dtype=np.float32)
    expect = _frames_by_array_expressions(x, light, 1.0, np.float32(2.0))
    got = frames_from_field(x, light, np.float32(1.0), np.float32(2.0),
                            np.empty((3, 4), np.float32))
    np.testing.assert_array_equal(np.isnan(got), np.isnan(expect))
    np.testing.assert_array_equal(got[~np.isnan(got)], expect[~np.isnan(expect)])


def _expose_by_array_expressions(intensity, cam, seed):
    """The camera as array expressions (each frame: electrons, shot and read noise,
    Poisson below POISSON_EXACT_BELOW, offset, full well, quantisation)."""
    inten = np.asarray(intensity)
    shape = inten.shape[1:]
    gain_map, offset_map = _fixed_patterns(cam, shape)
    peak = float(np.max(np.max(inten, axis=0) * gain_map))
    g = cam.exposure * cam.full_well_e / peak
    out = np.empty(inten.shape, dtype=np.float32)
    sat = np.zeros(shape, dtype=bool)
    e_per_adu = cam.full_well_e / cam.levels
    rng = np.random.default_rng(int(seed))
    scale = np.float32(g) * gain_map
    for f in range(inten.shape[0]):
        e = inten[f].astype(np.float32) * scale
        np.maximum(e, 0.0, out=e)
        low = e < POISSON_EXACT_BELOW
        noisy = e + rng.standard_normal(size=shape, dtype=np.float32) * np.sqrt(
            e + np.float32(cam.read_noise_e) ** 2)
        if low.any():
            noisy[low] = (rng.poisson(e[low]).astype(np.float32)
                          + np.float32(cam.read_noise_e) * rng.standard_normal(
                              size=int(low.sum()), dtype=np.float32))
        noisy += offset_map
        sat |= noisy >= cam.full_well_e
        np.clip(noisy, 0.0, cam.full_well_e, out=noisy)
        out[f] = np.rint(noisy / np.float32(e_per_adu)) / np.float32(cam.levels)
    return out, float(sat.mean())


@pytest.mark.parametrize("exposure, dark", [(0.8, False), (1.3, False), (0.8, True)])
def test_the_camera_equals_the_array_expressions(exposure, dark):
    rng = np.random.default_rng(5)
    # (large enough that a last-bit difference before the quantisation shows in some pixels)
    inten = rng.uniform(0.2, 1.0, (6, 301, 283)).astype(np.float32)
    if dark:  # counts below the Poisson limit in some frames
        inten[2, :10] = 1e-4
        inten[4, 5, 7] = 0.0
    cam = Camera(exposure=exposure, full_well_e=20000.5, read_noise_e=4.7, bit_depth=12)
    expect, sat = _expose_by_array_expressions(inten, cam, seed=11)
    got, info = expose(inten.copy(), cam, seed=11)
    assert _same(got, expect)
    assert info["saturated_fraction"] == sat
    assert (sat > 0) == (exposure > 1)
    inplace = inten.copy()
    got2, _ = expose(inplace, cam, seed=11, inplace=True)
    assert got2 is inplace and _same(got2, expect)


def test_the_fixed_patterns_made_ahead_give_the_frames_made_without():
    """The interferometer makes the camera's fixed patterns while the ray tracer works
    (:func:`~render_inspect.instruments._camera.make_fixed_patterns`): the exposure that
    follows takes the kept set and gives the frames it gives when it makes them itself;
    patterns made for another shape or camera are not used, and the kept ones cannot be
    written to."""
    from render_inspect.instruments import _camera

    rng = np.random.default_rng(4)
    inten = (rng.random((3, 9, 11)) * 2).astype(np.float32)
    cam = Camera(prnu=0.01, dsnu_e=3.0)
    _camera._fixed_patterns.cache_clear()
    expect, _ = expose(inten, cam, seed=5)
    _camera._fixed_patterns.cache_clear()
    _camera.make_fixed_patterns(cam, (9, 11))
    hits = _camera._fixed_patterns.cache_info().hits
    got, _ = expose(inten, cam, seed=5)
    assert _same(got, expect) and _camera._fixed_patterns.cache_info().hits == hits + 1
    for other, shape in ((Camera(prnu=0.02), (9, 11)), (cam, (9, 12))):  # another camera's, shape's
        _camera.make_fixed_patterns(other, shape)
        got, _ = expose(inten, cam, seed=5)
        assert _same(got, expect)
    gain, offset = _camera._fixed_patterns(cam, (9, 11))
    assert not gain.flags.writeable and not offset.flags.writeable
    _camera._fixed_patterns.cache_clear()
    _camera.make_fixed_patterns(Camera(noise=False), (9, 11))  # no noise: nothing made
    assert _camera._fixed_patterns.cache_info().currsize == 0


def test_the_deviates_drawn_into_a_buffer_are_the_stream_drawn_fresh():
    a = np.random.default_rng(9)
    b = np.random.default_rng(9)
    buf = np.empty((13, 17), dtype=np.float32)
    for _ in range(3):
        fresh = a.standard_normal(size=buf.shape, dtype=np.float32)
        b.standard_normal(dtype=np.float32, out=buf)
        assert _same(buf, fresh)


@pytest.mark.slow
def test_the_field_updated_in_threads_gives_the_frames_of_one_thread():
    from render_inspect.instruments import Microscope, interference_intensity, led
    from render_inspect.instruments._imaging import _exp_i, _row_blocks

    n, s, pixel = 40, 3, 0.000879
    y, x = (np.mgrid[0:n * s, 0:n * s] + 0.5) * pixel / s
    h = 4e-4 * np.cos(2 * np.pi * x / 0.02) * np.cos(2 * np.pi * y / 0.015) + 2e-5 * x / pixel
    mic = Microscope(source=led(600.0, bandwidth_nm=120.0))
    z = np.linspace(-1.2e-3, 1.2e-3, 23)
    runs = [interference_intensity(h, pixel=pixel, subsamples=s, microscope=mic, z_positions=z,
                                   crop=2, workers=w) for w in (1, 3)]
    assert runs[0][1]["axial_bins"] > 16  # the field is computed afresh at least once
    assert _same(runs[0][0], runs[1][0])
    # the phase factor by blocks of rows is the phase factor of one pass
    phase = (np.float32(21000.0) * h.astype(np.float32))
    whole = _exp_i(phase)
    parts = np.empty_like(whole)
    for r in _row_blocks(phase.shape[0], 3):
        _exp_i(phase[r], out=parts[r])
    assert _same(parts, whole)


def test_the_truths_mean_is_nanmean_without_a_warning():
    import warnings

    from render_inspect.instruments._interferometer import _nanmean_quiet

    rng = np.random.default_rng(4)
    h = rng.normal(0, 1e-3, (120, 135))
    h[rng.uniform(size=h.shape) < 0.3] = np.nan
    h[:6, :6] = np.nan  # pixels with no sub-sample
    blk = h[3:3 + 38 * 3, 3:3 + 43 * 3].reshape(38, 3, 43, 3)
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        expect = np.nanmean(blk, axis=(1, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = _nanmean_quiet(blk, (1, 3))
    assert np.isnan(got).any()
    assert _same(got, expect)


def test_the_filter_with_the_radial_index_of_all_bins_is_the_filter_of_each_bin():
    import math

    from render_inspect.instruments._kernels import filter_fold, radial_index

    n, s = 96, 3
    a = 0.000879 / s
    rng = np.random.default_rng(8)
    spec = (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))).astype(np.complex64)
    q = 2 * math.pi * np.fft.fftfreq(n, d=a)
    q2 = (q ** 2).astype(np.float32)
    sep = (np.sinc(q * 1e-4) * np.exp(1j * q * 2e-4)).astype(np.complex64)
    qmax = np.abs(q).max()
    index = None
    for frac in (0.95, 0.5):  # two bins, one radial index
        qb = frac * qmax
        table = rng.uniform(0, 1, 257).astype(np.float32)
        table[::7] = 0.0
        inv_dq = np.float32(256 / (0.8 * qmax))  # frequencies beyond the table too
        if index is None:
            index = radial_index(q2, q2, inv_dq, table.size)
            assert (index == table.size).any()
        cols = np.nonzero(np.abs(q) <= qb)[0]
        args = (spec, np.abs(q) <= qb, q2, sep, cols, cols % (n // s), q2, sep, table, inv_dq, s)
        plain = filter_fold(*args, np.empty((n // s, n // s), np.complex64))
        indexed = filter_fold(*args, np.empty((n // s, n // s), np.complex64), index=index)
        assert _same(plain, indexed)


def test_the_imaging_model_called_from_another_thread_runs_serially_with_the_same_frames():
    """Called from a thread other than the process's main one (a Dask worker runs its tasks
    in one), the imaging model starts no threads of its own (threads started there ended a
    LocalCluster's workers in segmentation faults) and gives the same frames."""
    import threading

    from render_inspect.instruments import Microscope, interference_intensity, led
    from render_inspect.instruments import _imaging

    n, s, pixel = 30, 3, 0.000879
    y, x = (np.mgrid[0:n * s, 0:n * s] + 0.5) * pixel / s
    h = 4e-4 * np.cos(2 * np.pi * x / 0.02) * np.cos(2 * np.pi * y / 0.015)
    mic = Microscope(source=led(600.0, bandwidth_nm=120.0))
    z = np.linspace(-1.2e-3, 1.2e-3, 9)

    def run():
        return interference_intensity(h, pixel=pixel, subsamples=s, microscope=mic,
                                      z_positions=z, crop=2)[0]

    here = run()
    got: dict = {}

    def in_thread():
        got["allowed"] = _imaging._threads_allowed()
        got["frames"] = run()

    t = threading.Thread(target=in_thread)
    t.start()
    t.join()
    assert _imaging._threads_allowed() and got["allowed"] is False
    assert _same(here, got["frames"])


_PRELOAD_CHECK = r"""
import json
import numpy as np
from render_inspect.instruments import Microscope, monochromatic, psi_frames
from render_inspect.instruments import _kernels
from render_inspect.instruments._interferometer import pixel_truth

def signatures():
    out = {}
    for name, v in vars(_kernels).items():
        d = getattr(v, "_dispatcher", None) or (v if hasattr(v, "signatures") else None)
        if d is not None and getattr(d, "signatures", None):
            out[name] = sorted(str(s) for s in d.signatures)
    return out

_kernels.preload()
loaded = signatures()
n, s, pixel = 32, 3, 0.000879
y, x = (np.mgrid[0:n * s, 0:n * s] + 0.5) * pixel / s
h = 4e-4 * np.cos(2 * np.pi * x / 0.02) * np.cos(2 * np.pi * y / 0.015)
nrm = np.stack([np.zeros_like(h), np.zeros_like(h), np.ones_like(h)], -1).astype(np.float32)
psi_frames(h, nrm, pixel=pixel, subsamples=s, microscope=Microscope(source=monochromatic(550.0)),
           crop=2)
pixel_truth(h, h[::s, ::s][2:-2, 2:-2], s=s, margin=2)
print(json.dumps({"loaded": loaded, "after": signatures()}))
"""


@pytest.mark.slow
def test_the_preload_loads_the_kernels_the_frames_use_with_their_argument_types():
    """The interferometer loads its compiled passes in a thread while the ray tracer works
    (:func:`~render_inspect.instruments._kernels.preload`): in a fresh process, every
    pass the PSI frames and the truth then call was loaded by it for the same argument
    types (a type it missed would be loaded or compiled again at the frames' first call,
    and a type it added would be work for nothing)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(repo)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])}
    p = subprocess.run([sys.executable, "-c", _PRELOAD_CHECK], capture_output=True, text=True,
                       env=env, cwd=repo, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    got = json.loads(p.stdout.strip().splitlines()[-1])
    assert set(got["loaded"]) >= {"_facets_kernel", "_wrap_axis0", "_wrap_axis1_cosine",
                                  "_steps_over_kernel", "_pixel_means_kernel",
                                  "_heights_about_kernel",
                                  "_radial_index_kernel", "_filter_fold_indexed",
                                  "_frames_kernel"}
    assert got["after"] == got["loaded"]
    assert all(len(v) == 1 for v in got["loaded"].values())
