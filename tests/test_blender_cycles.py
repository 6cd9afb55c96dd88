"""Cycles adapter (render_inspect.render._cycles): height map -> bpy mesh -> Cycles render.

Forward models: a known height grid must come back from the mesh vertices; a tilted
aluminium mirror under a uniform dome must show aluminium's Fresnel reflectance at the
tilt angle; a fixed seed must give the same image bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from render_inspect.errors import InputError
from render_inspect.machining import HeightMap

pytestmark = pytest.mark.blender


def _fresnel_conductor(theta, eta, k):
    """Unpolarised reflectance of a conductor of complex index eta + ik at incidence theta."""
    n = np.asarray(eta) + 1j * np.asarray(k)
    c = np.cos(theta)
    ct = np.sqrt(n**2 - np.sin(theta) ** 2)
    rs = (c - ct) / (c + ct)
    rp = (n**2 * c - ct) / (n**2 * c + ct)
    return (abs(rs) ** 2 + abs(rp) ** 2) / 2


def _plane(slope_x, n=17, half=0.5):
    x = np.linspace(-half, half, n)
    X, _ = np.meshgrid(x, x)
    z = slope_x * X
    return HeightMap(z, z.copy(), x[1] - x[0], (-half, -half))


def test_mesh_vertices_are_the_heights_times_exaggeration():
    import bpy

    from render_inspect.render._cycles import heightmap_object, object_heights

    bpy.ops.wm.read_factory_settings(use_empty=True)
    rng = np.random.default_rng(3)
    h = rng.normal(scale=1e-4, size=(7, 9))
    h[2, 3] = np.nan
    obj = heightmap_object(h, pixel=0.01, origin=(1.0, -2.0), exaggeration=250.0)
    assert len(obj.data.vertices) == 63
    # the 4 quads around the NaN point are dropped
    assert len(obj.data.polygons) == 6 * 8 - 4
    co = np.empty(63 * 3, np.float32)
    obj.data.vertices.foreach_get("co", co)
    co = co.reshape(7, 9, 3)
    np.testing.assert_allclose(co[0, :, 0], 1.0 + 0.01 * np.arange(9), rtol=1e-6)
    np.testing.assert_allclose(co[:, 0, 1], -2.0 + 0.01 * np.arange(7), rtol=1e-6)
    ok = np.isfinite(h)
    np.testing.assert_allclose(co[..., 2][ok], 250.0 * h[ok], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(object_heights(obj)[ok], h[ok], rtol=1e-6, atol=1e-12)
    assert obj["render_inspect_exaggeration"] == 250.0
    assert list(obj["render_inspect_shape"]) == [7, 9]


def test_mesh_rejects_bad_input():
    from render_inspect.render._cycles import heightmap_object

    with pytest.raises(InputError, match="exaggeration"):
        heightmap_object(np.zeros((3, 3)), pixel=0.1, exaggeration=0.0)
    with pytest.raises(InputError, match="pixel"):
        heightmap_object(np.zeros((3, 3)), pixel=-1.0)
    with pytest.raises(InputError, match="2-D"):
        heightmap_object(np.zeros(5), pixel=0.1)
    with pytest.raises(InputError, match="NaN"):
        heightmap_object(np.full((3, 3), np.nan), pixel=0.1)


@pytest.mark.parametrize("tilt_deg", [0.0, 60.0, 75.0])
def test_tilted_mirror_under_dome_shows_aluminium_fresnel(tilt_deg):
    from render_inspect.render._cycles import ALUMINIUM_ETA, ALUMINIUM_K, render_cycles

    exaggeration = 10.0
    hm = _plane(np.tan(np.radians(tilt_deg)) / exaggeration)
    res = render_cycles(hm, exaggeration=exaggeration, resolution=32, spp=4, light="dome")
    img = res["image"]
    assert img.shape == (32, 32, 3)
    inner = img[6:-6, 6:-6].reshape(-1, 3)  # away from the pixel filter's reach past the edge
    expected = _fresnel_conductor(np.radians(tilt_deg), ALUMINIUM_ETA, ALUMINIUM_K)
    np.testing.assert_allclose(np.median(inner, axis=0), expected, atol=1e-4)
    # a perfect mirror under a uniform sky: every path returns F(theta), bar the odd
    # ray that grazes a triangle edge
    assert np.mean(np.abs(inner - expected).max(axis=1) < 1e-3) > 0.98


def test_render_is_bitwise_repeatable_and_seed_dependent(tmp_path):
    from render_inspect.io import read_exr
    from render_inspect.render._cycles import render_cycles

    x = np.linspace(-0.1, 0.1, 41)
    X, Y = np.meshgrid(x, x)
    z = 1e-3 * np.sin(2 * np.pi * X / 0.1) * np.cos(2 * np.pi * Y / 0.13)
    hm = HeightMap(z, z.copy(), x[1] - x[0], (-0.1, -0.1))
    kw = dict(exaggeration=100.0, resolution=32, spp=8, light="ring")
    a = render_cycles(hm, seed=5, out=tmp_path / "a", **kw)
    b = render_cycles(hm, seed=5, **kw)
    c = render_cycles(hm, seed=6, **kw)
    assert np.array_equal(a["image"], b["image"])
    assert not np.array_equal(a["image"], c["image"])
    assert a["image"].std() > 0.01  # the ring's reflections make a pattern
    channels, attrs = read_exr(tmp_path / "a" / "cycles.exr")
    np.testing.assert_array_equal(channels["G"], a["image"][..., 1])
    assert attrs["seed"] == 5 and attrs["spp"] == 8 and attrs["exaggeration"] == 100.0
    assert (tmp_path / "a" / "cycles.png").is_file()


def test_render_rejects_bad_input():
    import bpy

    from render_inspect.render._cycles import render_object

    bpy.ops.wm.read_factory_settings(use_empty=True)
    with pytest.raises(InputError, match="Simulate first"):
        render_object(None)
    from render_inspect.render._cycles import render_cycles

    with pytest.raises(InputError, match="light must be"):
        render_cycles(_plane(0.0), light="laser", resolution=16, spp=1)
    with pytest.raises(InputError, match="spp"):
        render_cycles(_plane(0.0), resolution=16, spp=0)
