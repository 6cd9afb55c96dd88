"""Waviness filters chosen from the scene (ISO 16610-61), and their edge handling."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.errors import InputError
from render_inspect.metrology import (
    gaussian_filter,
    gaussian_transmission,
    s_filter,
    scallop_pv,
    waviness_filters,
)


def test_scallop_pv_is_the_cusp_height():
    assert scallop_pv(0.01, 0.514) == pytest.approx(0.01 ** 2 / (8 * 0.514), rel=1e-4)
    assert scallop_pv(0.1, 0.5) == pytest.approx(0.5 - math.sqrt(0.25 - 0.0025))


@pytest.mark.parametrize("f,rc", [(0.01, 0.514), (0.1, 0.5), (0.01, 0.025), (0.005, 0.1)])
def test_s_filter_leaves_half_a_nanometre_of_the_marks(f, rc):
    pv = scallop_pv(f, rc)
    r = waviness_filters(pixel=f / 10, window_mm=(1.0, 1.0), mark_period=f, mark_pv=pv)
    a1 = 4 * pv / math.pi ** 2 * 1e6
    left = a1 * float(gaussian_transmission(f, r["s_filter_mm"]))
    assert left == pytest.approx(min(0.5, a1), rel=1e-6)
    assert r["s_filter_mm"] >= f
    assert r["reasons"][0].startswith("S-filter")


def test_s_filter_removes_a_simulated_scallop_in_the_middle_of_the_map():
    """Forward model: a circular-arc scallop along x, filtered with the chosen nesting
    index, leaves < 1 nm (away from the cut border); a 0.5 mm waviness passes."""
    f, rc, px = 0.1, 0.5, 0.002
    x = np.arange(0, 2.0, px)
    u = (x % f) - f / 2
    scallop = rc - np.sqrt(rc * rc - u * u)
    wav = 40e-6 * np.cos(2 * np.pi * x / 0.5)
    z = np.broadcast_to(scallop + wav, (50, x.size)).copy()
    r = waviness_filters(pixel=px, window_mm=(2.0, 2.0), mark_period=f,
                         mark_pv=scallop_pv(f, rc), waviness=0.5)
    out = s_filter(z, pixel=px, nesting_index=r["s_filter_mm"], edges="mirror")
    mid = out[25, 300:700] - out[25, 300:700].mean()
    expect = wav[300:700] * float(gaussian_transmission(0.5, r["s_filter_mm"]))
    np.testing.assert_allclose(mid * 1e6, (expect - expect.mean()) * 1e6, atol=1.5)


def test_l_filter_and_edges():
    r = waviness_filters(pixel=0.0025, window_mm=(2.0, 2.0), mark_period=1.6e-5,
                         mark_pv=1.5e-3, waviness=0.2)
    assert r["s_filter_mm"] is None and "not resolved" in r["reasons"][0]
    assert r["l_filter_mm"] == pytest.approx(0.5)
    assert r["edges"] == "cut" and r["cut_mm"] == pytest.approx(0.25)
    # L-filter longer than the window: none, said so
    r = waviness_filters(pixel=0.002, window_mm=(1.2, 1.2), mark_period=0.1,
                         mark_pv=scallop_pv(0.1, 0.5), waviness=0.5)
    assert r["l_filter_mm"] is None and "longer than the window" in r["reasons"][1]
    # cutting would leave less than half of a small window: mirror instead
    r = waviness_filters(pixel=0.002, window_mm=(0.5, 0.5), mark_period=0.1,
                         mark_pv=scallop_pv(0.1, 0.5))
    assert r["edges"] == "mirror" and r["cut_mm"] == 0 and "mirrored" in r["reasons"][-1]
    # the user's values are used as given
    r = waviness_filters(pixel=0.002, window_mm=(2, 2), s_filter=0.05, l_filter=0.8)
    assert (r["s_filter_mm"], r["l_filter_mm"]) == (0.05, 0.8)
    with pytest.raises(InputError, match="filter_edges"):
        waviness_filters(pixel=0.002, window_mm=(2, 2), edges="normalised")


def test_edge_modes_of_the_gaussian_filter():
    px, lam = 0.01, 0.2
    x = np.arange(100) * px
    z = np.broadcast_to(0.3 * x, (40, 100)).copy()  # a plane: the mean line is itself
    cut = gaussian_filter(z, pixel=px, cutoff=lam, edges="cut")
    n = math.ceil(0.5 * lam / px)
    assert np.isnan(cut[:, :n]).all() and np.isnan(cut[:, -n:]).all()
    # what is left: the one-sided bias at the edge (normalised weights) is down to ~1 %
    edge = np.abs(gaussian_filter(z, pixel=px, cutoff=lam) - z)[:, 0].max()
    assert np.nanmax(np.abs(cut - z)) < 0.02 * edge
    mirror = gaussian_filter(z, pixel=px, cutoff=lam, edges="mirror")
    assert np.isfinite(mirror).all()
    # a mirrored plane bends at the border; beyond the kernel's reach (4 sigma) it is exact
    k = math.ceil(4 * 0.1874 * lam / px) + 1
    np.testing.assert_allclose(mirror[:, k:-k], z[:, k:-k], atol=1e-9)
    with pytest.raises(InputError, match="edges"):
        gaussian_filter(z, pixel=px, cutoff=lam, edges="wrap")
