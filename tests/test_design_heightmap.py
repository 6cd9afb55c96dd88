"""Height-map designs: EXR (heightmap.exr contract) and .npy, linear and cubic."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import HeightMapSurface, Sphere, make_surface
from render_inspect.errors import InputError
from render_inspect.io import write_heightmap_exr
from render_inspect.machining import HeightMap
from render_inspect.scene import load_scene

R = 20.0
PIXEL = 0.02
ORIGIN = (-1.0, -0.8)
SHAPE = (81, 101)   # ny, nx: x in [-1, 1], y in [-0.8, 0.8]


def _sphere_grid():
    s = Sphere(R)
    x = ORIGIN[0] + PIXEL * np.arange(SHAPE[1])
    y = ORIGIN[1] + PIXEL * np.arange(SHAPE[0])
    return s, s.height(x[None, :], y[:, None])


@pytest.fixture
def sphere_exr(tmp_path):
    s, z = _sphere_grid()
    path = tmp_path / "heightmap.exr"
    write_heightmap_exr(path, HeightMap(z, z + 1e-6, PIXEL, ORIGIN, scene={"design": {"type": "sphere"}}))
    return s, path


def test_exr_round_trips_a_sphere(sphere_exr):
    s, path = sphere_exr
    rng = np.random.default_rng(3)
    x = rng.uniform(-0.99, 0.99, 500)
    y = rng.uniform(-0.79, 0.79, 500)
    cubic = HeightMapSurface(path)
    assert cubic.pixel == PIXEL and cubic.origin == ORIGIN and cubic.data.shape == SHAPE
    # float32 storage (~3e-9 mm at these heights) dominates the cubic interpolation error
    assert_allclose(cubic.height(x, y), s.height(x, y), atol=2e-8)
    for a, b in zip(cubic.gradient(x, y), s.gradient(x, y)):
        assert_allclose(a, b, atol=5e-6)
    for a, b in zip(cubic.hessian(x, y), s.hessian(x, y)):
        assert_allclose(a, b, atol=2e-3)
    # bilinear: error <= pixel^2 / 8 * (|Fxx| + |Fyy|) (+ float32)
    lin = HeightMapSurface(path, interpolation="linear")
    bound = PIXEL ** 2 / 8 * (2 / R) * 1.02 + 1e-8   # h^2/8 (|Fxx| + |Fyy|)
    err = np.abs(lin.height(x, y) - s.height(x, y))
    assert err.max() <= bound
    assert err.max() > bound / 20        # linear really is coarser than cubic
    assert_allclose(lin.gradient(x, y)[0], s.gradient(x, y)[0], atol=PIXEL / R)
    # another channel
    mach = HeightMapSurface(path, channel="machined")
    assert_allclose(mach.height(0.1, 0.2) - cubic.height(0.1, 0.2), 1e-6, rtol=1e-3)


def test_npy_needs_pixel_and_origin(tmp_path):
    s, z = _sphere_grid()
    path = tmp_path / "design.npy"
    np.save(path, z)
    with pytest.raises(InputError, match="design.pixel"):
        HeightMapSurface(path)
    hm = HeightMapSurface(path, pixel=PIXEL, origin=ORIGIN, interpolation="cubic")
    assert_allclose(hm.height(0.333, -0.271), s.height(0.333, -0.271), atol=1e-11)
    # through the scene: a relative path is relative to the scene file
    (tmp_path / "scene.toml").write_text(
        '[design]\ntype = "heightmap"\npath = "design.npy"\npixel = 0.02\norigin = [-1.0, -0.8]\n'
        '[simulation]\nregion = [-0.5, -0.5, 0.5, 0.5]\npixel = 0.01\n')
    scene = load_scene(tmp_path / "scene.toml")
    surf = make_surface(scene.design)
    assert isinstance(surf, HeightMapSurface)
    assert_allclose(surf.height(0.0, 0.0), 0.0, atol=1e-12)
    # the region is clipped to the map: the steepest point is its corner (1, 0.8)
    r2 = 1.0 + 0.8 ** 2
    assert_allclose(surf.max_slope((-5, -5, 5, 5)), np.sqrt(r2 / (R * R - r2)), rtol=1e-3)


def test_outside_points_and_bad_maps_are_errors(sphere_exr, tmp_path):
    _, path = sphere_exr
    hm = HeightMapSurface(path)
    with pytest.raises(InputError, match=r"covers x in \[-1, 1\].*1 point"):
        hm.height(np.array([0.0, 1.5]), np.array([0.0, 0.0]))
    with pytest.raises(InputError, match="design.channel 'nope'"):
        HeightMapSurface(path, channel="nope")
    with pytest.raises(InputError, match="disagrees with the EXR header"):
        HeightMapSurface(path, pixel=0.05)
    bad = np.ones((10, 10))
    bad[3, 4] = np.nan
    np.save(tmp_path / "nan.npy", bad)
    with pytest.raises(InputError, match="NaN"):
        HeightMapSurface(tmp_path / "nan.npy", pixel=0.1, origin=(0, 0))
    np.save(tmp_path / "tiny.npy", np.ones((3, 3)))
    with pytest.raises(InputError, match="at least 4 x 4"):
        HeightMapSurface(tmp_path / "tiny.npy", pixel=0.1, origin=(0, 0))
    with pytest.raises(InputError, match=".exr or .npy"):
        (tmp_path / "map.txt").write_text("1 2 3")
        HeightMapSurface(tmp_path / "map.txt", pixel=0.1, origin=(0, 0))
    with pytest.raises(InputError, match="not found"):
        HeightMapSurface(tmp_path / "missing.exr")


@pytest.mark.parametrize("interpolation", ["linear", "cubic"])
def test_interpolant_passes_through_samples_and_derivatives_are_consistent(interpolation):
    rng = np.random.default_rng(11)
    data = rng.normal(0.0, 1e-3, size=(12, 15))
    hm = HeightMapSurface(None, pixel=0.1, origin=(2.0, -1.0), interpolation=interpolation,
                          data=data)
    xs = 2.0 + 0.1 * np.arange(15)
    ys = -1.0 + 0.1 * np.arange(12)
    assert_allclose(hm.height(xs[None, :], ys[:, None]), data, atol=1e-15)
    # derivatives agree with finite differences of the interpolant (away from cell edges)
    x = 2.0 + 0.1 * (rng.integers(0, 13, 200) + rng.uniform(0.1, 0.9, 200))
    y = -1.0 + 0.1 * (rng.integers(0, 10, 200) + rng.uniform(0.1, 0.9, 200))
    h = 1e-6
    gx, gy = hm.gradient(x, y)
    assert_allclose(gx, (hm.height(x + h, y) - hm.height(x - h, y)) / (2 * h), atol=1e-7)
    assert_allclose(gy, (hm.height(x, y + h) - hm.height(x, y - h)) / (2 * h), atol=1e-7)
    hxx, hxy, hyy = hm.hessian(x, y)
    assert_allclose(hxy, (hm.gradient(x, y + h)[0] - hm.gradient(x, y - h)[0]) / (2 * h), atol=1e-5)
    assert_allclose(hxx, (hm.gradient(x + h, y)[0] - hm.gradient(x - h, y)[0]) / (2 * h), atol=1e-5)
