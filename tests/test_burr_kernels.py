"""The compiled passes of the burr model give the numbers of the array expressions they
replaced, to the last bit (edges are thresholded: a last-bit change could move one)."""

import math

import numpy as np
import pytest
from scipy import ndimage

from render_inspect.machining import _burr_kernels as K
from render_inspect.machining import edge_turns, material_burr_block


def _edge_turns_reference(z, *, pixel, edge_angle_deg, span):
    """The burr model's edge search as numpy array expressions (its definition)."""
    edges = np.zeros(z.shape, dtype=bool)
    turn = np.zeros(z.shape)
    for axis in (0, 1):
        zz = np.moveaxis(z, axis, 0)
        if zz.shape[0] < 3:
            continue
        s = np.diff(zz, axis=0) / pixel
        j = np.nan_to_num(np.abs(np.arctan(s[1:]) - np.arctan(s[:-1])), nan=0.0)
        jp = np.pad(j, ((1, 1),) + ((0, 0),) * (j.ndim - 1))
        cand = np.zeros(zz.shape, dtype=bool)
        cand[1:-1] = (j >= jp[:-2]) & (j >= jp[2:]) & (j > 0)
        m = np.moveaxis(cand, 0, axis)
        n = s.shape[0]
        i = np.arange(n + 1)
        a = np.arctan(s)
        c = (span - 0.5) / span

        def face(k1, k2):
            a1 = np.take(a, np.clip(k1, 0, n - 1), axis=0)
            a2 = np.take(a, np.clip(k2, 0, n - 1), axis=0)
            return a1 - c * (a2 - a1)

        t = np.abs(face(i + span - 1, i + 2 * span - 1) - face(i - span, i - 2 * span))
        t = np.moveaxis(np.nan_to_num(t, nan=0.0), 0, axis)
        jf = np.zeros(z.shape)
        np.moveaxis(jf, axis, 0)[1:-1] = np.nan_to_num(np.abs(np.diff(a, axis=0)), nan=0.0)
        peak = jf >= ndimage.maximum_filter1d(jf, 6 * span + 1, axis=axis, mode="nearest")
        m = m & peak & (t > math.radians(edge_angle_deg))
        turn = np.where(m, np.maximum(turn, t), turn)
        edges |= m
    return edges, turn


def _maps():
    rng = np.random.default_rng(1)
    y, x = np.mgrid[0:120, 0:150] * 0.001
    ridge = np.minimum(0.01 * np.abs(x - 0.07), 0.02 * np.abs(y - 0.05)) + 2e-6 * np.sin(x / 0.003)
    r = np.hypot(x - 0.07, y - 0.06)
    dimple = np.where(r < 0.04, 0.5 * r ** 2, 0.0008) + 1e-7 * rng.normal(size=x.shape)
    holes = dimple.copy()
    holes[:9] = np.nan
    holes[60:64, 30:37] = np.nan
    wavy = 0.002 * np.sin(2 * np.pi * x / 0.05) * np.cos(2 * np.pi * y / 0.07)
    return {"ridge": ridge, "dimple": dimple, "holes": holes, "wavy": wavy,
            "two_columns": ridge[:, :2], "two_rows": ridge[:2], "small": ridge[:5, :7]}


@pytest.mark.parametrize("name", list(_maps()))
def test_edge_turns_match_the_array_definition_bit_for_bit(name):
    z = _maps()[name]
    found = 0
    for span in (1, 2, 4):
        for angle in (0.05, 0.5, 2.0):
            ref = _edge_turns_reference(z, pixel=0.001, edge_angle_deg=angle, span=span)
            got = edge_turns(z, pixel=0.001, edge_angle_deg=angle, span=span)
            assert np.array_equal(got[0], ref[0])
            assert np.array_equal(got[1], ref[1])
            found += int(ref[0].sum())
    if name in ("ridge", "dimple", "holes"):
        assert found > 0                      # the maps do have edges to find


@pytest.mark.parametrize("sigma", [0.7, 2.0, 6.5])
def test_gaussian_matches_scipy_bit_for_bit(sigma):
    z = _maps()["dimple"]
    assert np.array_equal(K.gaussian_nearest(z, sigma), ndimage.gaussian_filter(z, sigma, mode="nearest"))
    thin = z[:3]
    assert np.array_equal(K.gaussian_nearest(thin, sigma), ndimage.gaussian_filter(thin, sigma, mode="nearest"))


@pytest.mark.parametrize("cw", [1, 5, 64, 512, 4096])
def test_gaussian_column_blocks_match_scipy_bit_for_bit(cw):
    """The smoothing along axis 0 in blocks of columns (a last partial block, a block
    wider than the map) gives scipy's numbers."""
    rng = np.random.default_rng(11)
    z = np.cumsum(rng.normal(size=(41, 1100)), axis=1) * 1e-4
    sigma = 3.2
    w = K.gaussian_weights(sigma)
    out = np.empty_like(z)
    whole = (0, z.shape[0], 0, z.shape[1])
    K.smooth_axis0(z, w, out, cw, *whole)
    assert np.array_equal(out, ndimage.gaussian_filter1d(z, sigma, axis=0, mode="nearest"))
    K.smooth_axis1(z, w, out, cw, *whole)
    assert np.array_equal(out, ndimage.gaussian_filter1d(z, sigma, axis=1, mode="nearest"))
    inplace = z.copy()
    K.smooth_axis1(inplace, w, inplace, cw, *whole)
    assert np.array_equal(inplace, out)
    assert np.array_equal(K.gaussian_nearest(z, sigma), ndimage.gaussian_filter(z, sigma, mode="nearest"))


def test_material_burrs_keep_their_numbers():
    z = _maps()["holes"]
    r = material_burr_block(z, pixel=0.001, chip_thickness=1e-4, coefficient=1.0, smoothing=0.002,
                            width=3e-4, edge_angle_deg=0.3, seed=3)
    assert r is not None
    b, edges, turn, heights = r
    zf = z[tuple(ndimage.distance_transform_edt(~np.isfinite(z), return_distances=False,
                                                return_indices=True))]
    ref_edges, ref_turn = _edge_turns_reference(ndimage.gaussian_filter(zf, 2.0, mode="nearest"),
                                                pixel=0.001, edge_angle_deg=0.3, span=7)
    bad = ~np.isfinite(z)
    bad[:6] = bad[-6:] = True
    bad[:, :6] = bad[:, -6:] = True
    assert np.array_equal(edges, ref_edges & ~bad)
    assert np.array_equal(turn[edges], ref_turn[edges])


@pytest.mark.parametrize("shape", [(1, 1), (1, 7), (7, 1), (40, 53)])
def test_machined_edges_match_the_array_definition(shape):
    from render_inspect.machining import machined_edge_count, machined_edges

    rng = np.random.default_rng(4)
    p = rng.uniform(0.0, 8.0, shape)
    p[rng.uniform(size=shape) < 0.1] = np.nan
    ref = np.zeros(shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        dy = np.abs(np.diff(p, axis=0)) > math.pi
        dx = np.abs(np.diff(p, axis=1)) > math.pi
    ref[1:] |= dy
    ref[:-1] |= dy
    ref[:, 1:] |= dx
    ref[:, :-1] |= dx
    assert np.array_equal(machined_edges(p, jump=math.pi), ref)
    assert machined_edge_count(p, jump=math.pi) == int(ref.sum())


def test_material_burrs_in_place_give_the_same_map():
    """``overwrite``: the burrs added into the caller's array, the same numbers as on a copy."""
    from render_inspect.machining import material_burrs

    z = _maps()["ridge"]
    kw = dict(pixel=0.001, chip_thickness=1e-4, coefficient=1.0, smoothing=0.002, width=3e-4,
              edge_angle_deg=0.3, seed=3)
    ref, info = material_burrs(z, z, **kw)
    assert info["edge_pixels"] > 0 and not np.array_equal(ref, z)
    mine = z.copy()
    got, info2 = material_burrs(mine, z, overwrite=True, **kw)
    assert got is mine and np.array_equal(got, ref) and info2 == info


def test_the_gaussian_weights_are_scipys_kernel_bit_for_bit():
    """The smoothing passes' weights, computed without importing SciPy's ndimage, are the
    kernel SciPy's own ``gaussian_filter1d`` uses (reversed as it reverses it) to the bit,
    for whole and fractional widths and other truncations."""
    from scipy.ndimage import _filters

    from render_inspect.core.smoothing import gaussian_weights

    for sigma in (0.3, 0.5, 1.0, 1.7, 2.0, 3.14159, 10.0, 20.0, 33.3, 80.5, 161.0):
        for truncate in (4.0, 3.0, 2.5):
            radius = int(truncate * sigma + 0.5)
            want = np.ascontiguousarray(_filters._gaussian_kernel1d(sigma, 0, radius)[::-1])
            got = gaussian_weights(sigma, truncate)
            assert got.dtype == np.float64 and got.flags.c_contiguous
            assert np.array_equal(got, want), (sigma, truncate)
