"""Phase retrieval: synthesise frames with the forward model from a known height map
and recover it (render_inspect.metrology._phase)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.metrology._phase import (
    height_error,
    height_from_phase,
    retrieve_csi,
    retrieve_psi,
    unwrap_phase,
    wrapped_phase,
)

LAM_NM = 632.8
LAM = LAM_NM * 1e-6  # mm


def _grid(n=96, pixel=0.002):
    x = (np.arange(n) - n / 2) * pixel
    return np.meshgrid(x, x)


def _psi_frames(h, steps, *, a=0.5, b=0.4, z_ref=0.0):
    """I_k = a + b cos(2 pi OPD / lambda + delta_k), OPD = 2 (h - z_ref)."""
    opd = 2 * (h - z_ref)
    return np.stack([a + b * np.cos(2 * np.pi * opd / LAM + d) for d in steps])


def _tilted_plane():
    x, y = _grid()
    return 8e-3 * x - 5e-3 * y + 1e-5  # about 8 fringes across the field


def _sphere(radius=5.0):
    x, y = _grid()
    return radius - np.sqrt(radius ** 2 - x * x - y * y)


@pytest.mark.parametrize("surface", [_tilted_plane, _sphere])
@pytest.mark.parametrize("n", [4, 5])
def test_psi_recovers_height(surface, n):
    h = surface()
    steps = np.arange(n) * np.pi / 2 if n == 4 else (np.arange(n) - 2) * np.pi / 2
    res = retrieve_psi(_psi_frames(h, steps), wavelength_nm=LAM_NM, steps_rad=steps)
    assert res.valid.all()
    assert res.meta["algorithm"] == f"{n}step"
    # spans several fringes: unwrapping is needed
    assert np.ptp(h) > 3 * LAM / 2
    aligned, m = height_error(res.height, h, valid=res.valid)
    assert m["rms_nm"] < 0.5 and m["pv_nm"] < 2.0
    assert_allclose(aligned, h, atol=2e-6)


@pytest.mark.parametrize("sign", [1, -1])
def test_step_sign_convention(sign):
    """Steps made by moving the reference (delta_k = -k pi / 2) give the same height
    when the steps are passed in: the sign is taken from steps_rad, not assumed."""
    h = _tilted_plane()
    steps = sign * np.arange(4) * np.pi / 2
    frames = _psi_frames(h, steps)
    res = retrieve_psi(frames, wavelength_nm=LAM_NM, steps_rad=steps)
    _, m = height_error(res.height, h, valid=res.valid)
    assert m["rms_nm"] < 0.5
    # the wrong sign mirrors the surface: a large error, so the convention matters
    bad = retrieve_psi(frames, wavelength_nm=LAM_NM, steps_rad=-steps)
    _, mb = height_error(bad.height, h, valid=bad.valid)
    assert mb["rms_nm"] > 100 * m["rms_nm"] + 10


def test_four_step_formula_matches_textbook():
    h = _sphere()
    f = _psi_frames(h, np.arange(4) * np.pi / 2)
    phi, mod = wrapped_phase(f, algorithm="4step")
    i1, i2, i3, i4 = f
    assert_allclose(phi, np.arctan2(i4 - i2, i1 - i3), atol=1e-12)
    assert_allclose(mod, 0.4 / 0.5, atol=1e-9)
    # phi is the phase of the zero-shift frame: 4 pi h / lambda (mod 2 pi)
    d = phi - 4 * np.pi * h / LAM
    assert_allclose(np.angle(np.exp(1j * d)), 0, atol=1e-9)


def test_lsq_matches_for_other_steps():
    h = _tilted_plane()
    steps = np.arange(7) * 2 * np.pi / 7 + 0.3
    res = retrieve_psi(_psi_frames(h, steps), wavelength_nm=LAM_NM, steps_rad=steps)
    assert res.meta["algorithm"] == "lsq"
    _, m = height_error(res.height, h, valid=res.valid)
    assert m["rms_nm"] < 0.5


def test_five_step_robust_to_step_error():
    """A 5 % miscalibrated pi/2 step: the 4-step error is first order in the step error
    (PV ~ eps pi/2 rad of phase), Hariharan's is second order (much smaller)."""
    h = _tilted_plane()
    eps = 0.05
    true4 = np.arange(4) * np.pi / 2 * (1 + eps)
    true5 = (np.arange(5) - 2) * np.pi / 2 * (1 + eps)
    r4 = retrieve_psi(_psi_frames(h, true4), wavelength_nm=LAM_NM, steps_rad=np.arange(4) * np.pi / 2)
    r5 = retrieve_psi(_psi_frames(h, true5), wavelength_nm=LAM_NM,
                      steps_rad=(np.arange(5) - 2) * np.pi / 2)
    _, m4 = height_error(r4.height, h, valid=r4.valid)
    _, m5 = height_error(r5.height, h, valid=r5.valid)
    nm_per_rad = LAM_NM / (4 * np.pi)
    e = eps * np.pi / 2  # step error, rad
    # 4-step: first order, phase error PV = e (rad)
    assert m4["pv_nm"] == pytest.approx(e * nm_per_rad, rel=0.05)
    # 5-step (Hariharan): second order, phase error PV = e^2 / 2
    assert m5["pv_nm"] == pytest.approx(0.5 * e * e * nm_per_rad, rel=0.2)
    assert m5["rms_nm"] < 0.1 * m4["rms_nm"]


@pytest.mark.parametrize("quality", ["modulation", "reliability"])
def test_noisy_sphere_either_unwrapping_order(quality):
    """Frames with additive noise (1 % of the mean): a few nm, no fringe-order slips."""
    h = _sphere()
    rng = np.random.default_rng(5)
    f = _psi_frames(h, np.arange(4) * np.pi / 2) + rng.normal(0, 0.005, (4,) + h.shape)
    res = retrieve_psi(f, wavelength_nm=LAM_NM, quality=quality)
    _, m = height_error(res.height, h, valid=res.valid)
    assert m["rms_nm"] < 3.0 and m["pv_nm"] < 25.0, m


def test_unwrap_many_fringes_with_holes():
    """A steep tilt (about 20 fringes) with an invalid disc and a noisy corner."""
    x, y = _grid(128)
    phi_true = 2 * np.pi * 20 * (x - x.min()) / np.ptp(x) + 6 * np.sin(3 * y / np.ptp(y))
    valid = np.hypot(x - 0.02, y + 0.01) > 0.03
    wrapped = np.angle(np.exp(1j * phi_true))
    un, labels = unwrap_phase(wrapped, valid=valid)
    assert np.all(np.isnan(un[~valid]))
    assert labels.max() == 1
    diff = (un - phi_true)[valid]
    assert_allclose(diff - diff.mean(), 0, atol=1e-9)


def test_unwrap_separate_regions_are_labelled():
    x, y = _grid(64)
    phi = 40 * x / np.ptp(x) * np.pi
    valid = np.abs(x) > 0.01  # two halves that do not touch
    un, labels = unwrap_phase(np.angle(np.exp(1j * phi)), valid=valid)
    assert labels.max() == 2
    for i in (1, 2):
        d = (un - phi)[labels == i]
        assert_allclose(d - d.mean(), 0, atol=1e-9)


def test_low_modulation_pixels_are_invalid():
    h = _tilted_plane()
    frames = _psi_frames(h, np.arange(4) * np.pi / 2)
    frames[:, :10, :10] = 0.5  # no fringes
    res = retrieve_psi(frames, wavelength_nm=LAM_NM, valid=np.ones(h.shape, bool))
    assert not res.valid[:10, :10].any()
    assert np.isnan(res.height[:10, :10]).all()
    assert res.valid.sum() == h.size - 100


def _csi_stack(h, z, *, lc=0.0012, a=0.5, b=0.4, lam=LAM):
    """White-light stack: Gaussian coherence envelope of 1/e half-width lc (in OPD)."""
    opd = 2 * (h[None] - z[:, None, None])
    return a + b * np.exp(-(opd / lc) ** 2) * np.cos(2 * np.pi * opd / lam)


@pytest.mark.parametrize("refine", ["envelope", "phase"])
@pytest.mark.parametrize("direction", [1, -1])
def test_csi_recovers_step_height(refine, direction):
    x, y = _grid(48)
    step_mm = 0.00173  # 1.73 um step: > lambda/4, PSI alone could not tell it apart
    h = np.where(x > 0, step_mm, 0.0) + 2e-5 * y
    z = np.arange(-0.002, 0.004, 80e-6)[::direction]
    res = retrieve_csi(_csi_stack(h, z), z, wavelength_nm=LAM_NM, refine=refine)
    assert res.valid.all()
    # absolute heights (no piston freedom): no alignment
    _, m = height_error(res.height, h, piston="none")
    tol = 2.0 if refine == "phase" else 15.0
    assert m["rms_nm"] < tol, m
    meas_step = np.mean(res.height[x > 0.005]) - np.mean(res.height[x < -0.005])
    assert abs(meas_step - step_mm) * 1e6 < tol


def test_csi_pixels_without_peak_are_invalid():
    x, y = _grid(16)
    h = np.zeros_like(x)
    h[:4] = 0.05  # far outside the scan range
    z = np.arange(-0.002, 0.002, 80e-6)
    res = retrieve_csi(_csi_stack(h, z), z, wavelength_nm=LAM_NM)
    assert not res.valid[:4].any()
    assert res.valid[4:].all()


def test_height_error_piston_and_units():
    t = np.zeros((8, 8))
    m = t + 1e-4  # 100 nm piston: removed
    m[0, 0] += 2e-6
    aligned, e = height_error(m, t)
    assert abs(e["piston_nm"] - 100.03125) < 1e-6
    assert e["pv_nm"] == pytest.approx(2.0, abs=1e-6)
    _, e2 = height_error(m, t, piston="none")
    assert e2["rms_nm"] > 99


def test_height_from_phase():
    assert height_from_phase(4 * np.pi, wavelength_nm=500) == pytest.approx(500e-6)


@pytest.mark.parametrize("call,match", [
    (lambda: retrieve_psi(np.zeros((4, 5)), wavelength_nm=633), "frames must be an"),
    (lambda: retrieve_psi(np.zeros((2, 5, 5)), wavelength_nm=633), "at least 3"),
    (lambda: retrieve_psi(np.zeros((4, 5, 5)), wavelength_nm=50), "wavelength_nm must be in"),
    (lambda: wrapped_phase(np.zeros((4, 5, 5)), algorithm="7step"), "algorithm must be one of"),
    (lambda: wrapped_phase(np.zeros((4, 5, 5)), algorithm="5step"), "needs N = 5"),
    (lambda: wrapped_phase(np.zeros((4, 5, 5)), steps_rad=[0, 1, 2, 3], algorithm="4step"),
     "equal steps"),
    (lambda: wrapped_phase(np.zeros((4, 5, 5)), steps_rad=[0, 1]), "one phase shift per frame"),
    (lambda: retrieve_psi(np.zeros((4, 5, 5)), wavelength_nm=633, valid=np.ones((3, 3))),
     "valid must have"),
    (lambda: retrieve_csi(np.zeros((6, 5, 5)), [0, 1, 2, 4, 5, 6], wavelength_nm=633),
     "equally spaced"),
    (lambda: retrieve_csi(np.zeros((6, 5, 5)), np.arange(6.0), wavelength_nm=633, refine="x"),
     "refine must be"),
    (lambda: height_error(np.zeros((3, 3)), np.zeros((4, 4))), "one shape"),
    (lambda: retrieve_psi(np.ones((4, 5, 5)), wavelength_nm=633, quality="best"),
     "quality must be"),
])
def test_bad_input(call, match):
    with pytest.raises(InputError, match=match):
        call()
