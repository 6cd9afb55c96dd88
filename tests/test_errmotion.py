"""Error motions: the analytic print of a once-per-revolution radial error, and the
injected spindle harmonics and vibration in the spectrum of the machined surface."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy import ndimage

from render_inspect.errors import InputError
from render_inspect.machining import simulate_turning
from render_inspect.machining import Machine, follow_turning
from render_inspect.machining._errmotion import ErrorMotions, error_motion_offsets
from render_inspect.toolpath import ToolPath


def _face_path(F, *, r0, f, P, rpm):
    """Uncompensated spiral program z = F(rho) (a large nose on a gentle surface)."""
    n = int(round(r0 / f * P))
    k = np.arange(n + 1)
    th = k * 2 * np.pi / P
    rho = r0 - f * k / P
    return th / (2 * np.pi * rpm / 60.0), th, rho, F(rho)


def _cut(t, th, rho, z, machine, region, pixel, nose=2.0):
    fp = follow_turning(t, th, rho, z, machine, seed=5)
    path = ToolPath(fp.theta, fp.rho, fp.z, fp.t)
    return simulate_turning(path, nose_radius=nose, region=region, pixel=pixel)


def test_once_per_revolution_radial_error_prints_F_of_r_minus_a_cos_phi():
    """Tool at X + a cos(C): the program's height for radius rho lands on rho + a cos(phi),
    so the machined surface is F(r - a cos(phi)) (here a convex sphere of radius 50 mm: a
    tilt a / R x to first order).  The program is the exact Z-compensated path of the
    sphere (nose centres on the offset sphere); its feed scallops are < 0.01 nm (nose
    2 mm, 0.5 um/rev)."""
    Rs, Rn, a = 50.0, 2.0, 0.0005

    def F(r):
        return np.sqrt(Rs * Rs - r * r) - Rs

    t, th, rho, z = _face_path(lambda r: np.sqrt((Rs + Rn) ** 2 - r * r) - Rs - Rn,
                               r0=1.3, f=0.0005, P=720, rpm=600.0)
    region, pixel = (-1.0, -1.0, 1.0, 1.0), 0.02
    ideal = _cut(t, th, rho, z, Machine(), region, pixel, nose=Rn)
    m = Machine(servo_rate_hz=7200.0, interpolation="linear",
                errors=ErrorMotions(radial_sync=((1, a, 0.0),)))
    machined = _cut(t, th, rho, z, m, region, pixel, nose=Rn)
    x = region[0] + pixel * np.arange(machined.shape[1])
    xx, yy = np.meshgrid(x, x)
    r, phi = np.hypot(xx, yy), np.arctan2(yy, xx)
    inside = r < 1.0                       # the spiral starts at 1.3 mm: corners left out
    # the geometric part: the ideal cut is the sphere within its scallops (0.02 nm)
    assert_allclose(ideal[inside], F(r)[inside], atol=3e-8)
    # the error motion's print: F(r - a cos(phi)), within 0.05 nm (of up to 10 nm)
    assert_allclose(machined[inside], F(r - a * np.cos(phi))[inside], atol=5e-8)
    # and it is the tilt (a / R) x, 10 nm per mm here
    tilt = np.polyfit(x, (machined - ideal)[machined.shape[0] // 2], 1)[0]
    assert_allclose(tilt, a / Rs, rtol=0.01)


def _circle(machined, region, pixel, radius, n=4096):
    phi = 2 * np.pi * np.arange(n) / n
    cols = (radius * np.cos(phi) - region[0]) / pixel
    rows = (radius * np.sin(phi) - region[1]) / pixel
    return ndimage.map_coordinates(machined, [rows, cols], order=3)


def test_surface_spectrum_shows_spindle_harmonics_and_vibration():
    """Axial synchronous error at 3 and 7 per revolution (spokes) and a 115 Hz tool-part
    vibration along Z at 300 rpm (23 per revolution) on a flat face: the circular profile's
    spectrum peaks exactly there, with the injected amplitudes."""
    rpm = 300.0
    amps = {3: 4e-6, 7: 2.5e-6}
    vib_amp = 3e-6
    errors = ErrorMotions(axial_sync=tuple((n, a, 0.4 * n) for n, a in amps.items()),
                          vibration=((115.0, vib_amp, "z", 0.2),))
    t, th, rho, z = _face_path(lambda r: 0.0 * r, r0=1.2, f=0.002, P=720, rpm=rpm)
    region, pixel = (-1.05, -1.05, 1.05, 1.05), 0.005
    m = Machine(servo_rate_hz=3600.0, interpolation="linear", errors=errors)
    machined = _cut(t, th, rho, z, m, region, pixel, nose=1.0)
    prof = _circle(machined, region, pixel, 0.9)
    spec = np.abs(np.fft.rfft(prof - prof.mean())) * 2 / prof.size
    peaks = set(np.argsort(spec[1:200])[-3:] + 1)
    assert peaks == {3, 7, 23}
    assert_allclose(spec[3], amps[3], rtol=0.05)
    assert_allclose(spec[7], amps[7], rtol=0.05)
    # the vibration drifts in phase from revolution to revolution (115 Hz is not a
    # multiple of 5 Hz... it is: 23 x 5 Hz), so it prints at full amplitude too
    assert_allclose(spec[23], vib_amp, rtol=0.1)


def test_asynchronous_error_and_straightness_are_seeded_and_sized():
    t = np.arange(0, 2.0, 1e-4)
    th = 2 * np.pi * 10 * t
    rho = 3.0 - 0.001 * t
    e = ErrorMotions(radial_async_rms=3e-6, axial_async_rms=2e-6, async_bandwidth_hz=100.0,
                     x_straightness_rms=5e-5, x_straightness_length=2.0)
    a = error_motion_offsets(t, th, rho, e, seed=1)
    b = error_motion_offsets(t, th, rho, e, seed=1)
    c = error_motion_offsets(t, th, rho, e, seed=2)
    assert_allclose(a["x"], b["x"], atol=0)
    assert not np.allclose(a["x"], c["x"])
    assert_allclose(np.std(a["x"]), 3e-6, rtol=0.1)
    # straightness depends on X only: the same X gives the same Z deviation
    e2 = ErrorMotions(x_straightness_rms=5e-5, x_straightness_length=2.0)
    s1 = error_motion_offsets(t, th, rho, e2, seed=1)["z"]
    s2 = error_motion_offsets(t[::-1], th, rho[::-1], e2, seed=1)["z"]
    assert_allclose(s1, s2[::-1], atol=1e-15)


def test_error_motion_input_is_checked():
    with pytest.raises(InputError, match="harmonic must be an integer >= 1"):
        ErrorMotions(radial_sync=((0, 1e-6),))
    with pytest.raises(InputError, match="vibration direction"):
        ErrorMotions(vibration=((100.0, 1e-6, "w"),))
    with pytest.raises(InputError, match="unknown machine.errors setting"):
        ErrorMotions().with_overrides({"radial": 1})
    assert ErrorMotions().none and not ErrorMotions(axial_async_rms=1e-6).none


def test_error_motions_move_the_tool_by_hypot_and_atan2_to_the_bit():
    """The tool's radius and angle after the error motions are hypot(X + e_x, e_y) and
    C + atan2(e_y, X + e_x) (non-decreasing) bit for bit, with and without a displacement
    along Y, on a path whose X crosses the spindle axis (negative radii, -0)."""
    from render_inspect.machining._errmotion import apply_error_motions

    t = np.arange(4000) / 5000.0
    theta = 2 * np.pi * 20 * t
    rho = np.linspace(0.002, -0.002, t.size)
    rho[1000] = -0.0
    z = 1e-3 * np.sin(theta)
    base = dict(radial_sync=((2, 5e-6, 0.3),), radial_async_rms=1e-6, axial_sync=((3, 2e-6, 2.0),),
                x_straightness_rms=5e-5, vibration=((40.0, 1e-6, "z"),))
    for vib in ((), ((130.0, 2e-6, "y", 0.2),)):
        errors = ErrorMotions(**{**base, "vibration": base["vibration"] + vib})
        for mask in (None, np.arange(t.size) % 3 != 0):
            th2, rho2, z2 = apply_error_motions(t, theta, rho, z, errors, seed=4, mask=mask)
            off = error_motion_offsets(t, theta, rho, errors, seed=4, mask=mask)
            xr = rho + off["x"]
            assert (np.any(off["y"] != 0)) == bool(vib)
            assert np.any(np.signbit(xr)) and np.any(~np.signbit(xr))
            assert np.array_equal(rho2.view(np.uint64), np.hypot(xr, off["y"]).view(np.uint64))
            ref = np.maximum.accumulate(theta + np.arctan2(off["y"], xr))
            assert np.array_equal(th2.view(np.uint64), ref.view(np.uint64))
            assert np.array_equal(z2, z + off["z"])
