"""The proof that a whole map has no burr edge, read to its ends as the edge search reads
it (machining/_burr_bound.py, ``ends=True``: what material_burrs does with the design):
where it says so, the search on the whole smoothed map finds no candidate pixel outside
the band it leaves out, also for kinks and dimples near the map's ends, where the
smoothing and the tests are clamped; the burr model with it gives the same maps as
without it."""

import math

import numpy as np
import pytest

from render_inspect.machining import material_burrs
from render_inspect.machining._burr_bound import no_edge_possible
from render_inspect.machining._burr_kernels import (_BOUND_ABS, _bound_limit, _candidates0, _candidates1,
                                                    gaussian_nearest, gaussian_weights)
from test_burr_bound import same_with_reference

PIX = 0.001
SMOOTH = 0.004                      # 4-pixel sigma: taps reach 16 pixels
SPAN = max(2, int(math.ceil(3 * SMOOTH / PIX)) + 1)
BAND = int(math.ceil(3 * SMOOTH / PIX))     # the band along the border the search leaves out
SHAPE = (150, 170)
REACH = 2 * SPAN + 16               # a window this far inside needs no clamping
NEAR = 0.0035 + BAND * PIX          # a line between the band and REACH (mm from the first pixel)


def _part(kink=0.0, at=0.07, axis=1, dimple=0.0, dimple_at=(0.03, 0.02), seed=0):
    """A smooth design (sag and a slow wave), feed marks, noise, a kink of slope ``kink``
    along the line x = ``at`` (``axis`` 1; along y = ``at``: 0) and a dimple of depth
    ``dimple`` at ``dimple_at`` (x, y): the map, the design and the form with them."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:SHAPE[0], 0:SHAPE[1]] * PIX
    design = 0.01 * (x ** 2 + y ** 2) + 2e-3 * np.sin(x / 0.4) * np.cos(y / 0.5)
    r = np.hypot(x + 0.3, y + 0.2)
    z = design + 2e-9 * np.cos(2 * np.pi * r / 0.01) + 2e-9 * rng.normal(size=x.shape)
    ramp = kink * np.maximum(0.0, (x if axis == 1 else y) - at)
    ramp = ramp - dimple * np.exp(-((x - dimple_at[0]) ** 2 + (y - dimple_at[1]) ** 2) / (2 * 0.0025 ** 2))
    return z + ramp, design, design + ramp


def _window(border=(True, True, True, True)):
    ny, nx = SHAPE
    e = [BAND if f else 0 for f in border]
    return (e[0], ny - e[1], e[2], nx - e[3])


def _candidates(z, angle, window):
    """Candidate pixels of ``window`` along both axes on the whole smoothed map (the edge
    search's first step, clamped at the map's ends as the search is)."""
    zs = gaussian_nearest(z, SMOOTH / PIX)
    lim, eps = _bound_limit(math.radians(angle), PIX)
    r0, r1, c0, c1 = window
    ny, nx = z.shape
    cand = np.empty((r1 - r0, nx), dtype=np.bool_)
    count = np.empty(r1 - r0, dtype=np.int64)
    _candidates0(zs, 0, ny, 0, nx, r0, r1, SPAN, lim, eps, cand, count, 0, cand.shape[0])
    n = int(cand[:, c0:c1].sum())
    cand = np.empty((r1 - r0, c1 - c0), dtype=np.bool_)
    count = np.empty(r1 - r0, dtype=np.int64)
    _candidates1(zs, r0, r1, 0, nx, c0, c1, SPAN, lim, eps, cand, count, 0, cand.shape[0])
    return n + int(cand.sum())


def _proof(z, ref, angle, window, sample=None):
    lim, eps = _bound_limit(math.radians(angle), PIX)
    return no_edge_possible(z, ref, gaussian_weights(SMOOTH / PIX), window, pixel=PIX, edge_angle_deg=angle,
                            span=SPAN, lim=lim, eps=eps, rel=_BOUND_ABS, sample=sample, ends=True)


def test_the_whole_map_proof_holds_only_where_there_is_no_candidate():
    """Kinks along either axis from the middle of the map to just inside the band along
    its border (where the smoothing and the tests are clamped: the pixels the proof of a
    tile cannot read), from far below to above the threshold's turn, and dimples near a
    corner and between the sampled lines (they hold candidates no sampled line reads:
    only the slack between the lines refuses them), against the design and against the form with them, with and without the
    band: wherever the proof holds, no pixel is even a candidate; it holds on smooth maps
    and on kinks near the ends well below the threshold, and is refused elsewhere."""
    proved, refused, near_end = 0, 0, 0
    cases = [(k, at, axis, 0.0) for k in (0.0, 2e-3, 6e-3, 2e-2, 0.1) for axis in (0, 1)
             for at in (0.075, NEAR, (SHAPE[axis] - 16) * PIX)]
    # dimples near a corner, and half way between lines 64 apart (near the ends too)
    cases += [(0.0, 0.0, 1, (h, where)) for h in (1e-6, 3e-5, 1e-4, 1e-3)
              for where in ((0.016, 0.135), (0.0445, 0.0445), (0.1085, 0.0205), (0.0205, 0.1085))]
    for kink, at, axis, dimple in cases:
        depth, where = dimple if dimple else (0.0, (0.0, 0.0))
        z, design, form = _part(kink, at, axis, dimple=depth, dimple_at=where)
        for border in ((True, True, True, True), (False, True, False, True)):
            window = _window(border)
            for angle in (0.5, 1.0):
                n = _candidates(z, angle, window)
                for ref in (design, form):
                    for sample in (None, 8):
                        if _proof(z, ref, angle, window, sample):
                            assert n == 0, (kink, at, axis, depth, where, border, angle, sample)
                            proved += 1
                            far = min(at / PIX, SHAPE[axis] - at / PIX)
                            near_end += kink > 0 and far < REACH
                        else:
                            refused += 1
    assert proved >= 40 and refused >= 40
    assert near_end >= 4            # kinks the tile's proof could not have judged


def test_the_whole_map_proof_refuses_what_it_cannot_read():
    """A NaN pixel, a reference of another shape, a window beyond the map, a map too
    small for the tests: no proof (the search runs); without ``ends`` a window reaching
    the ends is refused as before."""
    z, design, _ = _part()
    window = _window()
    assert _proof(z, design, 1.0, window)
    holed = z.copy()
    holed[2, 2] = np.nan
    assert not _proof(holed, design, 1.0, window)
    assert not _proof(z, design[:-1], 1.0, window)
    assert not _proof(z, design, 1.0, (0, SHAPE[0] + 1, 0, SHAPE[1]))
    assert not _proof(z[:2], design[:2], 1.0, (0, 2, 0, SHAPE[1]))
    lim, eps = _bound_limit(math.radians(1.0), PIX)
    assert not no_edge_possible(z, design, gaussian_weights(SMOOTH / PIX), window, pixel=PIX, edge_angle_deg=1.0,
                                span=SPAN, lim=lim, eps=eps, rel=_BOUND_ABS)


@pytest.mark.parametrize("kink,at,axis", [(0.0, 0.07, 1), (4e-3, NEAR, 1), (0.3, NEAR, 1),
                                          (0.3, (SHAPE[0] - 16) * PIX, 0), (0.3, 0.07, 0)])
@pytest.mark.parametrize("border", [(True, True, True, True), (False, True, True, False)])
def test_the_whole_map_burrs_with_the_design_equal_them_without(kink, at, axis, border):
    """material_burr_block on a whole map with ``reference`` (the design, or a function
    that makes it): the same maps (or None) as without, on a smooth map (proved: None),
    near the threshold and on sharp edges near the ends and in the middle; material_burrs
    (which gives it the design) the same map as the search on the whole map."""
    z, design, _ = _part(kink, at, axis)
    kw = dict(pixel=PIX, origin=(-0.3, 0.2), chip_thickness=0.002, coefficient=1.0, variation=0.3,
              seed=3, edge_angle_deg=1.0, smoothing=SMOOTH, width=0.006)
    want = same_with_reference(z, design, border=border, **kw)
    if kink == 0.3:
        assert want is not None and want[1].any()       # a sharp edge: burrs to find
    if kink == 0.0:
        assert want is None and _proof(z, design, 1.0, _window(border))
    if border == (True, True, True, True):
        added, info = material_burrs(z, design, **kw)
        base = z.copy() if want is None else z + want[0]
        assert np.array_equal(added, base)
        assert info["edge_pixels"] == (0 if want is None else int(want[1].sum()))
