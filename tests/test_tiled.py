"""Fast envelope kernel, tiled out-of-core simulation, pyramids, Zarr and tiled EXR."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import make_surface
from render_inspect.core.errors import InputError
from render_inspect.core.units import MM_TO_UM
from render_inspect.io._exr import read_exr, read_exr_overview, write_height_channels
from render_inspect.io._heightmap import grid_attrs
from render_inspect.io._pyramid import block_sums, level_count, means, preview, pyramid
from render_inspect.io._zarr import ZarrHeightMap, create_heightmap_zarr, write_heightmap_zarr
from render_inspect.machining import residual_metrics, simulate_turning
from render_inspect.machining._envelope import envelope_fill, prepare_envelope
from render_inspect.batch import run_tiles
from render_inspect.machining import design_grid, metrics_from_moments, plan_tiles
from render_inspect.processes import plan_spiral
from render_inspect.toolpath import Tool
from render_inspect.scene import load_scene

GRID = Path(__file__).resolve().parents[1] / "scenes" / "sts_sinusoidal_grid.toml"
#: the fast kernel differs from the reference only by the rounding of the interpolation
#: fraction (see render_inspect/machining/_envelope.py)
KERNEL_ATOL_MM = 1e-12


def _case(region, pixel, overrides=()):
    scene = load_scene(GRID, [f"simulation.region={list(region)}", f"simulation.pixel={pixel}", *overrides])
    surface = make_surface(scene.design)
    path = plan_spiral(scene, surface, region=region)
    tool = Tool.from_config(scene.tool)
    return scene, surface, path, tool


@pytest.mark.parametrize("region, overrides", [
    ((-0.06, -0.05, 0.07, 0.06), ()),                                      # across the axis
    ((0.31, -0.2, 0.45, -0.08), ()),                                       # off axis
    ((-0.05, -0.04, 0.06, 0.05), ("process.sampling='constant_arc'",)),   # not constant-angle
    ((0.2, 0.2, 0.3, 0.28), ("process.compensation='none'",)),
])
def test_fast_kernel_equals_the_reference_kernel(region, overrides):
    _, _, path, tool = _case(region, 0.001, overrides)
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=region, pixel=0.001)
    fast = simulate_turning(path, **kw)
    ref = simulate_turning(path, reference=True, **kw)
    assert np.array_equal(np.isnan(fast), np.isnan(ref))
    assert_allclose(fast, ref, rtol=0, atol=KERNEL_ATOL_MM)
    assert prepare_envelope(path, nose_radius=tool.nose_radius).uniform == (not overrides or "sampling" not in overrides[0])


def test_fast_kernel_beyond_the_path_ends_visits_every_pass():
    # a window wider than the path: pixels outside the outermost pass fall back to every
    # pass that reaches, as in the reference kernel
    region = (4.95, -0.05, 5.3, 0.05)
    _, _, path, tool = _case(region, 0.002)
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=region, pixel=0.002)
    fast, ref = simulate_turning(path, **kw), simulate_turning(path, reference=True, **kw)
    assert np.isnan(ref).any() and np.isfinite(ref).any()
    assert np.array_equal(np.isnan(fast), np.isnan(ref))
    assert_allclose(fast, ref, rtol=0, atol=KERNEL_ATOL_MM)


@pytest.fixture(scope="module")
def tiled_case(tmp_path_factory):
    region, pixel = (-0.1, -0.07, 0.16, 0.12), 0.0005   # 381 x 521 pixels, across the axis
    _, surface, path, tool = _case(region, pixel)
    ep = prepare_envelope(path, nose_radius=tool.nose_radius, half_width=tool.half_width)
    machined = simulate_turning(path, nose_radius=tool.nose_radius, half_width=tool.half_width,
                                region=region, pixel=pixel)
    design = design_grid(surface, region, pixel)
    levels = level_count(machined.shape, smallest=32)
    store = str(tmp_path_factory.mktemp("tiled") / "heightmap.zarr")
    create_heightmap_zarr(store, machined.shape, chunk=128,
                          attrs=grid_attrs(pixel, region[:2], {"name": "t"}, {"seed": 0}), levels=levels)
    seen = []
    stats = run_tiles(ep, surface, origin=region[:2], pixel=pixel, shape=machined.shape, store=store,
                      levels=levels, tile=128, progress=lambda d, t, s: seen.append((d, t)))
    return dict(machined=machined, design=design, store=store, stats=stats, levels=levels, seen=seen,
                ep=ep, surface=surface, region=region, pixel=pixel)


def test_tiled_heights_equal_the_in_memory_map_without_seams(tiled_case):
    c = tiled_case
    z = ZarrHeightMap(c["store"])
    m = z.read("machined")
    assert np.array_equal(m, c["machined"].astype(np.float32), equal_nan=True)
    # the rows and columns on both sides of every tile boundary, in float64 via the residual
    r = z.read("residual")
    want = (c["machined"] - c["design"]).astype(np.float32)
    for b in (128, 256):
        assert np.array_equal(r[b - 1:b + 1], want[b - 1:b + 1], equal_nan=True)
        assert np.array_equal(r[:, b - 1:b + 1], want[:, b - 1:b + 1], equal_nan=True)
    assert c["seen"][-1] == (len(plan_tiles(m.shape, 128)), len(plan_tiles(m.shape, 128)))


def test_tiled_metrics_equal_the_single_array_metrics(tiled_case):
    c = tiled_case
    ref = residual_metrics(c["machined"], c["design"])
    got = metrics_from_moments(c["stats"].moments, c["stats"].abs_dev, c["machined"].size)
    for k in ("Sq_nm", "Sp_nm", "Sv_nm", "Sz_nm", "min_nm", "mean_nm", "valid_fraction"):
        assert got[k] == pytest.approx(ref[k], rel=1e-12, abs=1e-12), k
    # Sa from the float32 residual: error <= 2^-24 (Sa + |mean|)
    assert abs(got["Sa_nm"] - ref["Sa_nm"]) <= 2.0 ** -24 * (ref["Sa_nm"] + abs(ref["mean_nm"]))


def test_tiled_histogram_is_the_histogram_of_the_stored_residual(tiled_case):
    c = tiled_case
    lo, hi, counts = c["stats"].histogram
    r = ZarrHeightMap(c["store"]).read("residual").astype(np.float64)
    r = r[np.isfinite(r)]
    k = np.clip(((r - lo) / ((hi - lo) / counts.size)).astype(np.int64), 0, counts.size - 1)
    assert np.array_equal(np.bincount(k, minlength=counts.size), counts)
    assert counts.sum() == r.size


def test_tiled_pyramid_equals_the_area_means_of_the_whole_map(tiled_case):
    c = tiled_case
    z = ZarrHeightMap(c["store"])
    full = z.read("residual")
    for k, want in enumerate(pyramid(full, c["levels"]), start=1):
        assert np.array_equal(z.read("residual", level=k), want, equal_nan=True)
    assert z.level_for(100) >= 1


def test_a_flipped_run_stores_the_map_with_its_rows_turned_over(tiled_case, tmp_path):
    """``run_tiles(flip=True)`` (a program turning M04: the mirror image cut tile by tile):
    the store holds the map with its rows in the other order (row k of the grid cut is row
    ny - 1 - k; tiles of 128 do not divide its 381 rows), its pyramid that of the flipped
    map (a level coarser than a tile too), the same statistics."""
    c = tiled_case
    shape = c["machined"].shape
    levels = level_count(shape, smallest=4)
    assert levels > 7 and shape[0] % 128  # a level coarser than a tile of 128
    store = str(tmp_path / "flipped.zarr")
    create_heightmap_zarr(store, shape, chunk=128, levels=levels,
                          attrs=grid_attrs(c["pixel"], c["region"][:2], None, None))
    stats = run_tiles(c["ep"], c["surface"], origin=c["region"][:2], pixel=c["pixel"], shape=shape,
                      store=store, levels=levels, tile=128, flip=True)
    z = ZarrHeightMap(store)
    want = {"design": c["design"][::-1], "machined": c["machined"][::-1],
            "residual": (c["machined"] - c["design"])[::-1]}
    for name, a in want.items():
        full = z.read(name)
        assert np.array_equal(full, a.astype(np.float32), equal_nan=True), name
        for k, w in enumerate(pyramid(full, levels), start=1):
            assert np.array_equal(z.read(name, level=k), w, equal_nan=True), (name, k)
    n, mean, _, lo, hi = stats.moments
    assert (n, lo, hi) == (c["stats"].moments[0], *c["stats"].moments[3:])
    assert mean == pytest.approx(c["stats"].moments[1], rel=1e-12)
    assert stats.histogram[2].tolist() == c["stats"].histogram[2].tolist()
    assert "flip" in stats.timing_s


@pytest.mark.parametrize("ny, nx, chunk", [(257, 70, 64), (256, 64, 64), (63, 70, 64),
                                           (1, 3, 64), (449, 64, 128)])
def test_flipping_a_column_holds_a_few_chunks(tmp_path, ny, nx, chunk):
    """The rows of a store turned over column by column, each chunk written whole: the
    flipped map and its pyramid, with at most 3 chunks of a column held at once."""
    from render_inspect.batch._tile_flip import flip_column
    import zarr

    rng = np.random.default_rng(ny)
    levels = level_count((ny, nx), smallest=64)
    store = str(tmp_path / "s.zarr")
    create_heightmap_zarr(store, (ny, nx), chunk=chunk, levels=levels, attrs=grid_attrs(0.1, (0, 0), None, None))
    g = zarr.open_group(store, mode="r+")
    maps = {}
    for name in ("design", "machined", "residual"):
        a = rng.standard_normal((ny, nx)).astype(np.float32)
        a[rng.random((ny, nx)) < 0.1] = np.nan
        g[name][...] = maps[name] = a
    tile_levels = min(levels, int(math.log2(chunk)))
    for col in range(0, nx, chunk):
        held = {}
        parts = flip_column(store, (ny, nx), chunk, levels, tile_levels, col, stats=held)
        assert held["held"] <= 3 and len(parts) == -(-ny // chunk)
    z = ZarrHeightMap(store)
    for name, a in maps.items():
        assert np.array_equal(z.read(name), a[::-1], equal_nan=True), name
        for k, w in enumerate(pyramid(a[::-1], tile_levels), start=1):
            assert np.array_equal(z.read(name, level=k), w, equal_nan=True), (name, k)


def test_pyramid_averages_instead_of_aliasing():
    # a feed-mark pattern with a 3-pixel period: 8 x 8 block means nearly cancel it, while
    # taking every 8th sample would alias it into a full-amplitude pattern
    x = np.arange(512)
    a = np.cos(2 * np.pi * x / 3)[None, :] * np.ones((512, 1))
    lv = pyramid(a, 3)[2]
    assert np.max(np.abs(lv)) <= 1 / 8 + 1e-6   # what is left of 8 samples of a 3-sample period
    assert np.max(np.abs(a[::8, ::8])) > 0.9
    # NaNs are left out of the means; an all-NaN block is NaN
    b = np.ones((4, 4))
    b[0, 0] = np.nan
    b[2:, 2:] = np.nan
    s, n = block_sums(b, 2)
    assert_allclose(means(s, n), [[1.0, 1.0], [1.0, np.nan]])
    img, f = preview(np.zeros((2000, 900)), 512)
    assert f == 4 and img.shape == (500, 225)


def test_tiles_must_align_with_the_kernel_blocks():
    with pytest.raises(InputError, match="multiple of 64"):
        plan_tiles((100, 100), 100)


def test_zarr_store_has_the_attributes_of_heightmap_exr(tmp_path):
    rng = np.random.default_rng(0)
    design = rng.normal(size=(300, 200)) * 1e-3
    machined = design + rng.normal(size=design.shape) * 1e-6
    machined[:5, :5] = np.nan
    attrs = grid_attrs(0.001, (0.25, -0.5), {"name": "x"}, {"seed": 3})
    write_height_channels(tmp_path / "h.exr", design, machined, attrs, overview_side=64)
    write_heightmap_zarr(tmp_path / "h.zarr", design, machined, attrs=attrs, chunk=128)
    ch, ea = read_exr(tmp_path / "h.exr")
    z = ZarrHeightMap(tmp_path / "h.zarr")
    for k in ("pixel_size_mm", "origin_mm", "units", "software_version"):
        assert z.attrs[k] == ea[k], k
    assert z.scene == ea["scene"] and z.meta == ea["meta"]
    for name in ("design", "machined", "residual"):
        assert np.array_equal(z.read(name), ch[name], equal_nan=True)
    # residual formed in float64, then rounded once
    assert np.array_equal(ch["residual"], (machined - design).astype(np.float32), equal_nan=True)
    # float32 storage: relative error at most 2^-24
    ok = np.isfinite(machined)
    assert np.all(np.abs(ch["machined"][ok] - machined[ok]) <= 2.0 ** -24 * np.abs(machined[ok]))
    # overview part: 8 x 8-pixel area means (the first power of two bringing 300 to <= 64)
    ov, factor = read_exr_overview(tmp_path / "h.exr")
    assert factor == 8 and ov["residual"].shape == (38, 25)
    s, n = block_sums(machined, 8, minus=design)
    assert_allclose(ov["residual"], means(s, n), rtol=1e-6, atol=1e-12)
    # a window: only the pixels whose centres lie in the region
    rows, cols = z.index_window((0.3, -0.45, 0.35, -0.4))
    assert (rows.start, rows.stop, cols.start, cols.stop) == (50, 101, 50, 101)
    d, m, origin = z.window((0.3, -0.45, 0.35, -0.4))
    assert d.shape == (51, 51) and origin == pytest.approx((0.3, -0.45))
    with pytest.raises(InputError, match="does not overlap"):
        z.index_window((5, 5, 6, 6))


def test_small_exr_has_no_overview(tmp_path):
    a = np.zeros((10, 12))
    write_height_channels(tmp_path / "s.exr", a, a, grid_attrs(0.001, (0, 0), None, None))
    assert read_exr_overview(tmp_path / "s.exr") is None
    assert read_exr(tmp_path / "s.exr")[0]["machined"].shape == (10, 12)


@pytest.mark.slow
def test_tiles_on_a_local_dask_cluster_equal_the_threaded_run(tiled_case, tmp_path):
    from distributed import Client, LocalCluster

    c = tiled_case
    store = str(tmp_path / "cluster.zarr")
    create_heightmap_zarr(store, c["machined"].shape, chunk=128,
                          attrs=grid_attrs(c["pixel"], c["region"][:2], None, None), levels=c["levels"])
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        stats = run_tiles(c["ep"], c["surface"], origin=c["region"][:2], pixel=c["pixel"],
                          shape=c["machined"].shape, store=store, levels=c["levels"], tile=128, client=client)
    assert stats.moments == c["stats"].moments
    assert math.isclose(stats.abs_dev[1], c["stats"].abs_dev[1], rel_tol=1e-12)
    a, b = ZarrHeightMap(store), ZarrHeightMap(c["store"])
    for name in ("machined", "residual"):
        assert np.array_equal(a.read(name), b.read(name), equal_nan=True)


_GPU_CHECK = '''
import numpy as np, sys
sys.path.insert(0, sys.argv[1])
from test_tiled import _case
from render_inspect.machining._envelope import prepare_envelope, envelope_fill
from render_inspect.machining._envelope_gpu import cuda_available, envelope_fill_gpu
assert cuda_available()
region, pixel = (-0.012, -0.01, 0.011, 0.012), 0.001      # across the axis
_, _, path, tool = _case(region, pixel)
ep = prepare_envelope(path, nose_radius=tool.nose_radius, half_width=tool.half_width)
cpu = envelope_fill(ep, region[:2], pixel, np.empty((23, 24)))
gpu = envelope_fill_gpu(ep, region[:2], pixel, np.empty((23, 24)))
assert np.array_equal(np.isnan(cpu), np.isnan(gpu))
worst = float(np.nanmax(np.abs(cpu - gpu)))
# the shipped grid's 2 x 2 mm window at 0.5 um, the block that holds its axis pixel
# (2000, 2000), whose position -1 + 2000 * 0.0005 a fused multiply-add would not round to 0
region, pixel = (-1.0, -1.0, 1.0, 1.0), 0.0005
_, _, path, tool = _case(region, pixel)
ep = prepare_envelope(path, nose_radius=tool.nose_radius, half_width=tool.half_width)
cpu = envelope_fill(ep, region[:2], pixel, np.empty((64, 64)), start=(1984, 1984))
gpu = envelope_fill_gpu(ep, region[:2], pixel, np.empty((64, 64)), start=(1984, 1984))
assert np.array_equal(np.isnan(cpu), np.isnan(gpu))
print(max(worst, float(np.nanmax(np.abs(cpu - gpu)))))
'''


@pytest.mark.parametrize("simulator", [
    pytest.param(True, id="cuda-simulator"),
    pytest.param(False, id="cuda-device", marks=pytest.mark.gpu),
])
@pytest.mark.slow
def test_gpu_kernel_equals_the_cpu_kernel(simulator):
    import os
    import subprocess
    import sys

    from render_inspect.machining._envelope_gpu import cuda_available

    if not simulator and not cuda_available():
        pytest.skip("no CUDA device")
    env = dict(os.environ, NUMBA_ENABLE_CUDASIM="1" if simulator else "0")
    p = subprocess.run([sys.executable, "-c", _GPU_CHECK, str(Path(__file__).parent)], env=env,
                       capture_output=True, text=True)
    assert p.returncode == 0, p.stderr[-2000:]
    assert float(p.stdout.strip().splitlines()[-1]) < KERNEL_ATOL_MM


def _gpu_case():
    region, pixel = (0.31, -0.2, 0.45, -0.08), 0.001      # off axis, constant-angle
    _, _, path, tool = _case(region, pixel)
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=region, pixel=pixel)
    return path, kw, simulate_turning(path, device="cpu", **kw)


@pytest.fixture
def fake_gpu(monkeypatch):
    """A CUDA device that is present, with the GPU kernel replaced by ``calls["kernel"]``
    (its calls counted), and the process's memory of a failed GPU cleared."""
    from render_inspect.machining import _envelope, _envelope_gpu

    calls = {"kernel": None, "n": 0, "asked": 0}

    def kernel(ep, origin, pixel, out, **kw):
        calls["n"] += 1
        return calls["kernel"](ep, origin, pixel, out)

    def available():
        calls["asked"] += 1
        return True

    monkeypatch.setattr(_envelope_gpu, "cuda_available", available)
    monkeypatch.setattr(_envelope_gpu, "envelope_fill_gpu", kernel)
    monkeypatch.setattr(_envelope, "GPU_MIN_SAMPLES", 100)
    monkeypatch.setattr(_envelope, "_GPU_FAILED", None)
    return calls


def test_a_failing_gpu_stack_falls_back_to_the_cpu_once_and_says_why(fake_gpu, caplog):
    # what a CUDA stack whose numba.cuda does not match its NumPy raises when it compiles
    def broken(ep, origin, pixel, out):
        raise AttributeError("module 'numpy' has no attribute 'row_stack'")

    fake_gpu["kernel"] = broken
    path, kw, cpu = _gpu_case()
    with caplog.at_level("WARNING", logger="render_inspect"):
        first = simulate_turning(path, **kw)
        second = simulate_turning(path, **kw)
    assert np.array_equal(first, cpu, equal_nan=True) and np.array_equal(second, cpu, equal_nan=True)
    said = [r.getMessage() for r in caplog.records if "GPU" in r.getMessage()]
    assert said == ["the GPU envelope kernel failed (AttributeError: module 'numpy' has no attribute "
                    "'row_stack'); the CPU kernel runs instead"]
    assert fake_gpu["n"] == 1                         # not tried again in the same process
    with pytest.raises(AttributeError, match="row_stack"):
        simulate_turning(path, device="gpu", **kw)    # asked for by name: the error itself


def test_a_gpu_that_disagrees_with_the_cpu_is_not_used(fake_gpu, caplog):
    def off(ep, origin, pixel, out):
        envelope_fill(ep, origin, pixel, out)
        out += 1e-6                                    # 1 nm off
        return out

    fake_gpu["kernel"] = off
    path, kw, cpu = _gpu_case()
    with caplog.at_level("WARNING", logger="render_inspect"):
        got = simulate_turning(path, **kw)
    assert np.array_equal(got, cpu, equal_nan=True) and fake_gpu["n"] == 1
    assert any("disagrees with the CPU kernel" in r.getMessage() for r in caplog.records)


def test_a_gpu_that_disagrees_only_at_the_axis_is_not_used(fake_gpu, caplog):
    # the spindle axis' pixel is where the height depends on the pixel's radial section:
    # a GPU that rounds its position otherwise is off there alone (13.6 nm once, on a device)
    region, pixel = (-0.15, -0.15, 0.15, 0.15), 0.001          # the axis in block (128, 128)
    _, _, path, tool = _case(region, pixel)
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=region, pixel=pixel)
    cpu = simulate_turning(path, device="cpu", **kw)

    def off_at_the_axis(ep, origin, pixel, out):
        envelope_fill(ep, origin, pixel, out)
        out[150, 150] += 1.36e-5
        return out

    fake_gpu["kernel"] = off_at_the_axis
    with caplog.at_level("WARNING", logger="render_inspect"):
        got = simulate_turning(path, **kw)
    assert np.array_equal(got, cpu, equal_nan=True) and fake_gpu["n"] == 1
    assert any("disagrees with the CPU kernel" in r.getMessage() for r in caplog.records)


def test_the_gpu_is_not_asked_for_a_path_it_does_not_handle(fake_gpu):
    region = (-0.05, -0.04, 0.06, 0.05)
    _, _, path, tool = _case(region, 0.001, ("process.sampling='constant_arc'",))
    kw = dict(nose_radius=tool.nose_radius, half_width=tool.half_width, region=region, pixel=0.001)
    assert np.array_equal(simulate_turning(path, **kw), simulate_turning(path, device="cpu", **kw),
                          equal_nan=True)
    # asking whether a device is there starts CUDA's driver: not done for this path
    assert fake_gpu["asked"] == 0 and fake_gpu["n"] == 0


def _cli(*args, check=True):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "render_inspect.cli", *map(str, args)], capture_output=True,
                          text=True, check=check)


#: the shipped scene's lathe with an ideal material (tests/test_cut_kernel.py tiles the
#: shipped material)
WINDOW = ["--set", "simulation.region=[-0.2,-0.15,0.22,0.2]", "--set", "material.preset='ideal'",
          "--set", "simulation.pixel=0.001"]


@pytest.mark.slow
def test_simulate_tiles_a_map_that_does_not_fit_the_budget(tmp_path):
    import json

    # 3.7 M samples: about 0.21 GiB in memory, 0.08 GiB in tiles of 256 x 256 (0.05 GiB of
    # them the lathe's servo ticks, which the driver holds for the whole path)
    small, big = tmp_path / "in_memory", tmp_path / "tiled"
    fine = WINDOW[:5] + ["simulation.pixel=0.0002"]
    _cli("simulate", GRID, "--out", small, *fine)
    p = _cli("simulate", GRID, "--out", big, *fine, "--set", "simulation.max_memory_gb=0.12", "--tile", "256")
    assert "tiles" in p.stderr and "%" in p.stderr          # progress while it runs
    names = {f.name for f in big.iterdir()}
    assert {"heightmap.zarr", "metrics.json", "toolpath.npz", "residual.png", "kinematics.png"} <= names
    assert "heightmap.exr" not in names
    a = json.loads((small / "metrics.json").read_text())
    b = json.loads((big / "metrics.json").read_text())
    for k in ("Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "min_nm", "mean_nm"):
        assert b["residual"][k] == pytest.approx(a["residual"][k], rel=1e-12, abs=1e-9), k
    assert b["residual"]["Sa_nm"] == pytest.approx(a["residual"]["Sa_nm"], rel=1e-6)
    assert b["samples"] == a["samples"] and b["grid"] == a["grid"] and b["tiles"]["count"] == 63
    assert b["toolpath"]["points"] == a["toolpath"]["points"]
    z = ZarrHeightMap(big / "heightmap.zarr")
    ch, attrs = read_exr(small / "heightmap.exr")
    assert np.array_equal(z.read("machined"), ch["machined"], equal_nan=True)
    for sc in (z.scene, attrs["scene"]):
        sc["simulation"].pop("max_memory_gb")
    assert z.scene == attrs["scene"] and z.attrs["pixel_size_mm"] == attrs["pixel_size_mm"]


@pytest.mark.slow
def test_tiled_simulate_refuses_what_it_cannot_tile(tmp_path):
    p = _cli("simulate", GRID, "--out", tmp_path / "b", *WINDOW, "--tiled", "--set",
             "artifacts.burrs.height=0.0001", "--set", "artifacts.burrs.width=0.002", check=False)
    assert p.returncode == 1 and "artifacts.burrs.height" in p.stderr and "Traceback" not in p.stderr
    p = _cli("simulate", GRID, "--out", tmp_path / "c", *WINDOW, "--tile", "100", check=False, )
    # (checked on either path: a bad value is not passed over because the map fits)
    assert p.returncode == 1 and "power of two" in p.stderr and not (tmp_path / "c").exists()
    p = _cli("simulate", GRID, "--out", tmp_path / "d", *WINDOW, "--tiled", "--tile", "100", check=False)
    assert p.returncode == 1 and "power of two" in p.stderr and not (tmp_path / "d").exists()


@pytest.mark.slow
def test_simulate_on_two_dask_worker_processes(tmp_path):
    import json

    a, b = tmp_path / "threads", tmp_path / "workers"
    _cli("simulate", GRID, "--out", a, *WINDOW, "--tiled", "--tile", "128")
    p = _cli("simulate", GRID, "--out", b, *WINDOW, "--workers", "2", "--tile", "128")
    assert "2 Dask workers" in p.stderr
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
    assert mb["tiles"]["scheduler"] == "LocalCluster" and mb["tiles"]["workers"] == 2
    assert mb["residual"]["Sq_nm"] == pytest.approx(ma["residual"]["Sq_nm"], rel=1e-12)
    assert np.array_equal(ZarrHeightMap(a / "heightmap.zarr").read("residual"),
                          ZarrHeightMap(b / "heightmap.zarr").read("residual"), equal_nan=True)


@pytest.mark.slow
def test_renders_of_a_big_map_read_only_the_windows_they_need(tmp_path):
    from render_inspect.instruments import instrument_types, interferometer_geometry
    from render_inspect.pipeline import run_simulate_tiled, simulate
    from render_inspect.pipeline._views import BigMapViews

    scene = load_scene(GRID, ["simulation.region=[-0.3,-0.25,0.32,0.3]", "simulation.pixel=0.0005",
                              "material.preset='ideal'",
                              "render.interferometer.objective='50x'", "render.diffuse.resolution=64"])
    run_simulate_tiled(scene, tmp_path / "t", tile=256)
    hm = simulate(scene).heightmap
    views = BigMapViews(tmp_path / "t" / "heightmap.zarr")
    hm_i, icfg = views.instrument(instrument_types()["interferometer"],
                                  scene.render.interferometer)
    a = interferometer_geometry(hm, scene.render.interferometer)
    b = interferometer_geometry(hm_i, icfg)
    for k in ("nx", "ny", "pixel", "numerical_aperture"):
        assert a[k] == b[k], k
    assert_allclose(a["origin"], b["origin"], rtol=0, atol=1e-12)
    # the window holds the same samples as the in-memory map, and only those (plus 2 pixels)
    r0 = int(round((hm_i.origin[1] - hm.origin[1]) / hm.pixel))
    c0 = int(round((hm_i.origin[0] - hm.origin[0]) / hm.pixel))
    crop = hm.machined[r0:r0 + hm_i.shape[0], c0:c0 + hm_i.shape[1]]
    assert np.array_equal(hm_i.machined, crop.astype(np.float32).astype(np.float64), equal_nan=True)
    assert hm_i.design.size < hm.design.size / 2     # 0.36 mm field of view of a 0.62 x 0.55 mm map
    hm_m, _ = views.diffuse(scene.render.diffuse, "macro")
    assert max(hm_m.shape) <= 256 and hm_m.pixel > hm.pixel    # the coarsest level of the store
    hm_u, dcfg = views.diffuse(scene.render.diffuse, "micro")
    assert dcfg.window is not None and hm_u.design.size < hm.design.size / 16
    assert set(views.facts["read"]) == {"interferometer", "diffuse_macro", "diffuse_micro"}


def test_metrology_reads_a_window_of_a_store(tmp_path):
    from render_inspect.io import read_measured

    rng = np.random.default_rng(1)
    design = rng.normal(size=(200, 300)) * 1e-3
    machined = design + 1e-6
    write_heightmap_zarr(tmp_path / "m.zarr", design, machined, attrs=grid_attrs(0.001, (1.0, 2.0), None, None),
                         chunk=64)
    z, pixel, origin, meta = read_measured(tmp_path / "m.zarr", region=(1.05, 2.02, 1.1, 2.06))
    assert z.shape == (41, 51) and pixel == 0.001 and origin == pytest.approx((1.05, 2.02))
    assert np.array_equal(z, machined[20:61, 50:101].astype(np.float32).astype(np.float64))
    assert meta["format"] == "zarr" and meta["store_shape"] == [200, 300]


def test_tiles_of_a_constant_arc_path_equal_the_whole_grid():
    from render_inspect.machining import compute_tile

    region, pixel = (-0.05, -0.04, 0.09, 0.08), 0.0005
    _, surface, path, tool = _case(region, pixel, ("process.sampling='constant_arc'",))
    ep = prepare_envelope(path, nose_radius=tool.nose_radius, half_width=tool.half_width)
    assert not ep.uniform
    whole = simulate_turning(path, nose_radius=tool.nose_radius, half_width=tool.half_width, region=region,
                             pixel=pixel)
    for t in plan_tiles(whole.shape, 128):
        _, m, _ = compute_tile(ep, surface, region[:2], pixel, t)
        assert np.array_equal(m, whole[t.row:t.row + t.rows, t.col:t.col + t.cols], equal_nan=True), t


# ---- the material's burrs tile by tile -------------------------------------------------------
#: the shipped HTS toric scene over a window where the machined surface has sharp edges
#: (the lenslets' rims): 161 x 201 pixels of 2.5 um
TORIC = Path(__file__).resolve().parents[1] / "scenes" / "hts_toric_msa.toml"
TORIC_WINDOW = (0.1, 0.1, 0.6, 0.5)


@pytest.fixture(scope="module")
def burr_case():
    from render_inspect.machining import cut_turning
    from render_inspect.processes import process_of
    from render_inspect.processes._mechanics import material_cut_path

    scene = load_scene(TORIC, [f"simulation.region={list(TORIC_WINDOW)}"])
    proc = process_of(scene)
    cfg = proc.inputs_of(scene)
    surface = make_surface(scene.design)
    env = proc.envelope(cfg, surface, proc.plan(cfg, surface, region=TORIC_WINDOW))
    cp = material_cut_path(env.path, Tool.from_config(cfg.tool), env.mechanics)
    pixel = cfg.simulation.pixel
    cut = cut_turning(cp, env.grooves, region=TORIC_WINDOW, pixel=pixel)
    return dict(env=env, cp=cp, surface=surface, pixel=pixel, cut=cut, resp=env.mechanics)


@pytest.mark.parametrize("texture", [False, True])
def test_tiles_with_the_burr_halo_equal_the_material_burrs_of_the_whole_map(burr_case, texture):
    """compute_tile with the material's burrs against material_burrs on the whole cut map
    (after the texture, as ``turn`` adds them), on every tile of 64 pixels: those at the
    grid's border too.  Without texture bit for bit; the texture's random modes are summed
    by a matrix product whose last bits depend on the grid's size, so with it to 1e-12."""
    from render_inspect.machining import compute_tile, material_burrs
    from render_inspect.processes._mechanics import add_texture

    c = burr_case
    env, pixel, origin = c["env"], c["pixel"], TORIC_WINDOW[:2]
    m = c["cut"]["machined"]
    if texture:
        m, _ = add_texture(m, c["resp"], TORIC_WINDOW, pixel, env.texture[2])
    whole, info = material_burrs(m, m, pixel=pixel, origin=origin, **env.burrs)
    assert info["edge_pixels"] > 50 and info["max_added_um"] > 0.01     # burrs there are
    shape = whole.shape
    sums = {"burr_edge_pixels": 0, "burr_turn_max": 0.0, "burr_height_max": 0.0, "burr_added_max": 0.0}
    tiles = plan_tiles(shape, 64)
    assert len(tiles) == 12
    for t in tiles:
        _, mt, part = compute_tile(c["cp"], c["surface"], origin, pixel, t, grooves=env.grooves, shape=shape,
                                   texture=env.texture if texture else None, burrs=env.burrs)
        ref = whole[t.row:t.row + t.rows, t.col:t.col + t.cols]
        if texture:
            assert_allclose(mt, ref, rtol=1e-12, atol=0), t
        else:
            assert np.array_equal(mt, ref, equal_nan=True), t
        sums["burr_edge_pixels"] += part["burr_edge_pixels"]
        for k in ("burr_turn_max", "burr_height_max", "burr_added_max"):
            sums[k] = max(sums[k], part[k])
    assert sums["burr_edge_pixels"] == info["edge_pixels"]
    assert math.degrees(sums["burr_turn_max"]) == pytest.approx(info["turn_max_deg"], rel=1e-12)
    assert sums["burr_height_max"] * MM_TO_UM == pytest.approx(info["height_max_um"], rel=1e-12)
    assert sums["burr_added_max"] * MM_TO_UM == pytest.approx(info["max_added_um"], rel=1e-12)


@pytest.mark.slow
def test_simulate_tiles_the_material_burrs_as_in_memory(tmp_path):
    """The shipped HTS scene over a window with machined edges, in memory and tile by tile:
    the same burr facts and heights."""
    import json

    win = ("--set", f"simulation.region={list(TORIC_WINDOW)}")
    _cli("simulate", TORIC, "--out", tmp_path / "mem", *win, "-q")
    _cli("simulate", TORIC, "--out", tmp_path / "tiled", *win, "--tiled", "--tile", "64", "-q")
    a, b = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in ("mem", "tiled"))
    assert a["burrs"]["edge_pixels"] > 50
    assert b["burrs"].keys() == a["burrs"].keys()
    for k, v in a["burrs"].items():
        assert b["burrs"][k] == (pytest.approx(v, rel=1e-12) if isinstance(v, float) else v), k
    for k in ("Sq_nm", "Sz_nm", "min_nm", "mean_nm"):
        assert b["residual"][k] == pytest.approx(a["residual"][k], rel=1e-12), k
    ch, _ = read_exr(tmp_path / "mem" / "heightmap.exr")
    assert_allclose(ZarrHeightMap(tmp_path / "tiled" / "heightmap.zarr").read("machined"), ch["machined"],
                    rtol=1e-6, atol=0)
