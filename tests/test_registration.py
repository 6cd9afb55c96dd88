"""Outliers (second-difference 3-sigma) and 6-DOF rigid registration (direct LSQ and ICP):
a known misalignment is injected with the forward model and recovered."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import LensletArray
from render_inspect.errors import InputError
from render_inspect.metrology import (
    RIGID_KEYS,
    MovedSurface,
    detect_outliers,
    register_icp,
    register_lsq,
    rigid_resample,
    template_surface,
)


class Freeform:
    """Toric base + a sinusoidal feature: no symmetry, so all 6 DOF are determined."""

    def height(self, x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        return (x * x / 40.0 + y * y / 70.0
                + 2e-3 * np.sin(2 * np.pi * x / 0.5) * np.cos(2 * np.pi * y / 0.7))

    def gradient(self, x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        k1, k2 = 2 * np.pi / 0.5, 2 * np.pi / 0.7
        gx = x / 20.0 + 2e-3 * k1 * np.cos(k1 * x) * np.cos(k2 * y)
        gy = y / 35.0 - 2e-3 * k2 * np.sin(k1 * x) * np.sin(k2 * y)
        return gx, gy


# tx, ty, tz (mm), alpha, beta, gamma (rad): 8, -5, 3 um; 0.4, -0.3, 1.5 mrad
TRUE = dict(zip(RIGID_KEYS, (8e-3, -5e-3, 3e-3, 4e-4, -3e-4, 1.5e-3)))
# tolerances: 0.3 um in x/y, 0.05 um in z, 0.05 mrad in the tilts, 0.1 mrad about z
TOL = dict(zip(RIGID_KEYS, (3e-4, 3e-4, 5e-5, 5e-5, 5e-5, 1e-4)))


def _measured(surface, n=60, pixel=0.02, noise=2e-6, spikes=5, seed=1):
    rng = np.random.default_rng(seed)
    origin = (-0.6, -0.6)
    x = origin[0] + pixel * np.arange(n)
    y = origin[1] + pixel * np.arange(n)
    z = rigid_resample(surface, TRUE, x[None, :], y[:, None])
    z = z + rng.normal(0, noise, z.shape)
    idx = rng.choice(z.size, spikes, replace=False)
    z.flat[idx] += rng.choice([-1, 1], spikes) * 2e-3  # 2 um spikes
    return z, pixel, origin, idx


def _check(reg):
    for k in RIGID_KEYS:
        assert abs(reg[k] - TRUE[k]) < TOL[k], (k, reg[k], TRUE[k])


def test_rigid_resample_is_the_exact_forward_model():
    s = Freeform()
    rng = np.random.default_rng(0)
    u, v = rng.uniform(-0.5, 0.5, (2, 50))
    from render_inspect.metrology import rotation_matrix

    vec = np.array([TRUE[k] for k in RIGID_KEYS])
    p = rotation_matrix(*vec[3:]) @ np.vstack([u, v, s.height(u, v)]) + vec[:3, None]
    assert_allclose(rigid_resample(s, TRUE, p[0], p[1]), p[2], atol=1e-12)


def test_second_difference_outliers_found_and_replaced():
    z, pixel, origin, idx = _measured(Freeform(), spikes=8)
    cleaned, out = detect_outliers(z, pixel=pixel)
    rows, cols = np.unravel_index(idx, z.shape)
    interior = (rows > 0) & (rows < z.shape[0] - 1) & (cols > 0) & (cols < z.shape[1] - 1)
    assert out.flat[idx[interior]].all()
    assert out.sum() < 0.02 * z.size   # only the spikes and a few neighbours / noise tails
    clean_ref = rigid_resample(Freeform(), TRUE, origin[0] + pixel * cols, origin[1] + pixel * rows)
    # replaced by the mean of the valid neighbours: within the local curvature term
    # (f'' d^2 ~ 0.3 / mm * (0.02 mm)^2 ~ 1e-4 mm) of the truth, not 2e-3 mm away
    assert np.all(np.abs(cleaned.flat[idx[interior]] - clean_ref[interior]) < 3e-4)
    with pytest.raises(InputError, match="pixel"):
        detect_outliers(z, pixel=-1)


def test_lsq_registration_recovers_injected_misalignment():
    z, pixel, origin, _ = _measured(Freeform())
    cleaned, out = detect_outliers(z, pixel=pixel)
    reg = register_lsq(cleaned, Freeform(), pixel=pixel, origin=origin, mask=~out)
    _check(reg)
    assert reg["rms_mm"] < 4e-6 and reg["method"] == "lsq"
    # and with the template (design sampled 10 x denser) instead of the analytic design
    tpl = template_surface(Freeform(), region=(-0.7, -0.7, 0.7, 0.7), pixel=pixel)
    _check(register_lsq(cleaned, tpl, pixel=pixel, origin=origin, mask=~out))


def test_icp_registration_recovers_injected_misalignment():
    z, pixel, origin, _ = _measured(Freeform(), n=50)
    cleaned, out = detect_outliers(z, pixel=pixel)
    reg = register_icp(cleaned, Freeform(), pixel=pixel, origin=origin, mask=~out, oversample=10)
    _check(reg)
    assert reg["method"] == "icp" and reg["iterations"] < 50


def test_lsq_registration_of_a_lenslet_array_on_a_plane():
    la = LensletArray(rows=3, cols=3, pitch_x=0.4, pitch_y=0.4, aperture_radius=0.18,
                      lens_radius=1.0)
    z, pixel, origin, _ = _measured(la, n=60, pixel=0.02)
    cleaned, out = detect_outliers(z, pixel=pixel)
    reg = register_lsq(cleaned, la, pixel=pixel, origin=origin, mask=~out)
    _check(reg)
    moved = MovedSurface(la, reg)
    x, y = moved.move_point(0.0, 0.0)[:2]
    assert abs(x - TRUE["tx_mm"]) < 1e-3 and abs(y - TRUE["ty_mm"]) < 1e-3


def test_registration_bad_input():
    with pytest.raises(InputError, match="at least 6 valid"):
        register_lsq(np.full((10, 10), np.nan), Freeform(), pixel=0.01)
    z, pixel, origin, _ = _measured(Freeform(), n=20)
    with pytest.raises(InputError, match="fit entries"):
        register_lsq(z, Freeform(), pixel=pixel, origin=origin, fit=("tx", "scale"))
    with pytest.warns(UserWarning, match="10 x"):
        template_surface(Freeform(), region=(-0.1, -0.1, 0.1, 0.1), pixel=0.02, oversample=4)


def test_icp_template_too_large_names_the_key_the_largest_value_and_the_received_one():
    # a map of 593 x 593 pixels of 2 um at the default oversampling would make a template of
    # 4.3e7 points: refused in one line naming the scene key, the largest oversampling that
    # fits this map (3: 4.7e6 points) and the value received; a map too large for any
    class Flat:
        def height(self, x, y):
            return np.zeros(np.broadcast(x, y).shape)

        def gradient(self, x, y):
            z = np.zeros(np.broadcast(x, y).shape)
            return z, z

    z = np.zeros((593, 593))
    with pytest.raises(InputError) as e:
        register_icp(z, Flat(), pixel=0.002, oversample=10, max_iter=1)
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("metrology.template_oversample")
    assert "must be at most 3 for a map of 593 x 593 pixels" in msg and msg.endswith("received 10")
    with pytest.raises(InputError, match="cannot be small enough"):
        register_icp(np.zeros((3000, 3000)), Flat(), pixel=0.002, oversample=2, max_iter=1)
