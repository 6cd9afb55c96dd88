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
