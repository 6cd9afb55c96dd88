"""The imaging model's compiled passes over the sub-sample grid give, bit for bit, what the
array expressions they replace give: the facets' cosine, reach and unit normal; the
Gaussian smoothing of the normals (SciPy's, wrapped) with the cosine of the smoothed
facets; the fade of steep facets, left out only where it is 1 wherever light returns;
the autofocus's height range.  Whole renders with the old steps forced give the same
frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.instruments import _imaging
from render_inspect.instruments._focus import _finite_range
from render_inspect.instruments._kernels import facets, smoothed_cosine


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _normals(rng, shape):
    n = rng.standard_normal(shape + (3,)).astype(np.float32)
    n[..., 2] = np.where(rng.random(shape) > 0.2, np.abs(n[..., 2]) + 0.01, n[..., 2])
    n[rng.random(shape) > 0.9] = 0.0  # a missed ray's normal
    n.flat[0] = np.nan
    return n


@pytest.mark.parametrize("shape", [(1, 1), (7, 5), (64, 131)])
def test_the_facets_pass_equals_the_array_expressions(shape):
    rng = np.random.default_rng(shape[1])
    n = _normals(rng, shape)
    h = rng.standard_normal(shape)
    h[rng.random(shape) > 0.85] = np.nan
    h.flat[-1] = np.inf
    with np.errstate(invalid="ignore", divide="ignore"):
        nn = np.sqrt(n[..., 0] ** 2 + n[..., 1] ** 2 + n[..., 2] ** 2)
        cos_t = n[..., 2] / nn
        fin = np.isfinite(h)
        reached = fin & (cos_t > 0)
        unit = [np.where(reached, n[..., i] / nn, 0.0).astype(np.float32) for i in range(3)]
    got_cos, got_fin, got_reached, got_unit = facets(n, h)
    assert _same(got_cos, cos_t) and _same(got_fin, fin) and _same(got_reached, reached)
    assert all(_same(a, b) for a, b in zip(got_unit, unit))
    # a strided view (the autofocus's every b-th sub-sample) gives the same numbers
    sub = facets(n[::2, 1::3], h[::2, 1::3])
    assert _same(sub[0], cos_t[::2, 1::3]) and _same(sub[3][2], unit[2][::2, 1::3])


@pytest.mark.parametrize("shape, sigma", [((40, 33), 0.587), ((25, 61), 0.8), ((9, 12), 1.1)])
def test_the_smoothed_cosine_equals_scipys_filter_and_the_array_expressions(shape, sigma):
    from scipy.ndimage import gaussian_filter

    rng = np.random.default_rng(int(sigma * 100))
    n = _normals(rng, shape)
    n[~np.isfinite(n)] = 0.0
    nn = np.sqrt(n[..., 0] ** 2 + n[..., 1] ** 2 + n[..., 2] ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        unit = [np.where(nn > 0, n[..., i] / nn, 0.0).astype(np.float32) for i in range(3)]
    sm = [gaussian_filter(u, sigma, mode="wrap") for u in unit]
    expect = sm[2] / np.maximum(np.sqrt(sm[0] ** 2 + sm[1] ** 2 + sm[2] ** 2), 1e-12)
    got = smoothed_cosine(*unit, sigma)
    assert _same(got, expect)
    # the components' own arrays holding the passes: the same cosine, written into them
    copies = [u.copy() for u in unit]
    got = smoothed_cosine(*copies, sigma, overwrite=True)
    assert _same(got, expect) and any(got is c for c in copies)
    # arrays that share memory are not written over
    u = unit[0].copy()
    got = smoothed_cosine(u, u, u, sigma, overwrite=True)
    assert _same(u, unit[0]) and not any(got is c for c in (u,))


def test_the_smoothed_cosine_leaves_a_filter_longer_than_the_field_to_scipy():
    u = np.ones((4, 30), dtype=np.float32)
    assert smoothed_cosine(u, u, u, 1.3) is None  # radius 5 >= 4 rows
    v = [np.ones((4, 30), dtype=np.float32) for _ in range(3)]
    assert smoothed_cosine(*v, 1.3, overwrite=True) is None
    assert all(np.all(a == 1) for a in v)  # (left as they were)


def _fade_by_array_expressions(cos_t, alpha_half, alpha_dark):
    with np.errstate(invalid="ignore"):
        t = (np.arccos(np.clip(cos_t, -1.0, 1.0)) - np.float32(alpha_half)) \
            / np.float32(alpha_dark - alpha_half)
    t = np.where(np.isfinite(t), t, np.float32(1.0))
    return np.where(t <= 0, np.float32(1.0),
                    np.cos(np.float32(math.pi / 2) * np.clip(t, 0, 1)) ** 2).astype(np.float32)


@pytest.mark.parametrize("largest_tilt", [0.05, 0.2, 0.298, 0.2995, 0.3005, 0.32, 0.4])
def test_the_fade_is_left_out_only_where_it_is_one(largest_tilt):
    alpha_half, alpha_dark = 0.3, 0.45
    rng = np.random.default_rng(3)
    tilt = rng.uniform(0, largest_tilt, 5000)
    tilt[0] = largest_tilt
    cos_t = np.cos(tilt).astype(np.float32)
    cos_t[1::50] = np.nan  # no surface
    fade = _fade_by_array_expressions(cos_t, alpha_half, alpha_dark)
    returns = np.isfinite(cos_t) & (cos_t >= np.float32(math.cos(alpha_dark)))
    left_out = _imaging._below_tilt(cos_t, alpha_half)
    assert left_out == (largest_tilt < alpha_half - _imaging._FADE_MARGIN_RAD)
    if left_out:
        assert (fade[returns] == 1.0).all()
    assert not _imaging._below_tilt(np.full(4, np.nan, np.float32), alpha_half)
    assert not _imaging._below_tilt(cos_t, 0.0005)


def _surface(n, s, pixel, amplitude):
    y, x = (np.mgrid[0:n * s, 0:n * s] + 0.5) * pixel / s
    h = amplitude * np.cos(2 * np.pi * x / 0.02) * np.cos(2 * np.pi * y / 0.015)
    h[5:9, 40:47] = np.nan  # a hole
    return h


@pytest.mark.parametrize("amplitude", [4e-4, 3e-3])  # gentle; with facets the fade takes
def test_the_model_gives_the_frames_of_its_array_expressions(monkeypatch, amplitude):
    from render_inspect.instruments import Microscope, interference_intensity, monochromatic
    from render_inspect.instruments._imaging import normals_from_heights

    n, s, pixel = 36, 3, 0.000879
    h = _surface(n, s, pixel, amplitude)
    nrm = normals_from_heights(h, pixel / s)
    nrm[~np.isfinite(nrm)] = 0.0
    # (the PSI source: at 3 sub-samples of the 20x pixel its fade begins inside the slopes
    # light returns from, so steep facets fade)
    mic = Microscope(source=monochromatic(550.0, bandwidth_nm=10.0))
    z = np.linspace(-1.2e-3, 1.2e-3, 7)

    def run():
        inten, info = interference_intensity(h, nrm, pixel=pixel, subsamples=s, microscope=mic,
                                             z_positions=z, crop=2)
        return inten, info["light"]

    left_out = []
    below = _imaging._below_tilt
    monkeypatch.setattr(_imaging, "_below_tilt", lambda *a: left_out.append(below(*a)) or left_out[-1])
    new = run()
    assert left_out == [amplitude < 1e-3]  # the gentle surface leaves the fade out

    def old_facets(nrm, h):
        with np.errstate(invalid="ignore", divide="ignore"):
            nn = np.sqrt(nrm[..., 0] ** 2 + nrm[..., 1] ** 2 + nrm[..., 2] ** 2)
            cos_t = nrm[..., 2] / nn
            fin = np.isfinite(h)
            reached = fin & (cos_t > 0)
            unit = [np.where(reached, nrm[..., i] / nn, 0.0).astype(np.float32)
                    for i in range(3)]
        return cos_t, fin, reached, unit

    monkeypatch.setattr(_imaging, "facets", old_facets)
    monkeypatch.setattr(_imaging, "smoothed_cosine", lambda *a, **k: None)  # SciPy's filter
    monkeypatch.setattr(_imaging, "_below_tilt", lambda *a: False)  # the fade always made
    old = run()
    assert _same(new[0], old[0]) and _same(new[1], old[1])


def test_the_autofocus_height_range_is_the_finite_heights_range():
    rng = np.random.default_rng(1)
    h = rng.standard_normal((30, 40))
    h[rng.random(h.shape) > 0.7] = np.nan
    fin = h[np.isfinite(h)]
    assert _finite_range(h) == (float(fin.min()), float(fin.max()))
    h[3, 4] = np.inf
    h[5, 6] = -np.inf
    fin = h[np.isfinite(h)]
    assert _finite_range(h) == (float(fin.min()), float(fin.max()))
    with pytest.raises(InputError, match="all NaN"):
        _finite_range(np.full((3, 3), np.nan))


@pytest.mark.parametrize("s", [1, 2, 3, 4, 7])
def test_the_pixel_means_are_the_truths_nanmean(s):
    from render_inspect.instruments._interferometer import _nanmean_quiet
    from render_inspect.instruments._kernels import pixel_means

    rng = np.random.default_rng(s)
    ny, nx, margin = 13, 21, 2
    shape = ((ny + 2 * margin) * s, (nx + 2 * margin) * s)
    h = rng.standard_normal(shape) * 10.0 ** rng.integers(-6, 3, shape)
    h[rng.random(shape) > 0.7] = np.nan
    m = margin * s
    h[m:m + s, m:m + s] = np.nan  # a pixel with no sub-sample
    h[m + s:m + 2 * s, m:m + s] = -0.0
    expect = _nanmean_quiet(h[m:m + ny * s, m:m + nx * s].reshape(ny, s, nx, s), (1, 3))
    got = pixel_means(h, s, m, (ny, nx))
    assert _same(got, expect) and np.isnan(got[0, 0])


def test_the_pixel_means_leave_longer_pixels_to_numpy():
    from render_inspect.instruments._kernels import pixel_means

    assert pixel_means(np.zeros((16, 16)), 8, 0, (2, 2)) is None


def test_the_fft_into_a_buffer_is_scipys_fft2():
    import scipy.fft as sfft

    rng = np.random.default_rng(5)
    x = (rng.standard_normal((48, 39)) + 1j * rng.standard_normal((48, 39))).astype(np.complex64)
    keep = x.copy()
    out = np.empty_like(x)
    got = _imaging._fft2_into(x, out, 2)
    assert got is out and _same(x, keep)  # written into the buffer, the input kept
    assert _same(got, sfft.fft2(keep.copy(), workers=2, overwrite_x=True))
    # without SciPy's module: a copy transformed in place, the same numbers
    out2 = np.empty_like(x)
    orig = _imaging._pocketfft
    try:
        _imaging._pocketfft = lambda: None
        assert _same(_imaging._fft2_into(x, out2, 1), got)
    finally:
        _imaging._pocketfft = orig


@pytest.mark.parametrize("shape, workers", [((48, 39), 2), ((3120 // 8, 3120 // 8), 2),
                                            ((61, 64), 1)])
def test_the_fft_of_the_wanted_rows_alone_is_scipys_fft2_there(shape, workers):
    import scipy.fft as sfft

    rng = np.random.default_rng(shape[0])
    x = (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)).astype(np.complex64)
    full = sfft.fft2(x.copy(), workers=workers, overwrite_x=True)
    qy = np.fft.fftfreq(shape[0])
    # a band about 0 (the two ends of the rows), a single row, all rows, and no row
    for rows in (np.abs(qy) <= 0.3, np.arange(shape[0]) == 3, np.ones(shape[0], bool),
                 np.zeros(shape[0], bool)):
        out = np.empty_like(x)
        got = _imaging._fft2_into(x, out, workers, rows=rows)
        assert got is out and _same(got[rows], full[rows])
    assert [(r.start, r.stop) for r in _imaging._runs(np.array([1, 1, 0, 0, 1, 0, 1], bool))] \
        == [(0, 2), (4, 5), (6, 7)]


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (7, 1), (40, 53)])
def test_the_under_sampling_count_is_the_array_expressions(shape):
    from render_inspect.instruments._kernels import steps_over

    rng = np.random.default_rng(shape[0])
    dh = (rng.standard_normal(shape) * rng.choice([1e-6, 1e-3], shape)).astype(np.float32)
    ret = rng.random(shape) > 0.2
    lim = np.float32(1e-4)
    expect = (np.count_nonzero((np.abs(np.diff(dh, axis=1)) > lim) & ret[:, 1:] & ret[:, :-1])
              + np.count_nonzero((np.abs(np.diff(dh, axis=0)) > lim) & ret[1:, :] & ret[:-1, :]))
    assert steps_over(dh, ret, lim) == expect
    assert steps_over(dh, ret, np.float32(np.inf)) == 0


@pytest.mark.parametrize("shape,none_return", [((1, 1), False), ((40, 53), False),
                                              ((40, 53), True), ((0, 5), False)])
def test_the_heights_about_the_plane_are_the_array_expressions(shape, none_return):
    from render_inspect.instruments._kernels import heights_about

    rng = np.random.default_rng(sum(shape))
    h = 0.3 + rng.standard_normal(shape) * 1e-4  # mm, about a plane 0.3 mm up
    ret = (rng.random(shape) > 0.3) & (not none_return)
    h[~ret & (rng.random(shape) > 0.5)] = np.nan  # a missed ray (the others: dark facets)
    if ret.size:
        ret.flat[0] = not none_return
        h.flat[0] = 0.3
    zbar = float(np.mean(h[ret])) if ret.any() else 0.25
    expect = (h - zbar).astype(np.float32)
    expect[~ret] = 0.0
    lo, hi = ((float(expect[ret].min()), float(expect[ret].max())) if ret.any()
              else (0.0, 0.0))
    got, a, b = heights_about(h, ret, zbar)
    assert _same(got, expect)
    assert (a, b) == (lo, hi)


@pytest.mark.mitsuba
@pytest.mark.parametrize("fov", [(0.009, 0.009, 0.089, 0.089), (0.03, 0.03, 0.07, 0.07)])
def test_the_traced_sub_samples_outside_the_map_are_nan(fov):
    """Near the map's edge the margin's sub-samples beyond its span are NaN, inside it they
    are heights; a field whose margin stays inside has none marked."""
    from render_inspect.instruments._interferometer import interferometer_geometry, trace_heights
    from render_inspect.machining import HeightMap
    from render_inspect.scene import InterferometerConfig

    n, q = 101, 0.001
    c = np.arange(n) * q
    xx, yy = np.meshgrid(c, c)
    design = 2e-4 * np.sin(2 * np.pi * xx / 0.07) * np.cos(2 * np.pi * yy / 0.05)
    hm = HeightMap(design, design.copy(), q, (0.0, 0.0))
    cfg = InterferometerConfig(pixel=2 * q, field_of_view=fov, subsamples=2, noise=False)
    geom = interferometer_geometry(hm, cfg)
    h_sub, _, _ = trace_heights(hm, geom, surface="design", subsamples=2)
    x0, y0, x1, _ = geom["trace_window"]
    m = h_sub.shape[1]
    xs = x0 + (np.arange(m) + 0.5) * (x1 - x0) / m
    ys = y0 + (np.arange(h_sub.shape[0]) + 0.5) * (x1 - x0) / m
    outside = (xs[None, :] < 0) | (xs[None, :] > c[-1]) | (ys[:, None] < 0) | (ys[:, None] > c[-1])
    assert outside.any() == (fov[0] < 0.02)
    assert np.isnan(h_sub[outside]).all() and np.isfinite(h_sub[~outside]).all()


@pytest.mark.mitsuba
def test_the_traced_arrays_copied_in_threads_are_those_of_one_thread():
    """In a process's main thread the traced normals and the heights' float64 pass are
    made over blocks of rows in two threads; called from another thread, in one: the
    same arrays bit for bit."""
    from concurrent.futures import ThreadPoolExecutor

    from render_inspect.instruments._interferometer import interferometer_geometry, trace_heights
    from render_inspect.machining import HeightMap
    from render_inspect.scene import InterferometerConfig

    n, q = 101, 0.001
    c = np.arange(n) * q
    xx, yy = np.meshgrid(c, c)
    design = 2e-4 * np.sin(2 * np.pi * xx / 0.07) * np.cos(2 * np.pi * yy / 0.05)
    hm = HeightMap(design, design.copy(), q, (0.0, 0.0))
    cfg = InterferometerConfig(pixel=2 * q, field_of_view=(0.02, 0.02, 0.08, 0.08),
                               subsamples=3, noise=False)
    geom = interferometer_geometry(hm, cfg)
    main = trace_heights(hm, geom, surface="design", subsamples=3)
    with ThreadPoolExecutor(max_workers=1) as pool:
        other = pool.submit(trace_heights, hm, geom, surface="design", subsamples=3).result()
    for a, b in zip(main, other):
        assert _same(a, b)
    assert np.isfinite(main[0]).all() and main[1].shape == main[0].shape + (3,)
    assert np.allclose(np.linalg.norm(main[1], axis=-1), 1, atol=1e-5)  # unit normals
