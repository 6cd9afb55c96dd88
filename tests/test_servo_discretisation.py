"""The servo loop's exact discretisation (the matrix exponential of the augmented loop
matrix) and the noise scale from the discrete Lyapunov equation: against the same sums
carried out in 60-digit decimal arithmetic, against the closed form of a damped oscillator,
and against SciPy's ``expm`` and ``solve_discrete_lyapunov`` on the shipped machines."""

from __future__ import annotations

import math
from decimal import Decimal, localcontext

import numpy as np
import pytest

from render_inspect.core.errors import InputError
from render_inspect.machining._axes import _discrete_loop, _expm, _noise_scale
from render_inspect.machining._machines import MACHINE_PRESETS


def _mul(a, b):
    n = len(a)
    return [[sum(a[i][k] * b[k][j] for k in range(n)) for j in range(n)] for i in range(n)]


def _decimal_loop(wn: float, zeta: float, dt: float):
    """Phi, Gamma and the Lyapunov sum's P[0, 0] (unit noise) of the loop, in 60-digit
    decimals: the augmented matrix's exponential by its Taylor series after halving it to a
    norm below 0.01 (60 terms), squared back; P by doubling until the added terms fall
    below 1e-40 of P."""
    with localcontext() as ctx:
        ctx.prec = 60
        m = [[Decimal(0), Decimal(dt), Decimal(0)],
             [Decimal(-wn * wn * dt), Decimal(-2.0 * zeta * wn * dt), Decimal(dt)],
             [Decimal(0)] * 3]
        # (the entries are those of the float64 matrix the package builds, exactly)
        m[1][0] = -Decimal(wn) * Decimal(wn) * Decimal(dt)
        m[1][1] = -2 * Decimal(zeta) * Decimal(wn) * Decimal(dt)
        s = 0
        norm = max(sum(abs(m[i][j]) for i in range(3)) for j in range(3))
        while norm > Decimal("0.01"):
            norm /= 2
            s += 1
        a = [[x / 2 ** s for x in row] for row in m]
        out = [[Decimal(int(i == j)) for j in range(3)] for i in range(3)]
        term = [row[:] for row in out]
        for k in range(1, 60):
            term = [[x / k for x in row] for row in _mul(term, a)]
            out = [[out[i][j] + term[i][j] for j in range(3)] for i in range(3)]
        for _ in range(s):
            out = _mul(out, out)
        phi = [[out[0][0], out[0][1]], [out[1][0], out[1][1]]]
        g = [out[0][2], out[1][2]]
        p = [[g[i] * g[j] for j in range(2)] for i in range(2)]
        a = phi
        for _ in range(200):
            at = [[a[j][i] for j in range(2)] for i in range(2)]
            add = _mul(_mul(a, p), at)
            p = [[p[i][j] + add[i][j] for j in range(2)] for i in range(2)]
            a = _mul(a, a)
            if max(abs(x) for row in add for x in row) < abs(p[0][0]) * Decimal("1e-40"):
                break
        return (np.array([[float(x) for x in row] for row in phi]), np.array([float(x) for x in g]),
                float(p[0][0]))


#: (bandwidth Hz, damping, servo rate Hz): the shipped machines' loops, slow and fast
#: loops at slow and fast servo rates, light, critical and heavy damping
_LOOPS = [(60.0, 0.7, 5000.0), (40.0, 0.7, 5000.0), (100.0, 0.7, 20000.0), (2000.0, 0.6, 20000.0),
          (0.5, 0.05, 1e6), (5.0, 1.0, 1e6), (120.0, 10.0, 1000.0), (500.0, 0.05, 1000.0),
          (2000.0, 1.0, 1000.0), (2000.0, 10.0, 5000.0)]


@pytest.mark.parametrize("fn,zeta,rate", _LOOPS)
def test_the_discrete_loop_is_the_exponential_to_rounding(fn, zeta, rate):
    wn, dt = 2 * math.pi * fn, 1.0 / rate
    phi, gam = _discrete_loop(wn, zeta, dt)
    phi_ref, gam_ref, p_ref = _decimal_loop(wn, zeta, dt)
    np.testing.assert_allclose(phi, phi_ref, rtol=1e-12, atol=1e-13 * np.abs(phi_ref).max())
    # (a loop decayed over the tick, e^(-zeta wn dt) ~ 1e-6, has a few more roundings in
    # its small entries, as SciPy's Pade approximant has)
    np.testing.assert_allclose(gam, gam_ref, rtol=1e-11, atol=0)
    # the noise scale: sqrt of P[0, 0], the sum of about 1 / (zeta wn dt) terms: its
    # condition grows as the pole nears 1
    cond = max(1.0, 1.0 / (zeta * wn * dt))
    assert _noise_scale(phi, gam, 1.0) == pytest.approx(1.0 / math.sqrt(p_ref), rel=1e-13 * cond)


def test_the_discrete_loop_is_the_damped_oscillators_closed_form():
    """Underdamped: exp(A t) = e^(-sigma t) [[c + sigma s, s], [-wn^2 s, c - sigma s]],
    s = sin(wd t) / wd, c = cos(wd t); the input column is the integral of the second
    column, whose first entry is (1 - Phi_00) / wn^2 and the second Phi_01."""
    wn, zeta, dt = 2 * math.pi * 300.0, 0.3, 1.0 / 2000.0   # wn dt about 0.94: no cancellation
    sigma, wd = zeta * wn, wn * math.sqrt(1 - zeta * zeta)
    e, c, s = math.exp(-sigma * dt), math.cos(wd * dt), math.sin(wd * dt) / wd
    phi, gam = _discrete_loop(wn, zeta, dt)
    expect = e * np.array([[c + sigma * s, s], [-wn * wn * s, c - sigma * s]])
    np.testing.assert_allclose(phi, expect, rtol=1e-13, atol=1e-15 * np.abs(expect).max())
    np.testing.assert_allclose(gam, [(1 - expect[0, 0]) / wn ** 2, expect[0, 1]], rtol=1e-12)


def test_the_exponential_of_small_matrices():
    """exp(0) = I; a rotation generator gives the rotation; a nilpotent matrix's series
    ends; a diagonal one gives the exponentials of its entries."""
    np.testing.assert_array_equal(_expm(np.zeros((3, 3))), np.eye(3))
    t = 2.5
    rot = _expm(np.array([[0.0, -t], [t, 0.0]]))
    np.testing.assert_allclose(rot, [[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]],
                               rtol=0, atol=2e-15)
    nil = _expm(np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(nil, [[1.0, 1.0, 0.5], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]], rtol=1e-15)
    d = np.diag([-30.0, 0.25, 4.0])
    np.testing.assert_allclose(np.diag(_expm(d)), np.exp(np.diag(d)), rtol=1e-13)


def test_the_shipped_machines_loops_are_scipys_to_a_few_units_in_the_last_place():
    from scipy import linalg  # (a dependency of the package; only the test imports it here)

    n = 0
    for machine in MACHINE_PRESETS.values():
        for name in ("c", "x", "z", "fts"):
            axis = getattr(machine, name, None)
            if axis is None or axis.bandwidth_hz is None:
                continue
            wn, zeta, dt = 2 * math.pi * axis.bandwidth_hz, axis.damping, 1.0 / machine.servo_rate_hz
            m = np.zeros((3, 3))
            m[:2, :2] = np.array([[0.0, 1.0], [-wn * wn, -2.0 * zeta * wn]]) * dt
            m[1, 2] = dt
            em = linalg.expm(m)
            phi, gam = _discrete_loop(wn, zeta, dt)
            np.testing.assert_array_less(np.abs(phi - em[:2, :2]), 8 * np.spacing(np.abs(em[:2, :2])) + 1e-300)
            np.testing.assert_array_less(np.abs(gam - em[:2, 2]), 8 * np.spacing(np.abs(em[:2, 2])))
            p = linalg.solve_discrete_lyapunov(em[:2, :2], np.outer(em[:2, 2], em[:2, 2]))
            assert _noise_scale(phi, gam, 1.0) == pytest.approx(1.0 / math.sqrt(p[0, 0]), rel=1e-13)
            n += 1
    assert n >= 5


def test_a_loop_that_never_settles_is_refused_with_its_pole():
    """A loop whose pole is 1 to double precision (bandwidth x damping / rate ~ 1e-28) has no
    steady-state noise to scale: one clear error, not an infinite or zero scale."""
    phi, gam = _discrete_loop(2 * math.pi * 1e-12, 1e-9, 1e-7)
    with pytest.raises(InputError, match=r"bandwidth_hz x damping / servo_rate_hz .* received 0"):
        _noise_scale(phi, gam, 1e-6)
