"""Material response and the cutting mechanics in the envelope: minimum chip thickness
(Son et al.), Brammertz's cusp height, side flow, contact ratio of vibration cutting,
grooves, and seed 003's steel with and without ultrasonic vibration."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from render_inspect.errors import InputError
from render_inspect.machining import simulate_turning
from render_inspect.machining._cutting import (cut_lines_mechanics, cut_turning_mechanics,
                                               groove_texture, machined_edges)
from render_inspect.machining._material import (MATERIAL_PRESETS, contact_ratio,
                                                elastic_recovery, material_preset,
                                                material_response, min_chip_thickness)
from render_inspect.machining._sculpt import sculpt_surface
from render_inspect.toolpath import ToolPath

# The direct (reference) cut and envelope models are compiled on their first call, 15 CPU-s
# each from an empty cache: the files that call them run on one worker under `make test`,
# so each is compiled once per run (the two workers compiled them side by side before).
pytestmark = pytest.mark.xdist_group("direct_models")


# ---- the material model ---------------------------------------------------------------
def test_min_chip_thickness_of_son_et_al():
    # frictionless: 1 - cos(45 deg); mu = 0.2: 1 - cos(45 deg - atan(0.2) / 2)
    assert_allclose(min_chip_thickness(50.0, 0.0), 50.0 * (1 - math.cos(math.pi / 4)), rtol=1e-12)
    assert_allclose(min_chip_thickness(50.0, 0.2),
                    50.0 * (1 - math.cos(math.pi / 4 - math.atan(0.2) / 2)), rtol=1e-12)
    assert min_chip_thickness(50.0, 0.5) < min_chip_thickness(50.0, 0.1)


def test_presets_are_physical():
    for name, m in MATERIAL_PRESETS.items():
        k = elastic_recovery(m)
        assert 0.0 < k < 1.0, name
        assert m.sources
    # the reduced modulus is below both moduli
    steel = material_preset("die_steel")
    assert steel.reduced_modulus_gpa < steel.youngs_modulus_gpa
    with pytest.raises(InputError, match="material.preset must be one of"):
        material_preset("brass")
    with pytest.raises(InputError, match="unknown material setting"):
        material_preset("al6061", {"hardness": 1.0})
    assert material_preset("al6061", {"friction": 0.3}).friction == 0.3


def test_contact_ratio_of_one_dimensional_vibration_cutting():
    # continuous cutting, or a vibration too slow to reverse the tool: always in contact
    assert contact_ratio(1.0) == 1.0
    assert contact_ratio(10.0, 1e-3, 1000.0) == 1.0          # 2 pi f A = 6.3 mm/s < 10
    # seed 003: 100 mm/min, 0.75 um, 104 kHz; small-ratio approximation sqrt(v / (pi A w))
    v, a, f = 100 / 60, 0.75e-3, 104e3
    eta = contact_ratio(v, a, f)
    assert_allclose(eta, math.sqrt(v / (math.pi * a * 2 * math.pi * f)), rtol=0.05)
    assert 0.02 < eta < 0.05


def test_the_contact_ratio_scales_nothing_and_continuous_steel_is_outside_the_model():
    """No source relates the contact ratio to the surface left: it is reported, nothing
    scales with it; continuous cutting of a diamond-reactive material is flagged."""
    eta = contact_ratio(100 / 60, 0.75e-3, 104e3)
    for name in ("die_steel", "al6061"):
        cs = material_response(material_preset(name), edge_radius=50e-6)
        uv = material_response(material_preset(name), edge_radius=50e-6, contact_ratio=eta)
        for k in ("h_min", "kappa", "groove_rms", "burr_height", "texture_rms", "burr_coefficient"):
            assert getattr(uv, k) == getattr(cs, k), (name, k)
        assert uv.validity is None
        assert (cs.validity is not None) == (name == "die_steel")
    assert "outside the model" in material_response(material_preset("die_steel")).validity


# ---- the envelope with the cutting mechanics ---------------------------------------------
def _face(R=0.1, f=0.005, P=720, revs=40, r0=2.0):
    k = np.arange(revs * P)
    th = k * 2 * np.pi / P
    return ToolPath(th, r0 - f * k / P, np.zeros(k.size), th / 4.4)


def test_no_minimum_chip_thickness_is_the_geometric_envelope_exactly():
    p = _face()
    region = (1.92, -0.002, 1.95, 0.002)
    # the mechanics model evaluates each pass's arc directly, as the reference kernel does
    geo = simulate_turning(p, nose_radius=0.1, region=region, pixel=0.0002, reference=True)
    cut = cut_turning_mechanics(p, nose_radius=0.1, region=region, pixel=0.0002)
    assert_allclose(cut["machined"], geo, atol=0, rtol=0)
    # the fast kernel differs only by the rounding of its interpolation fraction
    fast = simulate_turning(p, nose_radius=0.1, region=region, pixel=0.0002)
    assert_allclose(cut["machined"], fast, atol=1e-12, rtol=0)
    assert np.all(cut["added"] == 0)


def test_brammertz_cusp_height_with_full_recovery():
    """kappa = 1: material thinner than h_min stays; the peak-to-valley is
    f^2/(8R) + h_min/2 (1 + R h_min / f^2) (Brammertz 1961, parabolic arcs); here the
    exact circular construction, within the pixel's sampling of the step."""
    R, f, hmin, pixel = 0.1, 0.005, 12e-6, 1e-5
    cut = cut_turning_mechanics(_face(R, f), nose_radius=R, region=(1.93, 0.0, 1.9401, 0.0), pixel=pixel,
                      h_min=hmin, kappa=1.0)
    row = cut["machined"][0]

    def za(x):
        return R - np.sqrt(R * R - x * x)

    xs = brentq(lambda x: za(x) - za(x - f) - hmin, 0.0, f)
    rt = np.nanmax(row) - np.nanmin(row)
    assert abs(rt - za(xs)) <= (xs / R) * pixel * 1.05
    assert_allclose(za(xs), f * f / (8 * R) + hmin / 2 * (1 + R * hmin / f ** 2), rtol=0.01)


def test_side_flow_raises_the_cusp_by_one_minus_kappa_h_min():
    R, f, hmin, kappa = 0.1, 0.005, 12e-6, 0.05
    p = _face(R, f)
    region = (1.93, 0.0, 1.9401, 0.0)
    geo = simulate_turning(p, nose_radius=R, region=region, pixel=1e-5)[0]
    cut = cut_turning_mechanics(p, nose_radius=R, region=region, pixel=1e-5, h_min=hmin, kappa=kappa)
    row = cut["machined"][0]
    assert_allclose(np.nanmax(row) - np.nanmax(geo), (1 - kappa) * hmin, rtol=0.02)
    # the material is put on the cusps, never taken
    assert np.all(row >= geo - 1e-15)


def test_lines_without_minimum_chip_are_sculpt_surface():
    rng = np.random.default_rng(1)
    prof = rng.normal(0, 1e-4, size=(4, 50))
    xl = np.array([-0.2, 0.0, 0.2, 0.4])
    xg = np.linspace(-0.3, 0.5, 81)
    a = sculpt_surface(prof, xl, xg, tool_radius=1.0, half_width=0.5)
    b = cut_lines_mechanics(prof, xl, xg, tool_radius=1.0, half_width=0.5)
    assert_allclose(b["machined"], a, atol=0, rtol=0)
    edges = machined_edges(b["pass_line"], jump=0.5)
    assert edges.any() and not edges.all()


def test_grooves_are_seeded_positional_and_sized():
    u = np.linspace(-0.05, 0.05, 400)[None, :]
    v = np.linspace(0, 2.0, 300)[:, None]
    g = groove_texture(u, v, rms=40e-6, seed=7, across_length=0.001, along_length=0.1)
    assert_allclose(np.sqrt(np.mean(g * g)), 40e-6, rtol=0.15)
    assert_allclose(groove_texture(u, v, rms=40e-6, seed=7), groove_texture(u, v, rms=40e-6, seed=7))
    # correlated along the cut, not across
    along = np.corrcoef(g[:-1].ravel(), g[1:].ravel())[0, 1]
    across = np.corrcoef(g[:, :-12].ravel(), g[:, 12:].ravel())[0, 1]  # 3 um apart
    assert along > 0.9 and across < 0.5
