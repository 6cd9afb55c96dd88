"""Design surfaces: known answers (sags, curvatures, lenslet depths) and analytic
derivatives against finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import (
    Biconic,
    Compound,
    LensletArray,
    LensletRings,
    Plane,
    SinusoidalGrid,
    Sphere,
    Toric,
    make_surface,
)
from render_inspect.errors import InputError, SceneError
from render_inspect.scene import load_scene, scene_from_dict


def _fd_gradient(s, x, y, h=1e-6):
    gx = (s.height(x + h, y) - s.height(x - h, y)) / (2 * h)
    gy = (s.height(x, y + h) - s.height(x, y - h)) / (2 * h)
    return gx, gy


def _fd_hessian(s, x, y, h=1e-5):
    gxp, gyp = s.gradient(x + h, y)
    gxm, gym = s.gradient(x - h, y)
    _, gyyp = s.gradient(x, y + h)
    _, gyym = s.gradient(x, y - h)
    return (gxp - gxm) / (2 * h), (gyp - gym) / (2 * h), (gyyp - gyym) / (2 * h)


def _check_derivatives(s, x, y, *, gtol=1e-6, htol=1e-5):
    """Analytic gradient/Hessian == central differences (abs tol relative to scale)."""
    g = s.gradient(x, y)
    for a, b in zip(g, _fd_gradient(s, x, y)):
        assert_allclose(a, b, atol=gtol * max(1.0, float(np.max(np.abs(b)))), rtol=1e-5)
    hs = s.hessian(x, y)
    for a, b in zip(hs, _fd_hessian(s, x, y)):
        assert_allclose(a, b, atol=htol * max(1.0, float(np.max(np.abs(b)))), rtol=1e-4)


RNG = np.random.default_rng(12345)
XY = RNG.uniform(-1.5, 1.5, size=(2, 200))


@pytest.mark.parametrize("surface", [
    SinusoidalGrid(0.002, 0.001, 2.5, 1.7, 0.3, -0.2),
    Plane(0.01, -0.02, 0.5),
    Sphere(20.0), Sphere(-15.0, x0=0.2, y0=-0.1, offset=0.01),
    Toric(50.0, 20.0), Toric(-50.0, 20.0), Toric(30.0, -80.0), Toric(-10.0, -25.0),
    Biconic(20.0, 40.0, -0.5, 0.3), Biconic(-25.0, 60.0, -1.0, -1.0),
    Compound(Biconic(1000.0, 1000.0), SinusoidalGrid(0.03, 0.03, 4.0, 4.0, -np.pi / 2, -np.pi / 2)),
], ids=lambda s: repr(s)[:40])
def test_analytic_derivatives_match_finite_differences(surface):
    _check_derivatives(surface, XY[0], XY[1])


def test_sphere_sag_and_apex_curvature():
    R = 50.0
    s = Sphere(R)
    # sag at r = 5: R - sqrt(R^2 - 25)
    assert_allclose(s.height(3.0, 4.0), -(R - math.sqrt(R * R - 25.0)), rtol=1e-13)
    hxx, hxy, hyy = s.hessian(0.0, 0.0)
    assert_allclose([hxx, hxy, hyy], [-1 / R, 0.0, -1 / R], atol=1e-15)
    mean, gauss = s.curvature(0.0, 0.0)
    assert_allclose(mean, -1 / R, rtol=1e-12)
    assert_allclose(gauss, 1 / R ** 2, rtol=1e-12)
    # the mean curvature of a sphere is 1/R everywhere, not only at the apex
    mean, gauss = s.curvature(XY[0] * 10, XY[1] * 10)
    assert_allclose(mean, -1 / R, rtol=1e-9)
    assert_allclose(gauss, 1 / R ** 2, rtol=1e-9)
    c = Sphere(-R)
    assert_allclose(c.height(3.0, 4.0), R - math.sqrt(R * R - 25.0), rtol=1e-13)
    assert_allclose(c.section_curvature(0.0, 0.0, 0.7), 1 / R, rtol=1e-12)
    with pytest.raises(InputError, match="design.radius"):
        s.height(60.0, 0.0)


@pytest.mark.parametrize("rx, ry", [(500.0, 250.0), (-40.0, 25.0), (30.0, -60.0), (-20.0, -35.0)])
def test_toric_principal_curvatures(rx, ry):
    t = Toric(rx, ry)
    hxx, hxy, hyy = t.hessian(0.0, 0.0)
    assert_allclose([hxx, hxy, hyy], [-1 / rx, 0.0, -1 / ry], atol=1e-15)
    # both principal sections are circles of those radii
    u = np.linspace(-5, 5, 11)
    circ = lambda R, s: -np.sign(R) * (abs(R) - np.sqrt(R * R - s * s))  # noqa: E731
    assert_allclose(t.height(u, 0.0), circ(rx, u), atol=1e-13)
    assert_allclose(t.height(0.0, u), circ(ry, u), atol=1e-13)
    # every section x = const is a circle of radius |ry| -+ sag_x(x) (the torus construction)
    x = 3.0
    sag_x = abs(rx) - math.sqrt(rx * rx - x * x)
    r_local = abs(ry) - np.sign(rx) * np.sign(ry) * sag_x
    assert_allclose(t.hessian(x, 0.0)[2], -np.sign(ry) / r_local, rtol=1e-12)


def test_plane_gradient_and_biconic_paraboloid():
    p = Plane(0.01, -0.03, 2.0)
    gx, gy = p.gradient(XY[0], XY[1])
    assert_allclose(gx, 0.01)
    assert_allclose(gy, -0.03)
    assert_allclose(p.height(1.0, 2.0), 0.01 - 0.06 + 2.0)
    # type = "paraboloid" is the biconic with conic -1: z = -x^2/(2 Rx) - y^2/(2 Ry)
    par = make_surface({"type": "paraboloid", "radius_x": 10.0, "radius_y": -20.0})
    assert_allclose(par.height(XY[0], XY[1]), -XY[0] ** 2 / 20 + XY[1] ** 2 / 40, atol=1e-15)
    with pytest.raises(SceneError, match="conic_x:? must be -1"):
        make_surface({"type": "paraboloid", "radius_x": 10.0, "radius_y": 20.0, "conic_x": 0.0})
    b = Biconic(20.0, 40.0)
    assert_allclose(b.hessian(0.0, 0.0), [-1 / 20, 0.0, -1 / 40], atol=1e-15)


# ---- lenslets ---------------------------------------------------------------------------------
def table4(**kw):
    """Seed 000 Table 4: 2 x 2, centre spacing 4.243 mm, aperture radius 2 mm, R 250.004 mm."""
    cfg = dict(rows=2, cols=2, pitch_x=4.243, pitch_y=4.243, lens_radius=250.004,
               aperture_radius=2.0)
    cfg.update(kw)
    return LensletArray(**cfg)


def test_table4_chord_height_is_8_um():
    m = table4()
    assert_allclose(m.chord_height, 0.008, rtol=1e-9)
    cx = [c[2] for c in m.centers()]
    cy = [c[3] for c in m.centers()]
    assert sorted(set(np.round(cx, 6))) == [-2.1215, 2.1215]
    assert sorted(set(np.round(cy, 6))) == [-2.1215, 2.1215]
    for (_, _, x, y) in m.centers():
        assert_allclose(m.height(x, y), -0.008, rtol=1e-9)          # dimple bottom
        assert_allclose(m.height(x + 2.0 - 1e-9, y), 0.0, atol=1e-10)  # rim at the base plane
        assert_allclose(m.height(x + 2.01, y), 0.0)                 # flat outside
    assert_allclose(m.max_slope(), 2.0 / math.sqrt(250.004 ** 2 - 4.0), rtol=1e-12)
    # sag instead of lens_radius: R = (a^2 + h^2) / (2 h) = 250.004
    ms = make_surface({"type": "lenslet_array", "rows": 2, "cols": 2, "pitch_x": 4.243,
                       "pitch_y": 4.243, "sag": 0.008, "aperture_radius": 2.0})
    assert_allclose(ms.lens_radius, 250.004, rtol=1e-12)
    convex = table4(concave=False, offset=1.0)
    assert_allclose(convex.height(2.1215, -2.1215), 1.008, rtol=1e-12)


def test_quad_mla_depths_seed003():
    r, p = 1.0, 0.19975
    q = LensletArray(rows=4, cols=4, pitch_x=p, pitch_y=p, lens_radius=r, cells="quad")
    for (_, _, x, y) in q.centers():
        z0 = q.height(x, y)
        edges = q.height(np.array([x + p / 2 - 1e-12, x, x - p / 2 + 1e-12]),
                         np.array([y, y + p / 2 - 1e-12, y]))
        assert_allclose(edges - z0, 0.005, rtol=2e-3)               # 5 um at edge midpoints
        corner = q.height(x + p / 2 - 1e-12, y + p / 2 - 1e-12)
        assert_allclose(corner - z0, 0.010, rtol=3e-3)              # 10 um at the corners
    assert q.aperture_radius is None and q.pitch_x == p
    # the blank outside the array sits at the corners' level
    x0, y0, x1, y1 = q.bounds
    assert_allclose(q.height(x1 + 0.05, 0.0), q.chord_height)
    with pytest.raises(InputError, match="half the cell diagonal"):
        LensletArray(rows=2, cols=2, pitch_x=2.0, pitch_y=2.0, lens_radius=1.0, cells="quad")


def test_lenslet_derivatives_match_finite_differences():
    m = table4(concave=False)
    q = LensletArray(rows=3, cols=5, pitch_x=0.2, pitch_y=0.25, lens_radius=1.0, cells="quad",
                     center_x=0.1)
    rings = LensletRings([0.0, 1.0, 2.0], [1, 8, 16], 0.3, 0.002, phase_deg=10.0)
    for s, scale in ((m, 4.0), (q, 0.4), (rings, 2.2)):
        x = RNG.uniform(-scale, scale, 400)
        y = RNG.uniform(-scale, scale, 400)
        # keep points away from the edges where the slope jumps (the FD stencil must not cross)
        far = np.ones(x.shape, bool)
        for (_, _, cx, cy) in s.centers():
            d = np.hypot(x - cx, y - cy)
            if isinstance(s, LensletArray) and s.cells == "quad":
                far &= (np.abs(np.abs(x - cx) - s.pitch_x / 2) > 1e-3)
                far &= (np.abs(np.abs(y - cy) - s.pitch_y / 2) > 1e-3)
            else:
                far &= np.abs(d - s.aperture_radius) > 1e-3
        _check_derivatives(s, x[far], y[far])
        gx, gy = s.gradient(x[far], y[far])
        assert np.max(np.hypot(gx, gy)) <= s.max_slope() * (1 + 1e-9)


def test_lenslet_rings_seed004():
    # 36 elements of plane radius 0.4 mm fit on rings >= 4.6 mm (seed 004's note)
    s = LensletRings([4.6, 5.5], [36, 36], 0.4, 0.002, phase_deg=5.0)
    assert_allclose(s.lens_radius, (0.16 + 4e-6) / 0.004)
    cs = s.centers()
    assert len(cs) == 72
    for (k, n, x, y) in cs[::7]:
        assert_allclose(math.hypot(x, y), [4.6, 5.5][k])
        assert_allclose(math.degrees(math.atan2(y, x)) % 360, (5.0 + 10.0 * n) % 360, atol=1e-9)
        assert_allclose(s.height(x, y), -0.002, rtol=1e-12)
    assert_allclose(s.height(0.0, 0.0), 0.0)
    # a point 0.2 mm from an element centre: depth 2 um - sag(0.2)
    k, n, x, y = cs[3]
    R = s.lens_radius
    assert_allclose(s.height(x + 0.2, y), -(0.002 - (R - math.sqrt(R * R - 0.04))), rtol=1e-12)


def test_compound_adds_heights_and_derivatives():
    base = Biconic(1000.0, 1000.0)
    feat = SinusoidalGrid(0.03, 0.03, 4.0, 4.0)
    c = Compound(base, feat)
    x, y = XY
    assert_allclose(c.height(x, y), base.height(x, y) + feat.height(x, y))
    for a, b, f in zip(c.hessian(x, y), base.hessian(x, y), feat.hessian(x, y)):
        assert_allclose(a, b + f)
    with pytest.raises(InputError, match="design.base"):
        Compound("sphere", feat)


# ---- scene-level checks ---------------------------------------------------------------------
def test_make_surface_from_every_scene(scenes_dir):
    files = sorted(scenes_dir.glob("*.toml"))
    assert files, "no scene files"
    for f in files:
        scene = load_scene(f)
        s = make_surface(scene.design)
        x0, y0, x1, y1 = scene.simulation.region
        xs, ys = np.meshgrid(np.linspace(x0, x1, 9), np.linspace(y0, y1, 9))
        z = s.height(xs, ys)
        gx, gy = s.gradient(xs, ys)
        assert z.shape == xs.shape and np.all(np.isfinite(z)), f.name
        assert np.all(np.isfinite(gx)) and np.all(np.isfinite(gy)), f.name


def test_scene_sts_mla_2x2_is_table4(scenes_dir):
    scene = load_scene(scenes_dir / "sts_mla_2x2.toml")
    m = make_surface(scene.design)
    assert isinstance(m, LensletArray)
    assert_allclose(m.chord_height, 0.008, rtol=1e-6)
    assert_allclose(m.lens_radius, 250.004, rtol=1e-6)
    assert (m.rows, m.cols, m.pitch_x, m.aperture_radius) == (2, 2, 4.243, 2.0)
    assert scene.process.spindle_rpm == 50 and scene.process.feed_mm_per_min == 0.5
    assert scene.tool.nose_radius == 0.514 and scene.process.compensation == "z"
    ny, nx = scene.simulation.shape
    assert ny * nx <= 1_000_000
    # the region crosses a lenslet's rim: both the flat and the dimple are inside it
    x0, y0, x1, y1 = scene.simulation.region
    xs, ys = np.meshgrid(np.linspace(x0, x1, 41), np.linspace(y0, y1, 41))
    z = m.height(xs, ys)
    assert np.any(z == 0.0) and np.any(z < -1e-5)


def test_scene_compound_sinusoid_is_seed001(scenes_dir):
    scene = load_scene(scenes_dir / "compound_sinusoid.toml")
    s = make_surface(scene.design)
    assert isinstance(s, Compound)
    x, y = XY
    # Z = Z1 + Z2: Z1 from two orthogonal circles r1 = r2 = 1000 mm (apex at 0), Z2 = h sin(w x) + h sin(w y)
    r, h, w = 1000.0, 0.03, 2 * math.pi / 4.0
    want = (np.sqrt(r * r - x * x) - r) + (np.sqrt(r * r - y * y) - r) + h * np.sin(w * x) + h * np.sin(w * y)
    assert_allclose(s.height(x, y), want, atol=1e-12)
    assert scene.tool.nose_radius == 0.506 and scene.process.compensation == "normal"
    assert scene.process.sampling == "hybrid"
    assert_allclose(scene.process.feed_per_rev, 0.05)
    # the tool fits: nose radius below the smallest concave radius of curvature
    assert 1 / (h * w * w) > scene.tool.nose_radius


def test_lenslet_scene_validation_names_the_key():
    base = {"design": {"type": "lenslet_array", "rows": 2, "cols": 2, "pitch_x": 4.243,
                       "pitch_y": 4.243, "aperture_radius": 2.0}}
    with pytest.raises(SceneError, match="exactly one of lens_radius"):
        scene_from_dict(base)
    both = {"design": dict(base["design"], lens_radius=250.004, sag=0.008)}
    with pytest.raises(SceneError, match="exactly one of lens_radius"):
        scene_from_dict(both)
    big = {"design": dict(base["design"], lens_radius=250.004, aperture_radius=2.5)}
    with pytest.raises(SceneError, match="aperture_radius:? must be <= half the smaller pitch"):
        scene_from_dict(big)
    quad_sag = {"design": {"type": "lenslet_array", "pitch_x": 0.2, "pitch_y": 0.2, "sag": 0.005,
                           "cells": "quad"}}
    with pytest.raises(SceneError, match="sag:? is only defined"):
        scene_from_dict(quad_sag)
    with pytest.raises(InputError, match="design.sag"):
        LensletArray(pitch_x=4.243, pitch_y=4.243, sag=2.5, aperture_radius=2.0)
