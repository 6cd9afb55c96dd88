"""A tile's float32 maps and pyramid levels, compiled, give the numbers of the numpy and
io operations they replace, to the last bit (the store is compared byte for byte across
changes)."""

import numpy as np
import pytest

from render_inspect.batch._tile_pyramid import block_means, coarsen2, tile_float32
from render_inspect.io import block_sums, coarsen, means


def _maps(shape, seed=0):
    rng = np.random.default_rng(seed)
    # heights of very different sizes (the sums' rounding depends on their order), NaN
    # where the path did not reach, a zero residual, a negative zero
    design = rng.normal(size=shape) * 10.0 ** rng.integers(-9, 1, size=shape)
    machined = design + rng.normal(size=shape) * 10.0 ** rng.integers(-12, -3, size=shape)
    machined[rng.uniform(size=shape) < 0.1] = np.nan
    design[rng.uniform(size=shape) < 0.02] = np.nan
    machined.flat[::97] = design.flat[::97]
    design.flat[min(5, design.size - 1)] = -0.0
    return design, machined


@pytest.mark.parametrize("shape", [(64, 64), (37, 53), (1, 1), (2, 7), (9, 1), (1024, 1024), (300, 20), (17, 260)])
def test_tile_float32_and_levels_equal_numpy(shape):
    design, machined = _maps(shape, seed=sum(shape))
    maps, level1 = tile_float32(design, machined)
    ref = {"design": design.astype(np.float32), "machined": machined.astype(np.float32),
           "residual": np.subtract(machined, design).astype(np.float32)}
    for name, a in ref.items():
        assert maps[name].dtype == np.float32
        assert maps[name].tobytes() == a.tobytes(), name
        s, c = block_sums(a, 2)
        gs, gc = level1[name]
        assert gs.tobytes() == s.tobytes() and np.array_equal(gc, c), name
        while s.shape != (1, 1):
            assert block_means(gs, gc).tobytes() == means(s, c).tobytes(), name
            s, c = coarsen(s, c, 2)
            gs, gc = coarsen2(gs, gc)
            assert gs.tobytes() == s.tobytes() and np.array_equal(gc, c) and gc.dtype == c.dtype, name
        assert block_means(gs, gc).tobytes() == means(s, c).tobytes(), name


def test_coarsen2_equals_numpy_on_many_shapes():
    rng = np.random.default_rng(5)
    for _ in range(40):
        shape = tuple(int(v) for v in rng.integers(1, 90, size=2))
        s = rng.normal(size=shape) * 10.0 ** rng.integers(-9, 3, size=shape)
        c = rng.integers(0, 5, size=shape)
        got, ref = coarsen2(s, c), coarsen(s, c, 2)
        assert got[0].tobytes() == ref[0].tobytes() and np.array_equal(got[1], ref[1]), shape


def test_the_path_lookup_table_equals_numpys_search():
    """The angle -> segment table of a path (each tile's slice makes one) by a merge: the
    same indices as numpy's sorted search, repeated angles and unsorted input included."""
    from render_inspect.machining._envelope_path import _lookup_table

    rng = np.random.default_rng(2)
    for theta in (np.cumsum(rng.uniform(0, 0.01, 5000)), np.repeat(np.linspace(0, 30, 700), 3),
                  np.linspace(-4.0, 90.0, 20001), np.array([1.0, 1.0]), np.array([0.0, 2.0, 1.0, 3.0]),
                  np.array([0.0, np.nan, 1.0])):
        n = theta.size
        span = theta[-1] - theta[0]
        nb = int(min(max(n, 16), 4_000_000))
        w = span / nb if span > 0 else 1.0
        edges = theta[0] + w * np.arange(nb)
        ref = np.clip(np.searchsorted(theta, edges, side="right") - 1, 0, max(n - 2, 0)).astype(np.int64)
        tab, t0, tw = _lookup_table(theta)
        assert tab.dtype == ref.dtype and np.array_equal(tab, ref) and t0 == theta[0] and tw == w
