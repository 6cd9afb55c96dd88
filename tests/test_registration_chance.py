"""A measured map's registration set against chance: the score of the registration (the
share of the map's variance the registered design explains) must beat what the same
search reaches on phase-randomised surrogates of the map.  Forward models: a dimple array
cut by the STS process (the scene's own simulation, shifted and with noise) is reliable;
maps of other surfaces of the same relief (another dimple pitch, a ripple, the right map
turned 90 deg on a design that is not symmetric) are not; noise of the same spectrum is a
draw from the null itself and explains far less.
ICP holds the rotation of one round lenslet as least squares does."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import make_surface
from render_inspect.metrology import (
    NULL_SURROGATES,
    compare_measured,
    explained_share,
    phase_surrogate,
)
from render_inspect.pipeline import expected_sq_mm, simulate
from render_inspect.scene import MetrologyConfig, load_scene, shipped_scenes

#: 2 um deep round dimples (aperture 0.1 mm, R 2.5 mm) on a 0.25 x 0.4 mm lattice, cut by
#: the shipped STS micro-lens scene's process: not symmetric under a quarter turn
DIMPLES = ["design.rows=4", "design.cols=4", "design.pitch_x=0.25", "design.pitch_y=0.4",
           "design.aperture_radius=0.1", "design.lens_radius=2.5",
           "process.workpiece_radius=1.0", "simulation.region=[-0.3,-0.3,0.3,0.3]",
           "simulation.pixel=0.006"]
CROP = 4  # the measured field leaves this many pixels of the simulation on each side


def _scene(extra=()):
    return load_scene(shipped_scenes()["sts_mla_2x2"], DIMPLES + list(extra))


def _measured(machined, shift_px=(1, -1), seed=1):
    """The simulated cut as a measurement of the part sitting ``shift_px`` pixels away
    from its design place, with 5 nm of noise."""
    sx, sy = shift_px
    k = CROP
    z = machined[k - sy:machined.shape[0] - k - sy, k - sx:machined.shape[1] - k - sx]
    return z + np.random.default_rng(seed).normal(0, 5e-6, z.shape)


def _compare(scene, z, origin, **metrology):
    met = scene.metrology.model_copy(update=metrology)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return compare_measured((z, scene.simulation.pixel, origin), make_surface(scene.design),
                                metrology=met, region=tuple(scene.simulation.region),
                                expected_sq_mm=expected_sq_mm(scene), force=True).metrics


@pytest.fixture(scope="module")
def dimples():
    scene = _scene()
    hm = simulate(scene).heightmap
    other = simulate(_scene(["design.pitch_x=0.4", "design.pitch_y=0.25"])).heightmap
    px = hm.pixel
    origin = (hm.origin[0] + CROP * px, hm.origin[1] + CROP * px)
    return scene, hm, other, origin


def test_phase_surrogate_keeps_the_spectrum_and_the_mean():
    rng = np.random.default_rng(3)
    for shape in [(64,), (63,), (48, 64), (47, 63), (48, 63), (47, 64)]:
        a = rng.standard_normal(shape).cumsum(axis=0) + 5.0
        s = phase_surrogate(a, np.random.default_rng(1))
        assert s.shape == a.shape and np.isrealobj(s)
        assert_allclose(np.abs(np.fft.rfftn(s - s.mean())), np.abs(np.fft.rfftn(a - a.mean())),
                        atol=1e-9)
        assert_allclose(s.mean(), a.mean())
        assert abs(np.corrcoef(s.ravel(), a.ravel())[0, 1]) < 0.9  # the structure is gone


def test_explained_share():
    x, y = np.meshgrid(np.linspace(0, 1, 30), np.linspace(0, 1, 30))
    d = np.sin(6 * x) * np.cos(5 * y)
    assert_allclose(explained_share(x, y, d + 0.3 * x - 2, d), 1.0)  # a plane is not counted
    noise = np.random.default_rng(0).normal(0, 1, d.shape)
    assert abs(explained_share(x, y, noise, np.zeros_like(d))) < 1e-12
    assert explained_share(x, y, noise, d) < 0  # a design unrelated to the map makes it worse


@pytest.mark.slow
def test_the_right_map_is_reliable_and_maps_of_other_surfaces_are_not(dimples):
    scene, hm, other, origin = dimples
    own = _measured(hm.machined)
    m = _compare(scene, own, origin)
    reg = m["registration"]
    assert m["checks"]["ok"] and reg["reliable"]
    assert reg["score"] > 0.99 and reg["score"] > reg["null_score"]
    ch = reg["chance"]
    assert ch["surrogates"] == NULL_SURROGATES == len(ch["null_scores"]) and ch["seed"] == 0
    assert "phase-randomised surrogates" in ch["rule"]
    assert m["measured"]["registration_reliable"] is True
    assert_allclose([reg["tx_mm"], reg["ty_mm"]], [0.006, -0.006], atol=1e-3)
    px = scene.simulation.pixel
    ny, nx = own.shape
    x = origin[0] + px * np.arange(nx)
    y = origin[1] + px * np.arange(ny)
    wrong = {
        # the same dimples on a 0.4 x 0.25 mm lattice
        "another pitch": (_measured(other.machined), origin),
        # a ripple of the same relief (2 um peak to valley)
        "ripple": (-1e-3 + 1e-3 * np.sin(2 * np.pi * x[None, :] / 0.2)
                   * np.cos(2 * np.pi * y[:, None] / 0.17), origin),
        # the right map turned a quarter turn (the lattice is 0.25 x 0.4 mm)
        "turned 90 deg": (np.rot90(own), origin),
    }
    for name, (z, o) in wrong.items():
        m = _compare(scene, z, o)
        reg = m["registration"]
        assert not reg["reliable"], (name, reg["score"], reg["null_score"])
        assert m["measured"]["registration_reliable"] is False, name
        assert any(w.startswith("the registration is not reliable") for w in
                   m["checks"]["warnings"]), name
    # the right map's spectrum with random phases: a draw from the null itself, so it
    # beats the surrogates by chance about once in 20 draws; it explains far less
    noise = phase_surrogate(own, np.random.default_rng(11))
    m = _compare(scene, noise, origin)
    assert m["registration"]["score"] < 0.7
    # the ripple passed every other check (its residual, 0.8 um, is under the 2 um floor)
    m = _compare(scene, wrong["ripple"][0], origin)
    assert m["checks"]["ok"] and not m["registration"]["reliable"]


@pytest.mark.slow  # its comparison sets the registration against 19 surrogates
def test_a_ripple_is_not_reliable_with_icp_either(dimples):
    scene, hm, other, origin = dimples
    own = _measured(hm.machined)
    m = _compare(scene, own, origin, registration="icp", template_oversample=4)
    assert m["registration"]["method"] == "icp" and m["registration"]["reliable"]
    px = scene.simulation.pixel
    x = origin[0] + px * np.arange(own.shape[1])
    y = origin[1] + px * np.arange(own.shape[0])
    rip = -1e-3 + 1e-3 * np.sin(2 * np.pi * x[None, :] / 0.2) * np.cos(2 * np.pi * y[:, None] / 0.17)
    m = _compare(scene, rip, origin, registration="icp", template_oversample=4)
    assert not m["registration"]["reliable"]
    # the residual checked is the heights' (ICP's own rms is to the nearest tangent plane)
    assert m["checks"]["residual_rms_mm"] > 5e-4


class OneDimple:
    """A spherical dimple 2 um deep, 0.4 mm across, centred at (1.5, 0) mm in a flat: the
    field of one round lenslet, which turns freely about its centre."""

    def height(self, x, y):
        r2 = (np.asarray(x, float) - 1.5) ** 2 + np.asarray(y, float) ** 2
        return np.where(r2 < 0.4 ** 2, -0.002 * (1.0 - r2 / 0.4 ** 2), 0.0)

    def gradient(self, x, y):
        dx, dy = np.asarray(x, float) - 1.5, np.asarray(y, float)
        inside = dx ** 2 + dy ** 2 < 0.4 ** 2
        k = 0.004 / 0.4 ** 2
        return np.where(inside, k * dx, 0.0), np.where(inside, k * dy, 0.0)


def test_icp_holds_the_rotation_of_one_round_lenslet_and_keeps_the_dof():
    """ICP fitted the rotation about z freely where least squares holds it (a turn about
    the lenslet's centre is a shift plus a turn about the origin); now both hold it, and
    ICP fits only ``metrology.registration_dof``."""
    px, n = 0.008, 113
    x0, y0 = 1.05, -0.45
    x = x0 + px * np.arange(n)
    y = y0 + px * np.arange(n)
    shift = (0.008, -0.008)
    z = OneDimple().height(x[None, :] - shift[0], y[:, None] - shift[1])
    z = z + np.random.default_rng(0).normal(0, 5e-6, z.shape)
    region = (x0, y0, x0 + px * (n - 1), y0 + px * (n - 1))
    met = MetrologyConfig(form_removal="plane", registration="icp", template_oversample=4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m = compare_measured((z, px, (x0, y0)), OneDimple(), metrology=met, region=region,
                             expected_sq_mm=5e-6).metrics
    ch, reg = m["checks"], m["registration"]
    assert ch["ok"] and ch["rotation_held"], ch
    assert reg["fitted"] == ["tx", "ty", "tz", "alpha", "beta"] and reg["gamma_rad"] == 0.0
    assert_allclose([reg["tx_mm"], reg["ty_mm"]], shift, atol=1e-3)
    assert reg["reliable"]
    held = met.model_copy(update={"registration_dof": ["tz", "alpha", "beta"]})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        reg = compare_measured((z, px, (x0, y0)), OneDimple(), metrology=held,
                               force=True).metrics["registration"]
    assert reg["fitted"] == ["tz", "alpha", "beta"]
    assert reg["tx_mm"] == reg["ty_mm"] == reg["gamma_rad"] == 0.0
