"""Diffuse-light images: mirror-like aluminium under a known dome / ring light.

A tilted flat mirror seen straight down reflects the sky at zenith angle 2 * atan(E s)
(E = vertical exaggeration, s = true slope), so its radiance is the light's profile there
times aluminium's reflectance: a closed-form answer for the path tracer.
"""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

from render_inspect.errors import InputError
from render_inspect.machining import HeightMap
from render_inspect.render import (
    AL_REFLECTANCE_RGB,
    diffuse_scene_spec,
    environment_map,
    light_profile,
    render_diffuse,
)
from render_inspect.scene import DiffuseConfig

pytestmark = pytest.mark.mitsuba


def _tilted(zenith_deg, exaggeration, n=41, pixel=0.01):
    c = np.arange(n) * pixel
    X, _ = np.meshgrid(c, c)
    z = X * math.tan(math.radians(zenith_deg / 2)) / exaggeration
    return HeightMap(z, z.copy(), pixel, (0.0, 0.0))


def _micro(light, ex=200.0, **kw):
    return DiffuseConfig(light=light, spp=8, resolution=24, exaggeration=ex,
                         window=(0.1, 0.1, 0.3, 0.3), **kw)


@pytest.mark.parametrize("light,zenith,profile", [("dome", 16.5, 0.5), ("dome", 4.0, 0.0),
                                                  ("ring", 60.0, 1.0), ("ring", 30.0, 0.0)])
def test_tilted_mirror_reflects_the_light_profile(light, zenith, profile):
    ex = 200.0
    rgb, meta = render_diffuse(_tilted(zenith, ex), _micro(light, ex), view="micro")
    assert light_profile(math.radians(zenith), light) == pytest.approx(profile)
    expect = profile * np.asarray(AL_REFLECTANCE_RGB)
    np.testing.assert_allclose(rgb.reshape(-1, 3).mean(axis=0), expect, rtol=0.02, atol=1e-3)
    assert rgb.std() < 0.01  # a flat mirror: uniform
    assert meta["vertical_exaggeration"] == ex


def test_exaggeration_is_applied_and_stated():
    # the same true slope at 100x reflects zenith 2 * atan(100 s) instead of 2 * atan(200 s)
    s = math.tan(math.radians(8.25)) / 200.0
    hm = _tilted(16.5, 200.0)
    rgb100, meta = render_diffuse(hm, _micro("dome", 100.0), view="micro")
    zen = 2 * math.degrees(math.atan(100 * s))
    expect = light_profile(math.radians(zen), "dome") * AL_REFLECTANCE_RGB[0]
    assert rgb100[..., 0].mean() == pytest.approx(expect, rel=0.03)
    assert meta["exaggeration"] == 100.0 and meta["camera"]["type"] == "orthographic"


def test_rough_aluminium_blurs_the_camera_port_edge():
    hm = _tilted(8.0, 200.0)  # reflection right at the port's edge
    smooth, _ = render_diffuse(hm, _micro("dome"), view="micro")
    rough, meta = render_diffuse(hm, _micro("dome", roughness=0.3), view="micro")
    assert meta["material"]["type"] == "roughconductor"
    assert smooth.mean() < 0.01 < rough.mean()


def test_macro_view_is_seeded_repeatable_and_decimated():
    c = np.linspace(-1, 1, 301)
    X, Y = np.meshgrid(c, c)
    z = 5e-4 * np.sin(2 * np.pi * X / 0.5) * np.sin(2 * np.pi * Y / 0.5)
    hm = HeightMap(z, z + 2e-6 * np.sin(2 * np.pi * np.hypot(X, Y) / 0.01), c[1] - c[0], (-1.0, -1.0))
    cfg = DiffuseConfig(spp=4, resolution=32)
    a, meta = render_diffuse(hm, cfg, view="macro", seed=3)
    b, _ = render_diffuse(hm, cfg, view="macro", seed=3)
    c3, _ = render_diffuse(hm, cfg, view="macro", seed=4)
    assert a.shape == (32, 32, 3)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c3)
    assert a.std() > 0.05  # the waviness shows as shading
    assert meta["mesh_stride"] == 5 and meta["mesh_triangles"] <= 2 * 64 * 64 + 8 * 64 + 1
    assert meta["mesh"]["skirt"] and meta["camera"]["type"] == "perspective"
    assert meta["seed"] == 3 and meta["mitsuba_variant"] in ("llvm_ad_rgb", "scalar_rgb", "cuda_ad_rgb")


def test_same_images_in_a_new_process():
    # the diffuse image and a (noisy) interferogram, bitwise, in two fresh processes
    code = (
        "import numpy as np, hashlib;"
        "from render_inspect.machining import HeightMap;"
        "from render_inspect.scene import DiffuseConfig, InterferometerConfig;"
        "from render_inspect.render import render_diffuse; from render_inspect.instruments import render_interferogram;"
        "c=np.linspace(-1,1,201); X,Y=np.meshgrid(c,c);"
        "z=5e-4*np.sin(2*np.pi*X/0.5)*np.cos(2*np.pi*Y/0.7);"
        "hm=HeightMap(z,z+1e-6*np.cos(2*np.pi*X/0.03),c[1]-c[0],(-1.0,-1.0));"
        "rgb,_=render_diffuse(hm,DiffuseConfig(spp=4,resolution=48),view='macro',seed=1);"
        "ig=render_interferogram(hm,InterferometerConfig(objective='5x',pixel=0.02),seed=2);"
        "print(hashlib.sha256(rgb.tobytes()+ig.frames.tobytes()+ig.height_true.tobytes()).hexdigest())")
    out = [subprocess.run([sys.executable, "-c", code], check=True, capture_output=True,
                          text=True).stdout.strip().splitlines()[-1] for _ in range(2)]
    assert out[0] == out[1]


def test_scene_spec_is_plain_numbers_and_light_image_matches_profile():
    import json

    hm = _tilted(10.0, 200.0)
    spec = diffuse_scene_spec(hm, DiffuseConfig(light="ring"), view="macro")
    json.dumps(spec)  # plain data only
    assert spec["light"]["type"] == "ring" and spec["material"]["material"] == "Al"
    env = environment_map("ring", height=361)
    assert env.shape == (361, 720, 3)
    theta = np.arange(361) / 360 * math.pi
    np.testing.assert_allclose(env[:, 0, 0], light_profile(theta, "ring"), atol=1e-6)


def test_bad_input():
    hm = _tilted(10.0, 200.0)
    with pytest.raises(InputError, match="view"):
        diffuse_scene_spec(hm, None, view="side")
    with pytest.raises(InputError, match="render.diffuse.window"):
        diffuse_scene_spec(hm, DiffuseConfig(window=(2.0, 2.0, 3.0, 3.0)), view="micro")
    with pytest.raises(InputError, match="surface"):
        diffuse_scene_spec(hm, None, surface="ideal")
    with pytest.raises(InputError, match="seed"):
        render_diffuse(hm, None, seed=-2)


def test_auto_exaggeration_brings_the_steepest_slopes_to_0_2_rad():
    from render_inspect.machining import HeightMap
    from render_inspect.render._diffuse import auto_exaggeration

    x = np.arange(101) * 0.01
    z = np.broadcast_to(1e-4 * x[None, :], (101, 101)).copy()  # slope 1e-4
    hm = HeightMap(z, z.copy(), 0.01, (0.0, 0.0))
    assert auto_exaggeration(hm) == 2000.0  # 0.2 / 1e-4, on the 1-2-5 steps
    hm2 = HeightMap(z * 3, z * 3, 0.01, (0.0, 0.0))
    assert auto_exaggeration(hm2) == 500.0  # 666 -> 500
