"""The lathe's filters give SciPy's numbers to the last bit: the second-order sections of
the Butterworth low-pass (the spindle's asynchronous error motion) and of the bilinear
second-order mode (the X drive's coupling into Z and Y), and the sections run over a
signal, over many random filters and signals."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import signal  # (a dependency of the package: the reference the filters match)

from render_inspect.machining import second_order_sos
from render_inspect.machining._iir import bilinear_sos, butter2_sos, sosfilt


def _bits(a) -> bytes:
    return np.ascontiguousarray(a, dtype=np.float64).tobytes()


def _scipy_second_order(fn: float, zeta: float, dt: float) -> np.ndarray:
    # the code second_order_sos ran on SciPy before
    fs = 1.0 / dt
    wn = 2 * math.pi * fn
    wa = 2 * fs * math.tan(min(wn / (2 * fs), 0.5 * math.pi * 0.999))
    z, p, k = signal.bilinear_zpk([], np.roots([1.0, 2 * zeta * wa, wa * wa]), wa * wa, fs)
    return signal.zpk2sos(z, p, np.real(k))


def test_butterworth_sections_are_scipys():
    rng = np.random.default_rng(1)
    cuts = np.concatenate([rng.uniform(1e-6, 0.99, 400), 10.0 ** rng.uniform(-7, 0, 200) * 0.99,
                           [0.99, 0.5, 1e-3, 0.02]])
    for wc in cuts:
        wc = float(wc)
        assert _bits(butter2_sos(wc)) == _bits(signal.butter(2, wc, output="sos")), wc


def test_second_order_mode_sections_are_scipys():
    rng = np.random.default_rng(2)
    cases = [(120.0, 0.05, 1 / 5000.0), (60.0, 0.7, 2e-4), (100.0, 1.0, 2e-4), (100.0, 10.0, 1e-4),
             (2400.0, 0.05, 2e-4), (1e5, 0.5, 1e-6)]
    for _ in range(600):
        fn = float(10.0 ** rng.uniform(-1, 5))
        zeta = float(rng.choice([rng.uniform(1e-3, 10.0), rng.uniform(0.95, 1.05),
                                 10.0 ** rng.uniform(-3, 1)]))
        dt = float(1.0 / 10.0 ** rng.uniform(2, 6))
        cases.append((fn, zeta, dt))
    for fn, zeta, dt in cases:
        assert _bits(second_order_sos(fn, zeta, dt)) == _bits(_scipy_second_order(fn, zeta, dt)), \
            (fn, zeta, dt)


def test_real_poles_pair_as_scipy_pairs_them():
    # an overdamped mode: two real poles (np.roots gives a real array)
    for poles in ([-3.0, -7.0], [-1e4, -2.5e2], [-5.0, -5.0]):
        z, p, k = signal.bilinear_zpk([], np.array(poles), 21.0, 1000.0)
        assert _bits(bilinear_sos(np.array(poles), 21.0, 1000.0)) == \
            _bits(signal.zpk2sos(z, p, np.real(k)))


def test_filtered_signals_are_scipys():
    rng = np.random.default_rng(3)
    for i in range(60):
        n = int(rng.integers(1, 20000))
        x = rng.normal(size=n) * 10.0 ** rng.uniform(-12, 6)
        if i % 4 == 0:
            sos = butter2_sos(float(rng.uniform(1e-4, 0.99)))
        elif i % 4 == 1:
            sos = second_order_sos(float(10.0 ** rng.uniform(0, 4)), float(rng.uniform(0.01, 3.0)),
                                   float(1.0 / 10.0 ** rng.uniform(3, 5)))
        elif i % 4 == 2:  # several sections, any coefficients with a0 = 1
            sos = rng.normal(size=(int(rng.integers(1, 5)), 6)) * 0.5
            sos[:, 3] = 1.0
            sos[:, 4:] = rng.uniform(-0.45, 0.45, size=(sos.shape[0], 2))  # (stable)
        else:  # a step, an impulse
            sos = butter2_sos(0.3)
            x = np.zeros(n)
            x[n // 3:] = 1.0
        assert _bits(sosfilt(sos, x)) == _bits(signal.sosfilt(sos, x)), i


def test_filter_leaves_its_input_and_takes_any_real_array():
    x = np.arange(10, dtype=np.float32)
    sos = butter2_sos(0.2)
    y = sosfilt(sos, x)
    assert y.dtype == np.float64 and x.tolist() == list(range(10))
    assert _bits(y) == _bits(signal.sosfilt(sos, x.astype(np.float64)))
    assert sosfilt(sos, np.zeros(0)).size == 0
    with pytest.raises(ValueError, match="sos"):
        sosfilt(np.ones((1, 6)) * 2, x)
