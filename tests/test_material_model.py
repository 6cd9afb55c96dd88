"""The material model against forward models with known answers: elastic recovery as the
recovered depth of a conical contact, the uncut chip thickness of a round nose, the burr
law (depth of cut, exit angle, ductility) on ridges of known angle, the part's texture
(positional, sized), the presets' sources and the copper temper."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.core.errors import InputError
from render_inspect.machining import (BURR_WIDTH_PER_CHIP, MATERIAL_PRESETS, burr_height_law,
                                      edge_turns, material_burrs, material_preset,
                                      material_response, texture_field, uncut_chip_thickness)
from render_inspect.machining._material import (DUCTILITY_REFERENCE_PERCENT,
                                                INDENTER_HALF_ANGLE_DEG, elastic_recovery)

HV = 9.80665e-3  # GPa per Vickers number


def _cone_unloading(h_c, hardness, e_r, theta_deg, m=2.0):
    """Oliver & Pharr's forward model of a conical indentation: the load at the contact
    depth h_c (P = H A, A = pi tan^2(theta) h_c^2), the contact stiffness at the top
    (S = 2 E_r sqrt(A / pi)), and the unloading curve P = alpha (h - h_f)^m through the top
    with that slope, solved for where it reaches zero load.  Returns the recovered depth
    h_max - h_f and the sink-in epsilon P / S (epsilon = 0.727 for a cone)."""
    from scipy.optimize import brentq

    t = math.tan(math.radians(theta_deg))
    area = math.pi * t * t * h_c * h_c
    p_max = hardness * area
    s = 2 * e_r * math.sqrt(area / math.pi)
    # alpha delta^m = P_max and m alpha delta^(m - 1) = S at the top: delta solves both
    delta = brentq(lambda d: m * (p_max / d ** m) * d ** (m - 1) - s, 1e-12 * h_c, 1e3 * h_c)
    return delta, 0.727 * p_max / s


@pytest.mark.parametrize("name", sorted(MATERIAL_PRESETS))
def test_elastic_recovery_is_the_recovered_depth_of_a_cone(name):
    mat = material_preset(name)
    h_c = 20e-6
    recovered, sink_in = _cone_unloading(h_c, mat.hardness_gpa, mat.reduced_modulus_gpa,
                                         INDENTER_HALF_ANGLE_DEG)
    k = elastic_recovery(mat)
    assert k == pytest.approx(recovered / h_c, rel=1e-7)
    # 2 / epsilon = 2.75 times the sink-in at the contact perimeter (what was used before)
    assert k / (sink_in / h_c) == pytest.approx(2 / 0.727, rel=1e-9)


def test_recovered_depth_numbers_and_the_half_hard_copper():
    """kappa = pi tan(70.3 deg) H / E_r: al6061 0.127 (107 HV, 68.9 GPa); half-hard copper
    (95 HV, within the 90-110 HV of H090 and below the 110 HV of fully hard) 0.069."""
    assert elastic_recovery(material_preset("al6061")) == pytest.approx(0.127, abs=0.001)
    cu = material_preset("ofhc_copper")
    assert 65 * HV < cu.hardness_gpa < 110 * HV and cu.hardness_gpa == pytest.approx(95 * HV)
    assert elastic_recovery(cu) == pytest.approx(0.069, abs=0.001)


def test_every_preset_number_names_its_source_or_its_range():
    for name, m in MATERIAL_PRESETS.items():
        text = " ".join(m.sources.values())
        for key in ("friction", "burr_coefficient", "texture"):
            assert any(key in k for k in m.sources), (name, key)
        assert "assumed" in text or "sheet" in text or "Table" in text, name
    assert all(p.adhesion_roughness_nm == 0 and p.adhesion_layer_nm == 0
               for p in MATERIAL_PRESETS.values())


def test_uncut_chip_thickness_of_a_round_nose():
    r, f = 0.5, 0.01
    for d in (1e-4, 1e-3, 3e-3):
        psi = math.acos(1 - d / r)
        assert uncut_chip_thickness(f, d, r) == pytest.approx(min(f * math.sin(psi), d))
    # shallow: f sqrt(2 d / R); deep, fine feed: the depth itself bounds it
    assert uncut_chip_thickness(f, 1e-5, r) == pytest.approx(1e-5)
    assert uncut_chip_thickness(0.01, 0.003, 0.514) == pytest.approx(0.01 * math.sqrt(2 * 0.003 / 0.514), rel=0.01)
    assert uncut_chip_thickness(0.0, 0.003, 0.5) == 0.0
    with pytest.raises(InputError, match="nose_radius"):
        uncut_chip_thickness(0.01, 0.003, 0.0)


PIX = 0.001


def _roof(slope, n=201, noise=0.0):
    x = -0.1 + PIX * np.arange(n)
    z = np.broadcast_to(-slope * np.abs(x)[None, :], (n, n)).copy()
    if noise:
        z += np.random.default_rng(0).normal(0.0, noise, z.shape)
    return x, z


@pytest.mark.parametrize("slope", [0.02, 0.1, 0.3, 2.0])
def test_burr_on_a_ridge_of_known_exit_angle(slope):
    """A ridge where the surface turns by 2 atan(slope) (exit angle pi minus that): the
    burr is C h_u turn / 90 deg (capped at a square edge), one pixel line on the ridge,
    cos^2 across it, width 3 h_u; the turn is found through the smoothing."""
    x, z = _roof(slope, noise=1e-9)
    turn = 2 * math.atan(slope)
    h_u, c = 0.001, 0.8
    out, info = material_burrs(z, z, pixel=PIX, origin=(-0.1, -0.1), chip_thickness=h_u,
                               coefficient=c, variation=0.0, smoothing=0.002)
    want = c * h_u * min(turn / (math.pi / 2), 1.0)
    assert info["turn_max_deg"] == pytest.approx(math.degrees(turn), rel=0.01)
    assert info["height_max_um"] == pytest.approx(want * 1e3, rel=0.01)
    row = (out - z)[100]
    assert_allclose(row.max(), want, rtol=0.01)
    assert x[np.argmax(row)] == pytest.approx(0.0, abs=PIX)
    w = BURR_WIDTH_PER_CHIP * h_u
    assert np.all(row[np.abs(x) > w / 2 + PIX] == 0)


def test_burr_law_depth_exit_angle_and_ductility():
    turn = np.array([0.0, math.pi / 8, math.pi / 4, math.pi / 2, math.pi])
    h = burr_height_law(0.002, 1.0, turn)
    assert_allclose(h, 0.002 * np.array([0, 0.25, 0.5, 1.0, 1.0]))     # exit angle
    assert_allclose(burr_height_law(0.001, 1.0, turn), h / 2)          # depth of cut
    # ductility: the coefficient follows the elongation at break up to A_ref
    al = material_response(material_preset("al6061"))
    nip = material_response(material_preset("nip"))
    assert al.burr_coefficient == pytest.approx(1.0)
    assert nip.burr_coefficient == pytest.approx(1.1 / DUCTILITY_REFERENCE_PERCENT)
    brittle = material_response(material_preset("al6061", {"elongation_percent": 0.0}))
    assert brittle.burr_coefficient == 0.0
    _, z = _roof(0.3)
    out, info = material_burrs(z, z, pixel=PIX, chip_thickness=0.001,
                               coefficient=brittle.burr_coefficient, smoothing=0.002)
    assert_allclose(out, z) and info["max_added_um"] == 0.0


def test_smooth_surfaces_and_feed_marks_have_no_burr():
    x = -0.1 + PIX * np.arange(201)
    X, Y = np.meshgrid(x, x)
    sphere = (X ** 2 + Y ** 2) / (1 + np.sqrt(1 - X ** 2 - Y ** 2))
    marks = sphere + 20e-6 * np.cos(2 * np.pi * X / 0.01)           # 10 um feed marks, 20 nm
    for z in (sphere, marks):
        out, info = material_burrs(z, z, pixel=PIX, chip_thickness=0.003, coefficient=1.0,
                                   smoothing=0.01)
        assert info["edge_pixels"] == 0 and np.array_equal(out, z)
    e, t = edge_turns(sphere, pixel=PIX)
    assert not e.any() and not t.any()


def test_texture_belongs_to_the_part():
    """The texture is a field of the position: the same seed gives the same heights at the
    same place on any grid; its rms and correlation length are the ones asked for."""
    xa = np.arange(0.0, 0.6, 0.001)
    ya = np.arange(0.0, 0.6, 0.001)
    a = texture_field(xa, ya, rms=1e-6, correlation_length=0.03, seed=4)
    b = texture_field(xa[100:300:2], ya[50:250:5], rms=1e-6, correlation_length=0.03, seed=4)
    assert_allclose(b, a[50:250:5, 100:300:2], rtol=0, atol=1e-18)
    assert np.sqrt(np.mean(a * a)) == pytest.approx(1e-6, rel=0.3)
    lag = 30  # one correlation length: exp(-1/2) = 0.61 for the Gaussian covariance
    c = np.corrcoef(a[:, :-lag].ravel(), a[:, lag:].ravel())[0, 1]
    assert c == pytest.approx(math.exp(-0.5), abs=0.15)
    assert not np.allclose(texture_field(xa, ya, rms=1e-6, correlation_length=0.03, seed=5), a)
    assert not texture_field(xa, ya, rms=0.0, correlation_length=0.03, seed=4).any()
