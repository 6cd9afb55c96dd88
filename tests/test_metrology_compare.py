"""compare_measured: a virtually measured map (known misalignment, known residual) through
the same chain as the simulation; bad input (NaNs, pixel mismatch, no overlap, partial
coverage) gives clear errors or warnings."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.io import read_measured, write_x3p
from render_inspect.machining import HeightMap
from render_inspect.metrology import (
    RIGID_KEYS,
    characterise_map,
    compare_measured,
    coverage,
    rigid_resample,
)
from render_inspect.scene import MetrologyConfig


class Freeform:
    def height(self, x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        return (x * x / 40.0 + y * y / 70.0
                + 2e-3 * np.sin(2 * np.pi * x / 0.5) * np.cos(2 * np.pi * y / 0.7))


TRUE = dict(zip(RIGID_KEYS, (5e-3, -3e-3, 2e-3, 3e-4, -2e-4, 1e-3)))
PIXEL, ORIGIN, N = 0.01, (-0.5, -0.5), 101
REGION = (-0.5, -0.5, 0.5, 0.5)


def _marks(x, y):
    return 2e-5 * np.sin(2 * np.pi * np.hypot(x, y) / 0.2)  # 20 nm waviness, 20 pixels/period


def _virtual_measurement(tmp_path):
    x = ORIGIN[0] + PIXEL * np.arange(N)
    y = ORIGIN[1] + PIXEL * np.arange(N)

    class Machined(Freeform):
        def height(self, xx, yy):
            return super().height(xx, yy) + _marks(xx, yy)

    z = rigid_resample(Machined(), TRUE, x[None, :], y[:, None])
    z = z + np.random.default_rng(0).normal(0, 1e-6, z.shape)
    path = write_x3p(tmp_path / "measured.x3p", z, pixel=PIXEL, origin=ORIGIN)
    xx, yy = np.meshgrid(x, y)
    sim = HeightMap(Freeform().height(xx, yy), Freeform().height(xx, yy) + _marks(xx, yy),
                    PIXEL, ORIGIN)
    return path, sim


@pytest.mark.slow  # its comparison sets the registration against 19 surrogates
def test_compare_measured_recovers_residual_and_matches_simulation(tmp_path):
    path, sim = _virtual_measurement(tmp_path)
    cmp_ = compare_measured(read_measured(path), Freeform(), metrology=MetrologyConfig(form_removal="plane"),
                            simulated=sim, region=REGION)
    m = cmp_.metrics
    for k in RIGID_KEYS:
        assert abs(m["registration"][k] - TRUE[k]) < (3e-4 if k[0] == "t" else 1e-4), k
    assert m["coverage"] == 1.0 and m["source"]["format"] == "x3p"
    ref = characterise_map(sim.machined - sim.design, pixel=PIXEL, form_removal="plane")
    # the measured residual is the ripple (seen from a tilted frame) plus 1 nm noise
    assert_allclose(m["measured"]["Sq_nm"], ref["Sq_nm"], rtol=0.05)
    assert_allclose(m["simulated"]["Sq_nm"], ref["Sq_nm"], rtol=0.03)
    assert m["difference"]["Sq_nm"] < 0.15 * ref["Sq_nm"]
    assert set(cmp_.maps) >= {"measured", "design", "residual", "simulated_residual", "difference"}


@pytest.mark.slow  # six comparisons, each setting its registration against 19 surrogates
def test_compare_bad_input(tmp_path):
    path, sim = _virtual_measurement(tmp_path)
    sim2 = HeightMap(sim.design[::2, ::2], sim.machined[::2, ::2], 2 * PIXEL, ORIGIN)
    with pytest.raises(InputError, match=r"measured 0.01 mm vs simulated 0.02 mm"):
        compare_measured(read_measured(path), Freeform(), simulated=sim2)
    with pytest.warns(UserWarning, match="resampled"):
        c = compare_measured(read_measured(path), Freeform(), simulated=sim2, resample_simulated=True)
    assert c.metrics["difference"]["Sq_nm"] < 5.0
    # heights in micrometres read as millimetres: 1000 x the design's range
    zz = rigid_resample(Freeform(), TRUE, (ORIGIN[0] + PIXEL * np.arange(N))[None, :],
                        (ORIGIN[1] + PIXEL * np.arange(N))[:, None])
    with pytest.raises(InputError, match=r"unit is probably wrong \(heights in micrometres or "
                                         r"nanometres read as millimetres\).*--force"):
        compare_measured((zz * 1e3, PIXEL, ORIGIN), Freeform())
    with pytest.raises(InputError, match="does not overlap"):
        compare_measured(read_measured(path), Freeform(), region=(10.0, 10.0, 11.0, 11.0))
    with pytest.warns(UserWarning, match=r"covers only 2[0-9]\.[0-9]% of the region"):
        with pytest.raises(InputError, match=r"overlaps 2[0-9]\.[0-9]% of the smaller .* at least "
                                             r"80% is needed \(--force compares anyway\)"):
            compare_measured(read_measured(path), Freeform(), region=(0.0, 0.0, 1.0, 1.0))
    with pytest.warns(UserWarning, match=r"covers only 2[0-9]\.[0-9]% of the region"):
        c = compare_measured(read_measured(path), Freeform(), region=(0.0, 0.0, 1.0, 1.0), force=True)
    assert c.metrics["checks"]["ok"] is False and c.metrics["checks"]["refusals"]
    # NaNs in the measurement are left out explicitly, and reported through n_valid
    z = rigid_resample(Freeform(), TRUE, (ORIGIN[0] + PIXEL * np.arange(N))[None, :],
                       (ORIGIN[1] + PIXEL * np.arange(N))[:, None])
    z[40:60, 40:60] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        c = compare_measured((z, PIXEL, ORIGIN), Freeform())
    assert c.metrics["measured"]["n_valid"] <= N * N - 400
    assert c.metrics["measured"]["Sq_nm"] < 1.0
    with pytest.raises(InputError, match="registration must be"):
        compare_measured((z, PIXEL, ORIGIN), Freeform(), metrology={"registration": "magic"})
    with pytest.raises(InputError, match="at least 6 valid"):
        compare_measured((np.full((8, 8), np.nan), PIXEL, ORIGIN), Freeform())


def test_coverage_fraction():
    z = np.zeros((11, 11))
    assert coverage(z, pixel=0.1, origin=(0, 0), region=(0, 0, 1, 1)) == 1.0
    # the cells of columns x = 0.5 .. 1.0 reach x = 1.05: 0.55 of the region's width
    assert_allclose(coverage(z, pixel=0.1, origin=(0, 0), region=(0.5, 0, 1.5, 1)), 0.55)
    # rows y = 0 .. 0.5 on 0.05 mm pixels reach y = 0.525
    assert_allclose(coverage(z, pixel=(0.1, 0.05), origin=(0, 0), region=(0.5, 0, 1.5, 1)),
                    0.55 * 0.525)
    with pytest.raises(InputError, match="region"):
        coverage(z, pixel=0.1, origin=(0, 0), region=(1, 0, 0, 1))


class OneDimple:
    """A spherical dimple 2 um deep, 0.4 mm across, centred at (1.5, 0) mm in a flat: the
    field of one round lenslet, which turns freely about its centre."""

    def height(self, x, y):
        r2 = (np.asarray(x, float) - 1.5) ** 2 + np.asarray(y, float) ** 2
        return np.where(r2 < 0.4 ** 2, -0.002 * (1.0 - r2 / 0.4 ** 2), 0.0)


def test_a_round_lenslet_is_registered_with_the_rotation_held_and_a_wrong_map_refused(tmp_path):
    """The field of one round lenslet fixes its centre but not a turn about it: the shift
    of a free registration is undetermined (a turn about the centre is a shift plus a turn
    about the origin), which refused the right map.  Now the rotation is held at the
    file's orientation, the shift recovered and said; a map of another surface of the
    same size and relief is still refused."""
    px, n = 0.004, 226
    x0, y0 = 1.05, -0.45
    x = x0 + px * np.arange(n)
    y = y0 + px * np.arange(n)
    shift = (0.004, -0.003)  # the part sits 4 um in +x and 3 um in -y of its design place
    z = OneDimple().height(x[None, :] - shift[0], y[:, None] - shift[1])
    z = z + np.random.default_rng(0).normal(0, 5e-6, z.shape)
    region = (x0, y0, x0 + px * (n - 1), y0 + px * (n - 1))
    metrology = MetrologyConfig(form_removal="plane")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = compare_measured((z, px, (x0, y0)), OneDimple(), metrology=metrology, region=region,
                             expected_sq_mm=5e-6).metrics
    ch, reg = m["checks"], m["registration"]
    assert ch["ok"] and ch["rotation_held"] and reg["fitted"] == ["tx", "ty", "tz", "alpha", "beta"]
    # the design moved onto the part: by the part's shift
    assert_allclose([reg["tx_mm"], reg["ty_mm"]], shift, atol=2e-4)
    assert reg.get("gamma_rad", 0.0) == 0.0
    assert ch["warnings"][0].startswith("the design turns freely about a point in the field")
    assert "held at the file's orientation" in ch["warnings"][0]
    assert ch["uncertainty"]["shift_mm"] < px  # registered again with the rotation held
    # a map of another surface of like relief is still refused: a ripple of 2 um
    other = 0.002 * np.sin(2 * np.pi * x[None, :] / 0.3) * np.cos(2 * np.pi * y[:, None] / 0.4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(InputError, match="does not match the design"):
            compare_measured((other, px, (x0, y0)), OneDimple(), metrology=metrology,
                             region=region, expected_sq_mm=5e-6)
