"""The height-map store (``heightmap.zarr``) as other tools read it, and the commands that
read a store: named dimensions and millimetre coordinates (what ``xarray.open_zarr``
needs), OME-NGFF multiscales metadata that place every pyramid level; ``analyze`` of a
store too large for the memory budget, window by window, equal to the whole-map
analysis; ``render`` into a ``simulate`` folder reading its store."""

from __future__ import annotations

import json

import numpy as np
import pytest

from render_inspect.core.errors import InputError, MemoryBudgetError
from render_inspect.io import ZarrHeightMap, grid_attrs
from render_inspect.io._pyramid import pyramid
from render_inspect.io._zarr import write_heightmap_zarr
from render_inspect.metrology import analyze_bands, analyze_map
from render_inspect.pipeline import run_analyze

GIB = 2 ** 30


def _surface(ny=300, nx=420, *, holes=True, seed=3):
    """Tilt, a parabola, feed marks and noise (mm), with a hole and a missing corner."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:ny, 0:nx] * 0.001
    z = (1e-4 * x + 2e-4 * y + 3e-3 * (x - 0.1) ** 2 + 1e-5 * np.sin(2 * np.pi * x / 0.02)
         + 4e-6 * np.cos(2 * np.pi * y / 0.05) + rng.normal(0, 2e-6, (ny, nx)))
    if holes:
        z[50:60, 70:90] = np.nan
        z[ny - 2, 5] = np.nan
        z[:3, -4:] = np.nan
    return z


def _store(tmp_path, z, *, name="h.zarr", chunk=64, levels=3, origin=(1.0, -2.0), pixel=0.001):
    return write_heightmap_zarr(tmp_path / name, np.zeros_like(z), z, chunk=chunk, levels=levels,
                                attrs=grid_attrs(pixel, origin, {"name": "t"}, {}))


# ------------------------------------------------------------------ the store's layout
def test_store_has_named_dimensions_mm_coordinates_and_ome_multiscales(tmp_path):
    import zarr

    z = _surface(holes=False)
    path = _store(tmp_path, z)
    g = zarr.open_group(str(path), mode="r")
    for k in range(0, 4):
        grp = g if k == 0 else g[f"levels/{k}"]
        f = 1 << k
        for name in ("design", "machined", "residual"):
            a = grp[name]
            assert a.metadata.dimension_names == ("y", "x") and a.attrs["units"] == "mm"
        x, y = grp["x"][:], grp["y"][:]
        assert grp["x"].metadata.dimension_names == ("x",) and grp["x"].attrs["units"] == "mm"
        assert x.size == grp["machined"].shape[1] and y.size == grp["machined"].shape[0]
        # pixel centres: origin + ((F - 1) / 2 + i F) pixel
        np.testing.assert_allclose(x, 1.0 + ((f - 1) / 2 + np.arange(x.size) * f) * 0.001, rtol=0,
                                   atol=1e-12)
        np.testing.assert_allclose(y, -2.0 + ((f - 1) / 2 + np.arange(y.size) * f) * 0.001,
                                   rtol=0, atol=1e-12)
    ome = g.attrs["ome"]
    assert ome["version"] == "0.5" and [m["name"] for m in ome["multiscales"]] == \
        ["design", "machined", "residual"]
    ms = ome["multiscales"][1]
    assert [a["name"] for a in ms["axes"]] == ["y", "x"]
    assert all(a["type"] == "space" and a["unit"] == "millimeter" for a in ms["axes"])
    assert [d["path"] for d in ms["datasets"]] == ["machined", "levels/1/machined",
                                                   "levels/2/machined", "levels/3/machined"]
    means = pyramid(z, 3)
    for k, d in enumerate(ms["datasets"]):
        (scale,), (shift,) = ([t[key] for t in d["coordinateTransformations"] if t["type"] == key]
                              for key in ("scale", "translation"))
        arr = g[d["path"]]
        # the transformation places each level's pixels where its coordinates say
        assert scale == pytest.approx([0.001 * 2 ** k] * 2)
        assert shift[1] == pytest.approx(float(g["x"][:1][0] if k == 0 else
                                               g[f"levels/{k}/x"][:1][0]))
        if k:
            np.testing.assert_array_equal(arr[:], means[k - 1])
    # a store written by an earlier version (no coordinates) still reads
    assert ZarrHeightMap(path).read("machined").shape == z.shape


def test_xarray_opens_the_store_with_coordinates(tmp_path):
    import xarray as xr  # in the lock: a missing one fails
    z = _surface(holes=False)
    path = _store(tmp_path, z)
    ds = xr.open_zarr(path)
    assert set(ds.data_vars) == {"design", "machined", "residual"}
    assert ds.machined.dims == ("y", "x") and ds.x.attrs["units"] == "mm"
    v = ds.machined.sel(x=1.25, y=-1.9, method="nearest").values
    assert v == np.float32(z[100, 250])
    lv = xr.open_zarr(path, group="levels/2")
    assert lv.machined.shape == (75, 105) and float(lv.x[0]) == pytest.approx(1.0015)


# ------------------------------------------------------------------ analyze window by window
@pytest.mark.parametrize("form", ["none", "plane", "poly2"])
@pytest.mark.parametrize("slope", ["forward", "central"])
def test_bands_give_the_whole_maps_parameters(form, slope):
    z = _surface()
    whole = analyze_map(z, pixel=0.001, form=form, slope=slope).metrics
    for rows in (2, 7, 64, 1000):
        got = analyze_bands(lambda r0, r1: z[r0:r1], z.shape, pixel=0.001, form=form, slope=slope,
                            band_rows=rows).metrics
        for k in ("Sa_nm", "Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "Ssk", "Sku", "Sdq"):
            assert got["areal"][k] == pytest.approx(whole["areal"][k], rel=1e-12), (k, rows)
        # Sdr is a small difference of area ratios: equal to 1e-12 of the ratio itself
        assert got["areal"]["Sdr_percent"] == pytest.approx(whole["areal"]["Sdr_percent"],
                                                            abs=1e-10)
        assert got["n_valid"] == whole["n_valid"]
        if slope == "forward":
            for k in ("n_border_gradients", "Sdq_with_border"):
                assert got["holes"][k] == pytest.approx(whole["holes"][k], rel=1e-12)


def test_analyze_of_a_store_over_the_budget_goes_window_by_window(tmp_path):
    z = _surface(600, 700)
    path = _store(tmp_path, z, chunk=128, levels=2)
    whole = run_analyze(path, tmp_path / "a", slope="forward")
    budget = (120 * 2 ** 20, "a test budget")
    got = run_analyze(path, tmp_path / "b", budget=budget)
    assert "windowed" not in whole and got["windowed"]["bands"] > 1
    assert got["windowed"]["band_rows"] % 128 == 0 or got["windowed"]["band_rows"] < 128
    for k in ("Sa_nm", "Sq_nm", "Sz_nm", "Ssk", "Sku", "Sdq"):
        assert got["areal"][k] == pytest.approx(whole["areal"][k], rel=1e-9), k
    assert got["input"]["format"] == "zarr" and got["input"]["channel"] == "machined"
    assert any("window by window" in w for w in got["warnings"])
    assert (tmp_path / "b" / "metrics.json").is_file()
    # what needs the whole map is refused up front, saying why and what works
    for kw, why in (({"form": "sphere"}, "--form sphere"), ({"filter_spec": ",0.2"}, "--filter"),
                    ({"outliers": "sigma"}, "--outliers sigma"), ({"x3p": True}, "--x3p")):
        with pytest.raises(MemoryBudgetError, match=f"with {why}.*needs the whole map in "
                                                    f"memory.*window by window"):
            run_analyze(path, tmp_path / "c", budget=budget, **kw)
    assert not (tmp_path / "c").exists()


def test_a_large_store_goes_window_by_window_whatever_the_budget(tmp_path, monkeypatch):
    """A store whose whole-map analysis would need more than the store limit is analysed
    window by window even with room to spare in the budget (its memory stays that of a
    few bands), with the whole map's parameters; options that need the whole map still
    run in memory when the budget holds them."""
    from render_inspect.pipeline import _analyze

    z = _surface(600, 700)
    path = _store(tmp_path, z, chunk=128, levels=2)
    roomy = (64 * GIB, "a roomy test budget")
    whole = run_analyze(path, tmp_path / "a", form="poly2", budget=roomy)
    assert "windowed" not in whole
    monkeypatch.setattr(_analyze, "STORE_WHOLE_MAP_BYTES", 4 * 2 ** 20)
    monkeypatch.setattr(_analyze, "WINDOW_BYTES", 13 * 2 ** 20)  # bands of 128 rows
    got = run_analyze(path, tmp_path / "b", form="poly2", budget=roomy)
    assert got["windowed"]["band_rows"] == 128 and got["windowed"]["bands"] == 5
    # a map too wide for a row of chunks in a band: bands of part of a row of chunks
    monkeypatch.setattr(_analyze, "WINDOW_BYTES", 5 * 2 ** 20)
    part = run_analyze(path, tmp_path / "p", form="poly2", budget=roomy)
    assert part["windowed"]["band_rows"] == 42
    for k in ("Sq_nm", "Sz_nm", "Sdq", "Sdr_percent"):
        assert part["areal"][k] == pytest.approx(got["areal"][k], rel=1e-12), k
    assert got["windowed"]["whole_map_limit_bytes"] == 4 * 2 ** 20
    for k in ("Sa_nm", "Sq_nm", "Sz_nm", "Sp_nm", "Sv_nm", "Ssk", "Sku", "Sdq"):
        assert got["areal"][k] == pytest.approx(whole["areal"][k], rel=1e-9), k
    assert got["n_valid"] == whole["n_valid"]
    # the periods come from the coarse view, which says its sampling
    assert got["periods"]["seen_at_mm"] == pytest.approx(0.002)
    assert got["periods"]["dominant"]["period_mm"] == pytest.approx(
        whole["periods"]["dominant"]["period_mm"], rel=0.05)
    # a sphere needs the whole map: done in memory, not refused, while the budget holds it
    sph = run_analyze(path, tmp_path / "c", form="sphere", budget=roomy)
    assert "windowed" not in sph and sph["form"]["method"] == "sphere"


def test_sal_from_a_pyramid_level_only_when_resolved(tmp_path):
    """A lay of 60 um period seen through level 1 (2 um): Sal is given, from that level,
    and equals the whole map's within the coarser sampling; white noise at level 3 is not
    resolved: Sal is None, and the warning says why."""
    ny, nx = 512, 512
    y, x = np.mgrid[0:ny, 0:nx] * 0.001
    lay = 5e-6 * np.sin(2 * np.pi * (x + 0.3 * y) / 0.06)
    path = _store(tmp_path, lay, chunk=128, levels=3)
    whole = run_analyze(path, tmp_path / "a", form="none")
    zc = ZarrHeightMap(path).read("machined", level=1)
    got = analyze_bands(lambda r0, r1: lay[r0:r1], lay.shape, pixel=0.001, form="none",
                        band_rows=100, spatial=(zc, 2, "level 1")).metrics
    assert got["spatial"]["source"] == "level 1"
    assert got["areal"]["Sal_mm"] == pytest.approx(whole["areal"]["Sal_mm"], rel=0.05)
    noise = np.random.default_rng(0).normal(0, 1e-6, (ny, nx))
    coarse = noise.reshape(64, 8, 64, 8).mean(axis=(1, 3))
    got = analyze_bands(lambda r0, r1: noise[r0:r1], noise.shape, pixel=0.001, form="none",
                        band_rows=100, spatial=(coarse, 8, "level 3")).metrics
    assert got["areal"]["Sal_mm"] is None and got["areal"]["Str"] is None
    assert any("too short to resolve" in w for w in got["warnings"])


def test_analyze_refuses_a_file_too_large_before_reading_it(tmp_path, capsys):
    """The memory check comes before the read, with analyze's own advice (no scene key:
    analyze has no --set)."""
    from render_inspect.cli import main as cli_main

    z = _surface(200, 200, holes=False)
    f = tmp_path / "m.npy"
    np.save(f, z)
    (tmp_path / "m.json").write_text(json.dumps({"pixel_mm": 0.001}))
    with pytest.raises(MemoryBudgetError) as err:
        run_analyze(f, tmp_path / "o", budget=(64 * 2 ** 20, "a test budget"))
    assert "analysing a 200 x 200 map" in str(err.value) and "a test budget" in str(err.value)
    monkey = pytest.MonkeyPatch()
    try:
        import render_inspect.pipeline._analyze as an

        monkey.setattr(an, "memory_budget", lambda _: (10 * 2 ** 20, "80% of the memory available "
                                                       "now, 12 MiB; set simulation.max_memory_gb "
                                                       "to choose"))
        rc = cli_main(["analyze", str(f), "--out", str(tmp_path / "o")])
    finally:
        monkey.undo()
    err = capsys.readouterr().err
    assert rc == 1 and "max_memory_gb" not in err and "--set" not in err, err
    assert "crop or resample" in err
    assert not (tmp_path / "o").exists()
    with pytest.raises(InputError, match="holds the input"):
        run_analyze(f, tmp_path)  # --out holding the input would delete it


# ------------------------------------------------------------------ render on a store
@pytest.mark.mitsuba
def test_render_reads_the_store_simulate_wrote_whatever_the_budget(tmp_path):
    """A ``simulate --tiled`` folder of a map that fits in memory: ``render`` reads its
    store (the windows it needs) instead of simulating again, also with another
    simulation.max_memory_gb (the budget is no part of the folder's identity)."""
    from render_inspect.pipeline import run_render, run_simulate
    from render_inspect.scene import load_scene

    over = ["machine.preset='ideal'", "material.preset='ideal'",
            "simulation.region=[-0.1,-0.1,0.1,0.1]", "render.interferometer.objective='50x'"]
    out = tmp_path / "part"
    run_simulate(load_scene("sts_sinusoidal_grid", over), out, tiled=True)
    res = run_render(load_scene("sts_sinusoidal_grid", over + ["simulation.max_memory_gb=3"]), out,
                     kind="interferometer")
    assert res["render"]["big_map"]["read"]["interferometer"]["shape"] == [201, 201]
    names = {p.name for p in out.iterdir()}
    assert {"heightmap.zarr", "interferogram.exr", "metrics.json"} <= names
    # another part in that folder is still refused
    with pytest.raises(InputError, match="of a different part"):
        run_render(load_scene("sts_sinusoidal_grid", over + ["tool.nose_radius=0.4"]), out,
                   kind="interferometer")


def test_a_store_that_lost_chunks_since_it_was_written_is_refused(tmp_path):
    """zarr reads a missing chunk as empty (NaN): a store cut short would pass for a map
    with unmeasured points.  The chunk files are counted when the store is written and
    again when it is read."""
    # a chunk that is all NaN (a corner the tool never reached) is not written: the count
    # made when the store is complete holds as it is
    z = np.random.default_rng(1).normal(size=(128, 128)) * 1e-6
    z[:32, :32] = np.nan
    corner = _store(tmp_path, z, name="corner.zarr", chunk=32)
    assert ZarrHeightMap(corner).shape == (128, 128)
    path = _store(tmp_path, np.random.default_rng(1).normal(size=(128, 128)) * 1e-6, chunk=32)
    assert ZarrHeightMap(path).shape == (128, 128)
    chunk = next(p for p in sorted((path / "machined" / "c").rglob("*")) if p.is_file())
    chunk.unlink()
    with pytest.raises(InputError, match=r"array 'machined' holds 15 chunk files, 16 when the "
                                         r"store was written: chunks are missing"):
        ZarrHeightMap(path)
