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
    return DiffuseConfig(light=light, micro_light=light, spp=8, resolution=24, exaggeration=ex,
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


@pytest.mark.parametrize("zenith", [0.0, 12.0, 25.0, 40.0])
def test_brightfield_is_the_overlap_of_the_objective_cones(zenith):
    """A reflected-light microscope's brightfield: a mirror tilted so that it turns the
    optical axis by ``zenith`` returns the share of the illumination cone that lands in
    the objective's cone (two caps of asin(NA), ``zenith`` apart): 1 flat, 0 beyond
    2 asin(NA)."""
    from render_inspect.render._studio import brightfield_profile, cap_overlap

    na, ex = 0.3, 200.0
    cfg = DiffuseConfig(micro_light="brightfield", objective_na=na, spp=8, resolution=24,
                        exaggeration=ex, window=(0.1, 0.1, 0.3, 0.3))
    rgb, meta = render_diffuse(_tilted(zenith, ex), cfg, view="micro")
    a = math.asin(na)
    exact = float(cap_overlap(a, a, math.radians(zenith)))
    prof = np.asarray(brightfield_profile(na))
    assert float(np.interp(zenith, prof[:, 0], prof[:, 1])) == pytest.approx(exact, abs=0.02)
    np.testing.assert_allclose(rgb.reshape(-1, 3).mean(axis=0),
                               exact * np.asarray(AL_REFLECTANCE_RGB), rtol=0.03, atol=0.01)
    assert meta["light"]["type"] == "brightfield" and meta["light"]["objective_na"] == na
    if zenith == 0.0:
        assert exact == 1.0
    if zenith == 40.0:
        assert exact == 0.0


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


def test_environment_azimuth_matches_mitsuba_envmap():
    """The lat-long image's columns are where Mitsuba's envmap (rotated so +z is up) looks:
    a port around a tilted axis is found in that direction by Emitter.eval."""
    from render_inspect.render import import_mitsuba

    mi, dr, _ = import_mitsuba()
    axis = np.array([0.3, -0.4, 0.866])
    axis /= np.linalg.norm(axis)
    env = environment_map("dome", axis=axis)
    em = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(env),
                       "to_world": mi.ScalarTransform4f().rotate([1, 0, 0], 90)})
    mirror = np.array([-axis[0], -axis[1], axis[2]])  # the camera's mirror direction
    dirs = np.stack([axis, mirror, [0.0, 0.0, -1.0]])
    si = dr.zeros(mi.SurfaceInteraction3f, len(dirs))
    si.wi = mi.Vector3f(-dirs[:, 0], -dirs[:, 1], -dirs[:, 2])
    val = np.array(em.eval(si))[0]
    assert val[0] == pytest.approx(0.0, abs=1e-3)   # the port, around the axis
    assert val[1] == pytest.approx(1.0, abs=1e-3)   # the dome, 2 x 30 deg away
    assert val[2] == pytest.approx(0.0, abs=1e-3)   # below the horizon


def test_grating_efficiencies_of_a_sinusoidal_phase_grating_are_bessel():
    """Thin-element theory: a sinusoidal profile h = a cos(2 pi x / d) puts the fraction
    J_m(2 k a)^2 into order m (Raman-Nath)."""
    from scipy.special import jv

    from render_inspect.render._turned_bsdf import grating_efficiencies

    d, a, lam = 0.01, 40e-6, 550.0
    n = 4096
    x = (np.arange(n) + 0.5) / n * d
    eta = grating_efficiencies(a * np.cos(2 * np.pi * x / d), period=d, wavelength_nm=lam,
                               orders=5)
    phi = 2 * (2 * np.pi / (lam * 1e-6)) * a
    np.testing.assert_allclose(eta, jv(np.arange(-5, 6), phi) ** 2, atol=1e-9)


def test_feed_scallop_efficiencies():
    """The seed-000 feed scallop (10 um, Rc 0.514 mm, PV 24 nm) keeps most of the light in
    the mirror order; the Fig. 16 one (0.1 mm, 2.5 um PV) spreads it over tens of orders,
    out to the geometric angle of its flanks (2 x the slope f / (2 Rc) = 0.1 in direction
    cosine)."""
    from render_inspect.render._turned_bsdf import WAVELENGTHS_NM, efficiency_tables

    t = efficiency_tables(period=0.01, nose_radius=0.514)
    assert t["zero_order_efficiency_550nm"] > 0.9
    assert 0.003 < t["first_order_efficiency_550nm"] < 0.03
    np.testing.assert_allclose(t["norm"], 1.0, atol=1e-6)  # Parseval over all orders
    t2 = efficiency_tables(period=0.1, nose_radius=0.5)
    i = int(np.argmin(np.abs(WAVELENGTHS_NM - 550)))
    eta = t2["eta"][i, -1]
    m = np.arange(eta.size) - t2["orders"]
    u = m * 550e-6 / 0.1
    spread = np.sqrt(np.sum(eta * u * u))
    assert t2["zero_order_efficiency_550nm"] < 0.1
    assert 0.03 < spread < 0.12  # rms of a uniform spread over +-0.1


def test_turned_bsdf_sends_light_into_the_grating_orders():
    """Sampled directions of the spectral BSDF: the u direction cosine (across the marks)
    clusters at -u_i + m lambda / d, v stays at -v_i; the sample weight is the reflectance."""
    from render_inspect.render import import_mitsuba, spectral_variant
    from render_inspect.render._turned_bsdf import (
        efficiency_tables,
        register_turned_bsdf,
        store_tables,
    )

    with spectral_variant() as sv:
        if sv is None:
            pytest.skip("needs a spectral JIT variant (scalar_rgb fallback)")
        mi, dr, _ = import_mitsuba()
        register_turned_bsdf(mi, dr)
        store_tables("test", efficiency_tables(period=0.01, nose_radius=0.2))
        bsdf = mi.load_dict({"type": "turned_al", "table_key": "test", "period_mm": 0.01,
                             "sigma_u": 0.001, "sigma_v": 0.001, "kind": 1, "dx": 0.0,
                             "dy": 1.0})
        n = 200000
        si = dr.zeros(mi.SurfaceInteraction3f, n)
        si.p = mi.Point3f(0.0, 0.0, 0.0)
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(si.n)
        ui = 0.2
        si.wi = mi.Vector3f(ui, 0.0, float(np.sqrt(1 - ui * ui)))
        si.wavelengths = mi.Spectrum(550.0, 550.0, 550.0, 550.0)
        rng = np.random.default_rng(1)
        s1 = mi.Float(rng.random(n).astype(np.float32))
        s2 = mi.Point2f(rng.random(n).astype(np.float32), rng.random(n).astype(np.float32))
        bs, w = bsdf.sample(mi.BSDFContext(), si, s1, s2)
        wo = np.array(bs.wo)
        w = np.array(w)[0]
    ok = w > 0
    # the marks run along y: u is the x direction cosine
    m = (wo[0][ok] + ui) / (550e-6 / 0.01)
    near = np.abs(m - np.round(m))
    assert np.mean(near < 0.1) > 0.99           # on the orders
    assert np.mean(np.round(m) == 0) > 0.5      # mostly the mirror order
    assert np.mean(np.abs(np.round(m)) == 1) > 0.01
    assert np.max(np.abs(wo[1][ok])) < 0.01     # v = -v_i = 0
    np.testing.assert_allclose(np.median(w[ok]), 0.91, atol=0.03)  # aluminium at 550 nm


@pytest.mark.slow
def test_macro_view_of_a_turned_part_has_rainbow_colours():
    """A flat turned disc (feed 10 um) under the lamp: the diffraction orders carry colour
    (a plain conductor under the same light stays grey), and the exaggeration and scale
    are in the metadata."""
    R = 2.0
    n = 129
    x = np.linspace(-R, R, n)
    X, Y = np.meshgrid(x, x)
    z = np.zeros_like(X)
    z[X ** 2 + Y ** 2 > R * R] = np.nan
    hm = HeightMap(z, z.copy(), x[1] - x[0], (-R, -R))
    marks = {"kind": "circular", "center_mm": [0.0, 0.0], "period_mm": 0.01,
             "nose_radius_mm": 0.514}
    cfg = DiffuseConfig(resolution=64, spp=16, exaggeration=1.0)
    rgb, meta = render_diffuse(hm, cfg, view="macro", marks=marks, seed=1)
    assert meta["material"]["type"] == "turned_al" and meta["material"]["grating"]
    assert meta["light"]["type"] == "studio" and meta["light"]["lamp"]["radiance"] > 0
    assert meta["scale"]["mm_per_px_at_target"] > 0
    sat = rgb.max(axis=2) - rgb.min(axis=2)
    assert (sat > 0.2).mean() > 0.002   # coloured pixels: the orders
    plain, _ = render_diffuse(hm, cfg.model_copy(update={"lamp": False}), view="macro",
                              seed=1)
    assert (plain.max(axis=2) - plain.min(axis=2)).max() < 0.05


@pytest.mark.slow
def test_studio_view_of_a_turned_disc_shows_its_edge_and_the_softbox():
    """The whole turned part in the studio: a round solid (face, chamfer, side wall), the
    softbox's mirror image on the far half of the face (bright), the dark backdrop around
    the part, and the front chamfer lit by the strip light."""
    R = 2.0
    x = np.linspace(-R, R, 129)
    X, Y = np.meshgrid(x, x)
    z = np.zeros_like(X)
    z[X ** 2 + Y ** 2 > R * R] = np.nan
    hm = HeightMap(z, z.copy(), x[1] - x[0], (-R, -R))
    marks = {"kind": "circular", "center_mm": [0.0, 0.0], "period_mm": 0.01,
             "nose_radius_mm": 0.514}
    part = {"shape": "disc", "center": [0.0, 0.0], "radius": R}
    cfg = DiffuseConfig(resolution=96, spp=16, exaggeration=1.0)
    rgb, meta = render_diffuse(hm, cfg, view="macro", marks=marks, part=part, seed=2)
    ms = meta["mesh"]
    assert ms["kind"] == "disc" and ms["chamfer_mm"] > 0 and ms["wall_mm"] > 0
    assert len(meta["light"]["softboxes"]) == 2
    lum = rgb.mean(axis=2)
    n = lum.shape[0]
    backdrop = np.r_[lum[:4].ravel(), lum[:, :3].ravel()]
    assert backdrop.max() < 0.05 and backdrop.mean() > 0.005   # dim, not black
    # the face mirrors the softbox (bright) and the room (dim): both show
    face = lum[int(0.3 * n):int(0.75 * n), int(0.35 * n):int(0.65 * n)]
    assert np.percentile(face, 90) > 0.4 and np.percentile(face, 10) < 0.3
    # plain: no studio, no chamfer: the face ends where the map ends
    flat, m2 = render_diffuse(hm, cfg.model_copy(update={"studio": False}), view="macro",
                              marks=marks, part=part, seed=2)
    assert m2["light"]["type"] == "dome" and m2["mesh"]["wall_mm"] == 0
