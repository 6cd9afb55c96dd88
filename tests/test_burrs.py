"""Burrs on sharp edges: edge detection, ridge shape, seeded variation."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.core.units import MM_TO_UM
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


def _facets():
    """Facets meeting on sharp edges (a pyramid and a step in slope), a feed-mark ripple and
    NaN holes (pixels the path did not reach), on a 150 x 170 grid of 1 um."""
    y, x = np.mgrid[0:150, 0:170] * PIX
    z = (0.02 * np.abs(x - 0.08) + 0.015 * np.abs(y - 0.07) + 0.03 * np.maximum(0, x - 0.13)
         + 1e-6 * np.sin(x / 0.01))
    z[100:140, 10:40] = np.nan
    z[:20, 150:] = np.nan
    z[60:63, 60:120] = np.nan
    z[75:80, 85:90] = np.nan          # a hole on an edge
    return z


def test_material_burrs_of_blocks_with_their_halo_equal_the_whole_map():
    """Each tile's burrs from a block of the map with the halo of burr_halo (the wider one
    where the block has NaN pixels): the whole map's burrs on the tile, bit for bit, and
    the facts' sums and maxima over the tiles the whole map's facts."""
    from render_inspect.machining import burr_halo, material_burr_block, material_burrs, plan_tiles

    z = _facets()
    ny, nx = z.shape
    kw = dict(pixel=PIX, origin=(-0.3, 0.2), chip_thickness=0.002, coefficient=1.0, variation=0.3,
              seed=3, edge_angle_deg=1.0, smoothing=0.004)
    w = 3 * kw["chip_thickness"]
    whole, info = material_burrs(z, z, **kw)
    assert info["edge_pixels"] > 100 and info["max_added_um"] > 0
    edges, turn, height, added = 0, 0.0, 0.0, 0.0
    for t in plan_tiles(z.shape, 64):
        for nan in (False, True):
            h = burr_halo(PIX, kw["smoothing"], w, nan=nan)
            r0, c0 = max(t.row - h, 0), max(t.col - h, 0)
            r1, c1 = min(t.row + t.rows + h, ny), min(t.col + t.cols + h, nx)
            if nan or np.isfinite(z[r0:r1, c0:c1]).all():
                break
        r = material_burr_block(z[r0:r1, c0:c1], width=w, border=(r0 == 0, r1 == ny, c0 == 0, c1 == nx),
                                start=(r0, c0), **kw)
        at = (slice(t.row - r0, t.row - r0 + t.rows), slice(t.col - c0, t.col - c0 + t.cols))
        got = z[t.row:t.row + t.rows, t.col:t.col + t.cols].copy()
        if r is not None:
            b, e, tn, hb = (a[at] for a in r)
            got += b
            edges += int(e.sum())
            turn = max(turn, float(tn[e].max()) if e.any() else 0.0)
            height, added = max(height, float(hb.max())), max(added, float(np.nanmax(b)))
        assert np.array_equal(got, whole[t.row:t.row + t.rows, t.col:t.col + t.cols], equal_nan=True), t
    assert edges == info["edge_pixels"]
    assert np.degrees(turn) == info["turn_max_deg"]
    assert height * MM_TO_UM == info["height_max_um"] and added * MM_TO_UM == info["max_added_um"]


def test_burr_halo_adds_up_the_reach_of_each_step():
    from render_inspect.machining import burr_halo

    # 1 um pixel, 10 um smoothing (sigma 10 px: Gaussian reach int(40.5) = 40, span 31),
    # 9 um wide burrs (ceil(4.5) = 5): 5 + 3 * 31 + 1 + 40
    assert burr_halo(0.001, 0.01, 0.009) == 5 + 94 + 40
    # NaN pixels: + floor(hypot(134, 40)) + 1
    assert burr_halo(0.001, 0.01, 0.009, nan=True) == 139 + 139 + 1
    assert burr_halo(0.001, 0.0, 0.0) == 0 + 3 * 2 + 1 + 0
