"""Burrs on sharp edges: edge detection, ridge shape, seeded variation."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.machining._burrs import apply_burrs, burr_map, sharp_edges
from render_inspect.scene import ArtifactsConfig

PIX = 0.001


def _roof(n=201, slope=0.1):
    """A roof z = -slope |x| (a sharp ridge on x = 0) on a grid from -0.1 to 0.1 mm."""
    x = -0.1 + PIX * np.arange(n)
    return x, np.broadcast_to(-slope * np.abs(x)[None, :], (n, n)).copy()


def test_sharp_edges_finds_the_ridge_only():
    x, z = _roof()
    edges = sharp_edges(z, pixel=PIX)
    cols = np.flatnonzero(edges.any(axis=0))
    assert_allclose(x[cols], [0.0], atol=1e-12)
    assert edges[1:-1, cols[0]].all()
    # a smooth sphere (radius 1 mm: 0.06 deg turn per pixel) has no sharp edge
    X, Y = np.meshgrid(x, x)
    sphere = (X ** 2 + Y ** 2) / (1 + np.sqrt(1 - X ** 2 - Y ** 2))
    assert not sharp_edges(sphere, pixel=PIX).any()


def test_ridge_shape_without_variation():
    x, z = _roof()
    h, w = 0.0002, 0.02
    b = burr_map(z, pixel=PIX, origin=(-0.1, -0.1), height=h, width=w, variation=0.0)
    expected = np.where(np.abs(x) < w / 2, h * np.cos(np.pi * x / w) ** 2, 0.0)
    assert_allclose(b[100], expected, atol=1e-15)
    assert b.min() >= 0.0 and b.max() == pytest.approx(h)


def test_seeded_variation_is_reproducible_and_grid_independent():
    x, z = _roof()
    kw = dict(height=0.0002, width=0.01, variation=0.3)
    a = burr_map(z, pixel=PIX, origin=(-0.1, -0.1), seed=5, **kw)
    b = burr_map(z, pixel=PIX, origin=(-0.1, -0.1), seed=5, **kw)
    c = burr_map(z, pixel=PIX, origin=(-0.1, -0.1), seed=6, **kw)
    assert_allclose(a, b, rtol=0, atol=0)
    assert np.abs(a - c).max() > 1e-6
    # the crest varies along the edge by about the relative variation
    crest = a[:, 100] / 0.0002
    assert 0.1 < crest.std() < 0.5 and crest.mean() == pytest.approx(1.0, abs=0.25)
    # the same edge point gets the same burr on a shifted grid (the field lives in mm)
    z2 = z[50:, 40:]
    d = burr_map(z2, pixel=PIX, origin=(-0.1 + 40 * PIX, -0.1 + 50 * PIX), seed=5, **kw)
    assert_allclose(d[:, 60], a[50:, 100], atol=1e-15)


def test_no_burrs_when_height_or_width_is_zero():
    _, z = _roof()
    assert not burr_map(z, pixel=PIX, height=0.0, width=0.01).any()
    assert not burr_map(z, pixel=PIX, height=0.001, width=0.0).any()


def test_apply_burrs_records_the_seed_and_adds_material():
    _, z = _roof()
    cfg = ArtifactsConfig(burrs={"height": 0.0001, "width": 0.008}).burrs
    m, info = apply_burrs(z, z, pixel=PIX, origin=(-0.1, -0.1), height=cfg.height, width=cfg.width,
                          variation=cfg.variation, edge_angle_deg=cfg.edge_angle_deg,
                          correlation_length=cfg.correlation_length, seed=42)
    assert info["seed"] == 42 and info["edge_pixels"] == 201   # the ridge column
    assert (m - z).min() >= 0 and info["max_added_um"] == pytest.approx((m - z).max() * 1e3)


@pytest.mark.parametrize("kw, word", [({"height": -1e-4}, "burrs.height"),
                                      ({"width": 2.0}, "burrs.width"),
                                      ({"variation": 1.5}, "burrs.variation")])
def test_bad_burr_values_are_named(kw, word):
    _, z = _roof(21)
    args = {"height": 1e-4, "width": 0.01, **kw}
    with pytest.raises(InputError, match=word):
        burr_map(z, pixel=PIX, **args)


def test_sharp_edges_checks_its_input():
    with pytest.raises(InputError, match="edge_angle_deg"):
        sharp_edges(np.zeros((5, 5)), pixel=PIX, edge_angle_deg=95)
    with pytest.raises(InputError, match="2-D"):
        sharp_edges(np.zeros(5), pixel=PIX)
