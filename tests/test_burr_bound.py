"""The proof that a window of a block has no burr edge (machining/_burr_bound.py): where it
says so, the edge search on the smoothed block finds no candidate pixel at all; the burr
model with it gives the same maps as without it."""

import math

import numpy as np
import pytest

from render_inspect.machining import material_burr_block
from render_inspect.machining._burr_bound import no_edge_possible
from render_inspect.machining._burr_kernels import (_BOUND_ABS, _bound_limit, _candidates0, _candidates1,
                                                    gaussian_nearest, gaussian_weights)

PIX = 0.001
SMOOTH = 0.004                      # 4-pixel sigma: taps reach 16 pixels
SPAN = max(2, int(math.ceil(3 * SMOOTH / PIX)) + 1)
WINDOW = (60, 140, 64, 170)         # far enough from the block's ends (2 span + 16 = 42)
SHAPE = (200, 230)


def _part(kink=0.0, seed=0, ripple=2e-9, dimple=0.0):
    """A smooth design (sag and a slow wave), feed marks, noise and a kink of slope
    ``kink`` along a column of the window (an edge turning by about that, rad): the map,
    the design and the form with the kink."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:SHAPE[0], 0:SHAPE[1]] * PIX
    design = 0.01 * (x ** 2 + y ** 2) + 2e-3 * np.sin(x / 0.4) * np.cos(y / 0.5)
    r = np.hypot(x + 0.3, y + 0.2)
    z = design + ripple * np.cos(2 * np.pi * r / 0.01) + 2e-9 * rng.normal(size=x.shape)
    ramp = kink * np.maximum(0.0, x - 0.1171)
    # a dimple of 2.5 pixels between the sampled columns and rows
    ramp = ramp - dimple * np.exp(-((x - 0.1175) ** 2 + (y - 0.1035) ** 2) / (2 * 0.0025 ** 2))
    return z + ramp, design, design + ramp


def _candidates(z, angle):
    """Candidate pixels of the window along both axes on the whole smoothed block (the
    edge search's first step, before any edge test)."""
    zs = gaussian_nearest(z, SMOOTH / PIX)
    lim, eps = _bound_limit(math.radians(angle), PIX)
    r0, r1, c0, c1 = WINDOW
    ny, nx = z.shape
    n = 0
    cand = np.empty((r1 - r0, nx), dtype=np.bool_)
    count = np.empty(r1 - r0, dtype=np.int64)
    _candidates0(zs, 0, ny, 0, nx, r0, r1, SPAN, lim, eps, cand, count, 0, cand.shape[0])
    n += int(cand[:, c0:c1].sum())
    cand = np.empty((r1 - r0, c1 - c0), dtype=np.bool_)
    count = np.empty(r1 - r0, dtype=np.int64)
    _candidates1(zs, r0, r1, 0, nx, c0, c1, SPAN, lim, eps, cand, count, 0, cand.shape[0])
    return n + int(cand.sum())


def _proof(z, design, angle):
    lim, eps = _bound_limit(math.radians(angle), PIX)
    return no_edge_possible(z, design, gaussian_weights(SMOOTH / PIX), WINDOW, pixel=PIX,
                            edge_angle_deg=angle, span=SPAN, lim=lim, eps=eps, rel=_BOUND_ABS)


def test_no_edge_is_proved_only_where_there_is_no_candidate():
    """Kinks from far below to above the threshold's turn (1 deg: 0.0175 rad), against the
    design and against the form with its kink (a close reference: the proof then holds
    up to near the threshold): wherever it holds, no pixel of the window is even a
    candidate (the proof is of that); it holds on the smooth parts and is refused where
    there are candidates."""
    proved, refused, closest = 0, 0, 0.0
    cases = [(k, 0.0) for k in (0.0, 1e-4, 1e-3, 3e-3, 4e-3, 5e-3, 6e-3, 8e-3, 1e-2, 2e-2, 5e-2)]
    cases += [(0.0, h) for h in (1e-6, 1e-5, 3e-5, 1e-4, 3e-4, 1e-3)]
    for kink, dimple in cases:
        for seed in (0, 1):
            z, design, form = _part(kink, seed, dimple=dimple)
            for angle in (0.5, 1.0, 2.0):
                n = _candidates(z, angle)
                for ref in (design, form):
                    if _proof(z, ref, angle):
                        assert n == 0, (kink, dimple, seed, angle)
                        proved += 1
                        closest = max(closest, kink / math.radians(angle))
                    else:
                        refused += 1
    assert proved >= 40 and refused >= 40
    assert closest > 0.25          # proved for kinks of more than a quarter of the threshold


def test_the_proof_refuses_what_it_cannot_read():
    """A window whose smoothing or tests would reach the block's ends, a NaN pixel, a
    reference of another shape: no proof (the search runs)."""
    z, design, _ = _part()
    assert _proof(z, design, 1.0)
    w = gaussian_weights(SMOOTH / PIX)
    lim, eps = _bound_limit(math.radians(1.0), PIX)
    kw = dict(pixel=PIX, edge_angle_deg=1.0, span=SPAN, lim=lim, eps=eps, rel=_BOUND_ABS)
    reach = 2 * SPAN + (w.size - 1) // 2
    assert not no_edge_possible(z, design, w, (reach - 1, 140, 64, 170), **kw)
    assert no_edge_possible(z, design, w, (reach, 140, 64, 170), **kw)
    assert not no_edge_possible(z, design, w, (60, 140, 64, SHAPE[1] - reach + 1), **kw)
    holed = z.copy()
    holed[5, 5] = np.nan
    assert not no_edge_possible(holed, design, w, WINDOW, **kw)
    assert not no_edge_possible(z, design[:-1], w, WINDOW, **kw)
    # a far reference (none): the proof is still sound, only useless here
    assert not no_edge_possible(z, np.zeros_like(z), w, WINDOW, **kw)


def same_with_reference(z, design, **kw):
    """material_burr_block of ``z`` without a reference; with ``design`` as its reference
    (the map, or a function that makes it) the same maps, or None, are asserted."""
    want = material_burr_block(z, **kw)
    for ref in (design, lambda: design):
        got = material_burr_block(z, reference=ref, **kw)
        if want is None:
            assert got is None
        else:
            assert got is not None and all(np.array_equal(a, b) for a, b in zip(got, want))
    return want


@pytest.mark.parametrize("kink", [0.0, 2e-3, 0.3])
def test_the_burr_model_with_the_design_equals_it_without(kink):
    """material_burr_block with ``reference`` (the design, or a function that makes it):
    the same maps (or None) as without, on a smooth block (proved: None), near the threshold and on a sharp edge."""
    z, design, _ = _part(kink)
    kw = dict(pixel=PIX, origin=(-0.3, 0.2), chip_thickness=0.002, coefficient=1.0, variation=0.3,
              seed=3, edge_angle_deg=1.0, smoothing=SMOOTH, width=0.006,
              border=(False, False, False, False), start=(100, 200), inner=(63, 137, 67, 167))
    want = same_with_reference(z, design, **kw)
    if kink == 0.3:
        assert want is not None and want[1].any()      # a sharp edge: burrs to find
    if kink == 0.0:
        assert _proof(z, design, 1.0) and want is None


def test_tiles_with_the_design_equal_the_burrs_of_the_whole_map():
    """Tiles of a map with a sharp edge over part of it, each as ``simulate --tiled`` gives
    it to the burr model (a block with the model's halo, the design on the block beside
    it): on every tile the maps of the whole map, no burr where the whole map has none;
    the proof holds on some tiles away from the edge and the others find the edge's burrs."""
    from render_inspect.machining import burr_halo, plan_tiles

    ny, nx = 320, 384
    y, x = np.mgrid[0:ny, 0:nx] * PIX
    design = 0.01 * (x ** 2 + y ** 2) + 2e-3 * np.sin(x / 0.4) * np.cos(y / 0.5)
    rng = np.random.default_rng(5)
    z = design + 2e-9 * np.cos(2 * np.pi * np.hypot(x + 0.3, y + 0.2) / 0.01) + 2e-9 * rng.normal(size=x.shape)
    z = z + 0.2 * np.maximum(0.0, x - 0.3005) * (y > 0.2)          # an edge over the top rows
    kw = dict(pixel=PIX, origin=(-0.3, 0.2), chip_thickness=0.002, coefficient=1.0, variation=0.3,
              seed=3, edge_angle_deg=1.0, smoothing=SMOOTH, width=0.006)
    whole = material_burr_block(z, **kw)
    assert whole is not None and whole[1].sum() > 50
    h = burr_halo(PIX, SMOOTH, 0.006)
    proved = found = 0
    for t in plan_tiles((ny, nx), 64):
        r0, c0 = max(t.row - h, 0), max(t.col - h, 0)
        r1, c1 = min(t.row + t.rows + h, ny), min(t.col + t.cols + h, nx)
        inner = (t.row - r0, t.row - r0 + t.rows, t.col - c0, t.col - c0 + t.cols)
        border = (r0 == 0, r1 == ny, c0 == 0, c1 == nx)
        got = material_burr_block(z[r0:r1, c0:c1], border=border, start=(r0, c0), inner=inner,
                                  reference=None if any(border) else design[r0:r1, c0:c1], **kw)
        at = (slice(t.row, t.row + t.rows), slice(t.col, t.col + t.cols))
        if got is None:
            assert not whole[1][at].any() and not whole[0][at].any(), t
        else:
            for a, b in zip(got, whole):
                assert np.array_equal(a, b[at]), t
            found += int(got[1].sum())
        if not any(border):
            rw = 3
            window = (inner[0] - rw, inner[1] + rw, inner[2] - rw, inner[3] + rw)
            lim, eps = _bound_limit(math.radians(1.0), PIX)
            proved += no_edge_possible(z[r0:r1, c0:c1], design[r0:r1, c0:c1], gaussian_weights(SMOOTH / PIX),
                                       window, pixel=PIX, edge_angle_deg=1.0, span=SPAN, lim=lim, eps=eps,
                                       rel=_BOUND_ABS)
    assert found == int(whole[1].sum())
    assert proved >= 3
