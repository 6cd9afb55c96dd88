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


def test_mesh_rejects_bad_input(monkeypatch):
    from render_inspect.render import _cycles
    from render_inspect.render._cycles import heightmap_object

    monkeypatch.setattr(_cycles, "MAX_VERTICES", 20)
    with pytest.raises(InputError, match="simulation.pixel"):
        heightmap_object(np.zeros((5, 5)), pixel=0.1)
    monkeypatch.undo()

    with pytest.raises(InputError, match="exaggeration"):
        heightmap_object(np.zeros((3, 3)), pixel=0.1, exaggeration=0.0)
    with pytest.raises(InputError, match="pixel"):
        heightmap_object(np.zeros((3, 3)), pixel=-1.0)
    with pytest.raises(InputError, match="2-D"):
        heightmap_object(np.zeros(5), pixel=0.1)
    with pytest.raises(InputError, match="NaN"):
        heightmap_object(np.full((3, 3), np.nan), pixel=0.1)


@pytest.mark.parametrize("light, tilt_deg", [("dome", 0.0), ("dome", 7.5), ("dome", 30.0),
                                             ("ring", 10.0), ("ring", 30.0)])
def test_tilted_mirror_reflects_the_light_at_twice_its_tilt(light, tilt_deg):
    """Straight down onto an aluminium mirror tilted by a: the view ray leaves at zenith
    angle 2a, so a pixel shows F_Al(a) x L(2a) (Fresnel x the light's zenith profile):
    dark for a flat part under the dome (its camera port), bright at 30 deg, and so on."""
    from render_inspect.render import light_profile
    from render_inspect.render._cycles import ALUMINIUM_ETA, ALUMINIUM_K, render_cycles

    exaggeration = 10.0
    hm = _plane(np.tan(np.radians(tilt_deg)) / exaggeration, n=33)
    dcfg = {"light": light, "micro_light": light, "exaggeration": exaggeration, "resolution": 32,
            "spp": 4}
    rgb, meta = render_cycles(hm, dcfg, view="micro")
    assert rgb.shape == (32, 32, 3) and rgb.dtype == np.float32
    assert meta["camera"]["type"] == "orthographic" and meta["vertical_exaggeration"] == 10.0
    inner = rgb[4:-4, 4:-4].reshape(-1, 3)
    a = np.radians(tilt_deg)
    expected = _fresnel_conductor(a, ALUMINIUM_ETA, ALUMINIUM_K) * light_profile(2 * a, light)
    np.testing.assert_allclose(np.median(inner, axis=0), expected, atol=1e-4)
    # a perfect mirror under a light at infinity: every path returns the same value, bar
    # the odd ray that grazes a triangle edge
    assert np.mean(np.abs(inner - expected).max(axis=1) < 1e-3) > 0.98


def test_render_is_bitwise_repeatable_and_seed_dependent(tmp_path):
    from render_inspect.render._cycles import render_cycles

    x = np.linspace(-0.1, 0.1, 41)
    X, Y = np.meshgrid(x, x)
    z = 1e-3 * np.sin(2 * np.pi * X / 0.1) * np.cos(2 * np.pi * Y / 0.13)
    hm = HeightMap(z, z.copy(), x[1] - x[0], (-0.1, -0.1))
    dcfg = {"light": "dome", "exaggeration": 100.0, "resolution": 32, "spp": 8, "roughness": 0.05}
    a, meta = render_cycles(hm, dcfg, seed=5)
    b, _ = render_cycles(hm, dcfg, seed=5)
    c, _ = render_cycles(hm, dcfg, seed=6)
    assert meta["camera"]["type"] == "perspective" and meta["seed"] == 5
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert a.std() > 0.01  # the waviness shows as shading


def test_render_object_writes_exr_and_png(tmp_path):
    import bpy

    from render_inspect.io import read_exr
    from render_inspect.render._cycles import render_object, surface_object

    bpy.ops.wm.read_factory_settings(use_empty=True)
    hm = _plane(0.05, n=9)
    obj = surface_object(hm, exaggeration=4.0)
    res = render_object(obj, view="micro", out=tmp_path, resolution=16, spp=2, seed=3)
    channels, attrs = read_exr(tmp_path / "cycles.exr")
    np.testing.assert_array_equal(channels["G"], res["image"][..., 1])
    assert attrs["seed"] == 3 and attrs["spp"] == 2 and attrs["vertical_exaggeration"] == 4.0
    assert (tmp_path / "cycles.png").is_file()
    # the user's scene is untouched: no camera, no world was added to it
    assert bpy.context.scene.name != "render_inspect_cycles" and bpy.context.scene.camera is None


def test_render_rejects_bad_input():
    import bpy

    from render_inspect.errors import SceneError
    from render_inspect.render._cycles import render_cycles, render_object

    bpy.ops.wm.read_factory_settings(use_empty=True)
    with pytest.raises(InputError, match="Simulate first"):
        render_object(None)
    with pytest.raises(SceneError, match="light"):
        render_cycles(_plane(0.0), {"light": "laser"})
    with pytest.raises(SceneError, match="spp"):
        render_cycles(_plane(0.0), {"spp": 0})
    with pytest.raises(InputError, match="view"):
        render_cycles(_plane(0.0), {"resolution": 16}, view="side")


@pytest.mark.mitsuba
@pytest.mark.parametrize("view", ["macro", "micro"])
def test_cycles_matches_mitsuba_on_the_same_scene(view):
    """The same diffuse_scene_spec rendered by both engines: the same picture (up to
    Monte-Carlo noise), and the right way round (a mirrored Cycles image does not match)."""
    from render_inspect.render import render_diffuse
    from render_inspect.render._cycles import render_cycles

    x = np.linspace(-0.2, 0.2, 81)
    X, Y = np.meshgrid(x, x)
    # an off-centre bump on a gentle tilt: no symmetry to hide a flipped axis
    z = 2e-3 * np.exp(-((X - 0.08) ** 2 + (Y + 0.05) ** 2) / 0.004) + 2e-3 * X + 1e-3 * Y
    hm = HeightMap(z, z.copy(), x[1] - x[0], (-0.2, -0.2))
    dcfg = {"light": "dome", "exaggeration": 20.0, "resolution": 32, "spp": 64,
            "window": (-0.15, -0.15, 0.15, 0.15)}
    mi_img, mi_meta = render_diffuse(hm, _diffuse(dcfg), view=view, seed=0)
    cy_img, cy_meta = render_cycles(hm, dcfg, view=view, seed=0)
    assert cy_img.shape == mi_img.shape
    assert cy_meta["camera"] == mi_meta["camera"]
    rmse = float(np.sqrt(np.mean((cy_img - mi_img) ** 2)))
    assert abs(float(cy_img.mean() - mi_img.mean())) < 0.01
    assert rmse < 0.03  # measured 0.011 (macro), 0.005 (micro): the noise
    for flipped in (cy_img[::-1], cy_img[:, ::-1]):  # measured 0.18 .. 0.64
        assert float(np.sqrt(np.mean((flipped - mi_img) ** 2))) > 5 * rmse


def _diffuse(d):
    from render_inspect.scene import DiffuseConfig

    return DiffuseConfig(**d)


def test_fresnel_conductor_matches_the_closed_form():
    from render_inspect.render._cycles import ALUMINIUM_ETA, ALUMINIUM_K, fresnel_conductor

    theta = np.radians([0.0, 20.0, 45.0, 70.0, 85.0])
    np.testing.assert_allclose(fresnel_conductor(np.cos(theta), ALUMINIUM_ETA, ALUMINIUM_K),
                               _fresnel_conductor(theta[:, None], ALUMINIUM_ETA, ALUMINIUM_K),
                               rtol=1e-12)
    n, k = np.asarray(ALUMINIUM_ETA), np.asarray(ALUMINIUM_K)
    np.testing.assert_allclose(fresnel_conductor(1.0, n, k),
                               ((n - 1) ** 2 + k**2) / ((n + 1) ** 2 + k**2), rtol=1e-12)


def test_principled_fallback_follows_aluminium_fresnel():
    """Blender 4.2's fallback: the Principled BSDF's F82-tint metal, F(mu) = Schlick(F0, mu)
    - a mu (1 - mu)^6 with a set by the specular tint at mu = 1/7.  With
    f82_tint_colours it equals the conductor Fresnel at 0 and 81.8 deg and stays within
    0.1 % up to 30 deg and 1 % up to 65 deg."""
    from render_inspect.render._cycles import (ALUMINIUM_ETA, ALUMINIUM_K, F82_COS,
                                               f82_tint_colours, fresnel_conductor)

    f0, tint = (np.asarray(c) for c in f82_tint_colours())

    def schlick(mu):
        return f0 + (1 - f0) * (1 - mu) ** 5

    a = schlick(F82_COS) * (1 - tint) / (F82_COS * (1 - F82_COS) ** 6)

    def model(mu):
        return schlick(mu) - a * mu * (1 - mu) ** 6

    for deg, rtol in ((0.0, 1e-12), (15.0, 1e-3), (30.0, 1e-3), (50.0, 1e-2), (65.0, 1e-2)):
        mu = np.cos(np.radians(deg))
        np.testing.assert_allclose(model(mu), fresnel_conductor(mu, ALUMINIUM_ETA, ALUMINIUM_K),
                                   rtol=rtol, err_msg=f"{deg} deg")
    np.testing.assert_allclose(model(F82_COS), fresnel_conductor(F82_COS, ALUMINIUM_ETA, ALUMINIUM_K),
                               rtol=1e-12)


def test_this_blender_has_the_metallic_bsdf():
    import bpy

    from render_inspect.render._cycles import material_model

    assert material_model(bpy) == ("metallic_bsdf" if bpy.app.version >= (4, 3, 0)
                                   else "principled_f82")
