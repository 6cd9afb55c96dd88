"""The vectorised cosine and sine (render_inspect.core.trig) against numpy's (the C
library's), and the compiled kernel against the numpy form of the same steps."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from render_inspect.core import trig

RANGES = [(-1.0, 1.0), (-10.0, 10.0), (-1e3, 1e3), (-1e6, 1e6), (-1e-8, 1e-8), (-1e9, 1e9)]


def _ulps(got, want):
    return np.abs(got - want) / np.spacing(np.abs(want))


@pytest.mark.parametrize("lo, hi", RANGES)
def test_within_two_units_in_the_last_place_of_numpy(lo, hi):
    x = np.random.default_rng(7).uniform(lo, hi, 200_000)
    c, s = trig.cos_sin(x)
    assert _ulps(c, np.cos(x)).max() <= 2 and _ulps(s, np.sin(x)).max() <= 2
    # most values are numpy's to the last bit
    assert np.mean(c == np.cos(x)) > 0.75 and np.mean(s == np.sin(x)) > 0.75
    assert np.array_equal(trig.cos(x), c) and np.array_equal(trig.sin(x), s)


def test_special_values_and_far_arguments_are_numpys():
    x = np.array([0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324, -5e-324, 1e-300, trig.ARG_MAX,
                  -trig.ARG_MAX, 3e7, 1e300, np.pi / 2, -np.pi, 2.5 * np.pi])
    with np.errstate(invalid="ignore"):
        want_c, want_s = np.cos(x), np.sin(x)
    c, s = trig.cos_sin(x)
    far = ~(np.abs(x) < trig.ARG_MAX)
    assert np.array_equal(c[far], want_c[far], equal_nan=True)
    assert np.array_equal(s[far], want_s[far], equal_nan=True)
    near = ~far
    assert _ulps(c[near], want_c[near]).max() <= 2
    assert np.all(np.abs(s[near] - want_s[near]) <= 2 * np.spacing(np.abs(want_s[near])))
    # the signs of zeros and of the smallest values are kept
    assert np.array_equal(np.signbit(s[:8]), np.signbit(want_s[:8]))


def test_the_kernel_and_the_numpy_form_give_the_same_bits():
    x = np.random.default_rng(3).uniform(-2e6, 2e6, 50_000)
    x[::97] = -0.0
    x[::101] = np.nan
    x[::103] = np.inf
    c, s = trig.cos_sin(x)
    nc, ns = trig._numpy_form(x, 2)
    assert np.array_equal(c, nc, equal_nan=True) and np.array_equal(s, ns, equal_nan=True)


@pytest.mark.slow
def test_small_arrays_before_numba_loads_give_the_kernels_bits(tmp_path):
    # a fresh process that checks a scene has not loaded numba: small arrays take the numpy
    # form there, and must give the numbers the kernel gives in this process
    x = np.random.default_rng(5).uniform(-100.0, 100.0, 1000)
    code = ("import json, sys; import numpy as np; from render_inspect.core import trig; "
            f"x = np.array(json.loads({json.dumps(json.dumps(x.tolist()))})); "
            "c, s = trig.cos_sin(x); o = trig.cos(x[:7]); "
            "print(json.dumps(['numba' in sys.modules, c.tolist(), s.tolist(), o.tolist()]))")
    env = {**os.environ, "HOME": str(tmp_path), "XDG_CACHE_HOME": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    loaded, c, s, o = json.loads(out.stdout)
    assert not loaded
    kc, ks = trig.cos_sin(x)
    assert "numba" in sys.modules
    assert np.array_equal(np.array(c), kc) and np.array_equal(np.array(s), ks)
    assert np.array_equal(np.array(o), kc[:7])


def test_shapes_scalars_out_and_other_types():
    x = np.linspace(-4.0, 4.0, 24).reshape(2, 3, 4)
    c, s = trig.cos_sin(x)
    assert c.shape == s.shape == x.shape
    assert np.array_equal(c.ravel(), trig.cos(x.ravel()))
    assert isinstance(trig.cos(0.5), np.float64) and trig.cos(0.5) == trig.cos(np.array([0.5]))[0]
    assert np.array_equal(trig.sin([1, 2, 3]), trig.sin(np.array([1.0, 2.0, 3.0])))
    y = x.copy()
    assert trig.cos(y, out=y) is y and np.array_equal(y, c)       # in place
    # written over its argument a block at a time: the same bits over several blocks, a
    # part-block at the end, and values the C library takes (far, not finite)
    big = np.random.default_rng(3).uniform(-50.0, 50.0, 2 * trig._IN_PLACE_BLOCK + 77)
    big[::997] = 2e6
    big[[4, 5, 6]] = np.nan, np.inf, -np.inf
    for f in (trig.cos, trig.sin):
        w = big.copy()
        assert f(w, out=w) is w and w.tobytes() == f(big).tobytes()
    z = np.empty_like(x)
    trig.sin(x, out=z)
    assert np.array_equal(z, s)
    with pytest.raises(ValueError, match="out must be"):
        trig.cos(x, out=np.empty(3))
    small = np.linspace(-3.0, 3.0, 12)
    nc, _ = trig._numpy_form(small, 0)
    o = np.empty(12)
    assert trig.cos(small, out=o) is o and np.array_equal(o, nc)
    f32 = np.linspace(0, 1, 5, dtype=np.float32)
    assert trig.cos(f32).dtype == np.float32 and np.array_equal(trig.cos(f32), np.cos(f32))
