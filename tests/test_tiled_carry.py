"""Tiles of a column cut in one task share the cut pixels of their halo'd blocks: the
heights and the partial sums equal those of each tile cut on its own, bit for bit."""

from pathlib import Path

import numpy as np
import pytest

from render_inspect.batch._tiled import column_runs
from render_inspect.core.grid import grid_shape
from render_inspect.design import make_surface
from render_inspect.machining import Tile, compute_tile, plan_tiles
from render_inspect.scene import load_scene

#: the shipped HTS toric scene over a window where the machined surface has sharp edges
SCENE = Path(__file__).resolve().parents[1] / "scenes" / "hts_toric_msa.toml"


def _case(scene_file, region, sets=()):
    """The cut path, envelope and grid of ``scene_file`` over ``region`` (mm)."""
    from render_inspect.processes import process_of
    from render_inspect.processes._mechanics import material_cut_path
    from render_inspect.toolpath import Tool

    scene = load_scene(scene_file, [f"simulation.region={list(region)}", *sets])
    proc = process_of(scene)
    cfg = proc.inputs_of(scene)
    surface = make_surface(scene.design)
    env = proc.envelope(cfg, surface, proc.plan(cfg, surface, region=region))
    cp = material_cut_path(env.path, Tool.from_config(cfg.tool), env.mechanics)
    pixel = cfg.simulation.pixel
    return dict(env=env, cp=cp, surface=surface, pixel=pixel, origin=region[:2],
                shape=grid_shape(region, pixel))


@pytest.fixture(scope="module")
def toric():
    return _case(SCENE, (0.1, 0.1, 0.6, 0.5))


def _alone(c, tiles, kw) -> dict:
    """Each tile cut on its own, all first (so that the carried runs do not reuse the
    freed memory of the same block just cut alone)."""
    return {t: compute_tile(c["cp"], c["surface"], c["origin"], c["pixel"], t, **kw)[1:] for t in tiles}


def _same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        if isinstance(a[k], tuple):
            assert a[k][:2] == b[k][:2] and np.array_equal(a[k][2], b[k][2], equal_nan=True), k
        else:
            assert a[k] == b[k], k


def _burrs(env, halo_px: int | None, pixel: float) -> dict:
    """The scene's burrs, or with a smoothing that gives a halo of about ``halo_px``
    pixels (blocks that overlap in part)."""
    b = dict(env.burrs)
    if halo_px is not None:
        b["smoothing"] = halo_px / 12 * pixel
    return b


@pytest.mark.parametrize("halo_px, texture", [(None, True), (24, False), (40, True)])
def test_a_column_of_tiles_with_a_carry_equals_each_tile_alone(toric, halo_px, texture):
    c = toric
    env = c["env"]
    kw = dict(grooves=env.grooves, shape=c["shape"], stride=7, burrs=_burrs(env, halo_px, c["pixel"]),
              texture=env.texture if texture else None)
    tiles = plan_tiles(c["shape"], 64)
    runs = column_runs(tiles, 1)
    assert sum(len(r) for r in runs) == len(tiles) and all(len({t.col for t in r}) == 1 for r in runs)
    ref = _alone(c, tiles, kw)
    for run in runs:
        carry: dict = {}
        for t in run:
            m0, p0 = ref[t]
            _, m1, p1 = compute_tile(c["cp"], c["surface"], c["origin"], c["pixel"], t, carry=carry, **kw)
            assert np.array_equal(m0, m1, equal_nan=True), t
            _same(p0, p1)


def test_tiles_cut_bottom_to_top_or_across_columns_with_a_carry_equal_each_tile_alone(toric):
    """A carry left by the tile below (rows above the shared ones cut) or by a tile of
    another column (not reused) gives the same tile."""
    c = toric
    env = c["env"]
    kw = dict(grooves=env.grooves, shape=c["shape"], burrs=_burrs(env, 30, c["pixel"]))
    tiles = plan_tiles(c["shape"], 64)
    ref = _alone(c, tiles, kw)
    order = [t for run in column_runs(tiles, 1) for t in reversed(run)] + tiles
    carry: dict = {}
    for t in order:
        m0, p0 = ref[t]
        _, m1, p1 = compute_tile(c["cp"], c["surface"], c["origin"], c["pixel"], t, carry=carry, **kw)
        assert np.array_equal(m0, m1, equal_nan=True), t
        _same(p0, p1)


def test_column_runs_split_the_columns_into_enough_runs():
    tiles = plan_tiles((5000, 2100), 1024)          # 5 rows x 3 columns of tiles
    runs = column_runs(tiles, 4)
    assert len(runs) >= 4
    assert sorted((t.row, t.col) for r in runs for t in r) == sorted((t.row, t.col) for t in tiles)
    for r in runs:
        assert len({t.col for t in r}) == 1
        assert [t.row for t in r] == sorted(t.row for t in r)
    assert len(column_runs(tiles, 1)) == 3
    assert column_runs([Tile(0, 0, 64, 64)], 8) == [[Tile(0, 0, 64, 64)]]


@pytest.fixture(scope="module")
def rim():
    """The shipped sinusoidal grid at 2 um over a window across the workpiece's rim: the
    tiles there have uncut (NaN) pixels and are cut again with the burr model's wider
    halo."""
    return _case(SCENE.parent / "sts_sinusoidal_grid.toml", (4.7, -0.2, 5.7, 0.2),
                 ["simulation.pixel=0.002"])


def test_the_wider_halo_of_tiles_with_uncut_pixels_reuses_the_narrower_block(rim):
    c = rim
    env = c["env"]
    kw = dict(grooves=env.grooves, shape=c["shape"], burrs=env.burrs, texture=env.texture)
    tiles = plan_tiles(c["shape"], 64)
    nan_tiles = 0
    ref = _alone(c, tiles, kw)
    for run in column_runs(tiles, 1):
        carry: dict = {}
        for t in run:
            m0, p0 = ref[t]
            _, m1, p1 = compute_tile(c["cp"], c["surface"], c["origin"], c["pixel"], t, carry=carry, **kw)
            nan_tiles += bool(np.isnan(m0).any())
            assert np.array_equal(m0, m1, equal_nan=True), t
            _same(p0, p1)
    assert nan_tiles > 0
