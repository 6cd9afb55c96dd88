"""The burr model on a window of a block (the tile of a halo'd block): the edges, turns,
heights and ridges of the window's pixels equal those of the whole block there, bit for
bit (edges are thresholded: a last-bit change could move one)."""

import numpy as np
import pytest

from render_inspect.machining import edge_turns, material_burr_block, plan_tiles
from render_inspect.machining._burr_kernels import edge_turn_window

PIX = 0.001


def _facets(seed=0):
    """Facets meeting on sharp edges, a feed-mark ripple, noise and NaN holes, 150 x 170."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:150, 0:170] * PIX
    z = (0.02 * np.abs(x - 0.08) + 0.015 * np.abs(y - 0.07) + 0.03 * np.maximum(0, x - 0.13)
         + 1e-6 * np.sin(x / 0.01) + 1e-8 * rng.normal(size=x.shape))
    z[100:140, 10:40] = np.nan
    z[60:63, 150:] = np.nan
    return z


#: windows (first row, end row, first column, end column): inside, on each border, the
#: whole map, one pixel, empty
WINDOWS = [(40, 90, 50, 120), (0, 30, 0, 170), (120, 150, 100, 170), (0, 150, 0, 170),
           (75, 76, 81, 82), (10, 10, 0, 5), (30, 140, 0, 12)]


@pytest.mark.parametrize("window", WINDOWS)
def test_edge_turn_window_equals_the_whole_map_on_the_window(window):
    z = _facets()
    r0, r1, c0, c1 = window
    found = 0
    for span in (1, 2, 5):
        for angle in (0.05, 1.0):
            edges, turn = edge_turns(z, pixel=PIX, edge_angle_deg=angle, span=span)
            e, t = edge_turn_window(z, window, pixel=PIX, edge_angle_deg=angle, span=span)
            assert np.array_equal(e, edges[r0:r1, c0:c1])
            assert np.array_equal(t, turn[r0:r1, c0:c1])
            found += int(e.sum())
    if window == WINDOWS[0]:
        assert found > 0                   # the window has edges to find


def test_material_burrs_on_the_inner_pixels_equal_the_block():
    """The maps of a block's inner pixels (``inner``) are those of the whole block there:
    tiles of the map with a halo, each against the block's maps cropped to the tile."""
    z = _facets(1)
    ny, nx = z.shape
    kw = dict(pixel=PIX, origin=(-0.3, 0.2), chip_thickness=0.002, coefficient=1.0, variation=0.3,
              seed=3, edge_angle_deg=1.0, smoothing=0.004, width=0.006)
    burrs = 0
    for t in plan_tiles(z.shape, 64):
        h = 40
        r0, c0 = max(t.row - h, 0), max(t.col - h, 0)
        r1, c1 = min(t.row + t.rows + h, ny), min(t.col + t.cols + h, nx)
        block = z[r0:r1, c0:c1]
        side = dict(border=(r0 == 0, r1 == ny, c0 == 0, c1 == nx), start=(r0, c0), **kw)
        whole = material_burr_block(block, **side)
        inner = (t.row - r0, t.row - r0 + t.rows, t.col - c0, t.col - c0 + t.cols)
        got = material_burr_block(block, inner=inner, **side)
        at = (slice(inner[0], inner[1]), slice(inner[2], inner[3]))
        if got is None:
            # no edge within the ridge's reach of the tile: the block adds nothing there
            assert whole is None or (not whole[1][at].any() and not whole[0][at].any())
            continue
        for a, b in zip(got, whole):
            assert np.array_equal(a, b[at], equal_nan=True), t
        burrs += int(got[1].sum())
    assert burrs > 50


@pytest.mark.parametrize("window", WINDOWS)
@pytest.mark.parametrize("sigma", [0.7, 6.5])
def test_the_smoothing_on_the_cross_equals_the_whole_map_there(window, sigma):
    from render_inspect.machining._burr_kernels import gaussian_nearest, gaussian_nearest_cross

    z = np.nan_to_num(_facets(2), nan=0.01)
    reach = 9
    whole = gaussian_nearest(z, sigma)
    got = gaussian_nearest_cross(z, sigma, window, reach)
    ny, nx = z.shape
    r0, r1, c0, c1 = window
    if r1 <= r0 or c1 <= c0:
        return                             # an empty window reads nothing
    rows = slice(max(r0 - reach, 0), min(r1 + reach, ny))
    cols = slice(max(c0 - reach, 0), min(c1 + reach, nx))
    assert np.array_equal(got[rows, c0:c1], whole[rows, c0:c1])
    assert np.array_equal(got[r0:r1, cols], whole[r0:r1, cols])


def test_burr_ridges_on_the_edges_box_equal_the_whole_map():
    """The ridges are laid from the nearest edges found on the edges' bounding box: the
    same numbers as with the distance transform of the whole map (its definition)."""
    from scipy import ndimage

    from render_inspect.machining import burr_map

    rng = np.random.default_rng(7)
    for trial in range(12):
        ny, nx = (int(v) for v in rng.integers(20, 120, size=2))
        edges = np.zeros((ny, nx), dtype=bool)
        k = int(rng.integers(1, 40))
        r = rng.integers(int(ny * 0.2), int(ny * 0.8) + 1, size=k)
        c = rng.integers(0, nx, size=k) if trial % 3 else np.full(k, nx // 2)
        edges[r, c] = True
        edges[r[0], :] = trial % 4 == 0          # a whole line of edges: ties to break
        heights = np.where(edges, rng.uniform(1e-4, 2e-4, size=(ny, nx)), 0.0)
        pixel, width, start, origin = 0.001, 0.0073, (3, 5), (-0.2, 0.1)
        got = burr_map(np.zeros((ny, nx)), pixel=pixel, origin=origin, height=heights, width=width,
                       variation=0.3, seed=trial, edges=edges, start=start)
        # the definition: the transform of the whole map
        dist, (iy, ix) = ndimage.distance_transform_edt(~edges, return_indices=True)
        d = dist * pixel
        near = d < width / 2
        ref = np.zeros((ny, nx))
        from render_inspect.machining._burrs import _random_field
        ex = origin[0] + pixel * (ix[near] + start[1])
        ey = origin[1] + pixel * (iy[near] + start[0])
        v = np.maximum(1.0 + 0.3 * _random_field(ex, ey, correlation_length=4 * width, seed=trial), 0.0)
        ref[near] = heights[iy[near], ix[near]] * v * np.cos(np.pi * d[near] / width) ** 2
        assert got.tobytes() == ref.tobytes(), trial
