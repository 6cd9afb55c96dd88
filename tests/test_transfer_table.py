"""The tabulated transfer function H(Q, K) is built with reused buffers; it must equal, bit
for bit, the plain array expression it replaces (the pupil's unit table interpolated
along u for each wavelength, deposited on the axial bins and summed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.instruments import led, monochromatic
from render_inspect.instruments._transfer import (
    _N_Q,
    flat_moments,
    transfer_function,
    unit_transfer_table,
)


def _table_by_array_expressions(na, na_ill, obs, source, dK):
    u, kappa, G = unit_transfer_table(float(na), float(na_ill), float(obs))
    k, w = source.sample(dk=dK / 4)
    K_lo = float(k.min() * kappa[0])
    nb = math.ceil((float(k.max() * kappa[-1]) - K_lo) / dK) + 2
    q = float(k.max() * (na + na_ill)) / (_N_Q - 1) * np.arange(_N_Q)
    du = u[1] - u[0]
    table = np.zeros((nb, _N_Q))
    cols = np.arange(kappa.size)
    for kj, wj in zip(k, w):
        pos_u = q / kj / du
        i0 = np.floor(pos_u).astype(np.int64)
        inside = i0 < u.size - 1
        f = (pos_u - i0)[inside]
        gu = np.zeros((_N_Q, kappa.size))
        gu[inside] = G[i0[inside]] * (1 - f)[:, None] + G[i0[inside] + 1] * f[:, None]
        pos_k = (kj * kappa - K_lo) / dK
        b0 = np.clip(np.floor(pos_k).astype(np.int64), 0, nb - 2)
        t = np.clip(pos_k - b0, 0.0, 1.0)
        dep = np.zeros((nb, kappa.size))
        np.add.at(dep, (b0, cols), 1 - t)
        np.add.at(dep, (b0 + 1, cols), t)
        table += wj * (dep @ gu.T)
    nz = table > 1e-12 * max(table.max(), 1e-300)
    table[~nz] = 0.0
    return table.astype(np.float32)


@pytest.mark.parametrize("na, na_ill, obs, source, dK", [
    (0.4, 0.4, 0.0, monochromatic(550.0, bandwidth_nm=10.0), 400.0),
    (0.55, 0.3, 0.3, monochromatic(633.0, bandwidth_nm=0.0), 300.0),
    (0.13, 0.0, 0.0, led(600.0, bandwidth_nm=120.0), 900.0),
])
def test_transfer_table_equals_the_array_expressions(na, na_ill, obs, source, dK):
    tf = transfer_function(na, na_ill, obs, source, dK=dK)
    expect = _table_by_array_expressions(na, na_ill, obs, source, dK)
    assert tf.table.shape == expect.shape
    np.testing.assert_array_equal(tf.table, expect)
    # the flat mirror's moments come from the same unit table
    k, w = source.sample(dk=dK / 4)
    assert (tf.k_eff, tf.sigma_k) == flat_moments(na, na_ill, obs, k, w)
