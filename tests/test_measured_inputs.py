"""Measured files at the edges: FRT row order, containers without heights, bounds on
heights and pixels, hostile Zarr stores and .npy headers, mostly empty maps, and the
filters a map can carry.  Each bad input is one InputError naming the file and the key,
never an allocation or a library's traceback."""

from __future__ import annotations

import json
import os
import shutil
import zipfile

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.core.errors import InputError, MemoryBudgetError
from render_inspect.io import read_surface, write_exr
from render_inspect.io._frt import FRT_INVALID, frt_bytes, reader_keeps_stored_order
from render_inspect.io._heightmap import grid_attrs
from render_inspect.io._zarr import write_heightmap_zarr
from render_inspect.metrology import analyze_map
from render_inspect.metrology._analysis import check_filter, filter_range, parse_filter


# ------------------------------------------------------------------ FRT rows
@pytest.mark.slow
def test_frt_rows_come_in_gwyddions_order(tmp_path):
    """An FRT raster whose stored rows differ (a ramp in y, a step in x, one point not
    measured) is read with the last stored row first, as Gwyddion's microprof module and
    SurfaceTopography from 1.27 read it, whichever SurfaceTopography is installed."""
    ny, nx = 6, 9
    counts = (1000 + 100 * np.arange(ny)[:, None] + 7 * (np.arange(nx)[None, :] >= 4)).astype(np.uint16)
    counts[0, 2] = FRT_INVALID  # not measured
    f = tmp_path / "a.frt"
    f.write_bytes(frt_bytes(counts, pixel_m=2e-6, zscale_m=1e-9))
    m = read_surface(f)
    assert m.shape == (ny, nx) and m.meta["row_order"].startswith("Gwyddion")
    assert_allclose(m.pixel, (2e-3, 2e-3), rtol=1e-12)
    expect = counts[::-1].astype(float) * 1e-6  # nm -> mm, last stored row first
    expect[counts[::-1] == FRT_INVALID] = np.nan
    assert_allclose(m.z, expect, rtol=1e-12, equal_nan=True)
    assert np.isnan(m.z[ny - 1, 2]) and m.meta["n_invalid"] == 1
    # SurfaceTopography 1.18 .. 1.22 give the stored order: the reader flips it then
    from SurfaceTopography.IO import FRTReader

    h = np.asarray(FRTReader(str(f)).topography().heights())
    assert reader_keeps_stored_order() == bool(h[0, 0] < h[0, -1])


# ------------------------------------------------------------------ empty containers
@pytest.mark.slow
def test_plux_without_a_height_layer_says_so(tmp_path):
    index = ("<xml><GENERAL><IMAGE_SIZE_X>4</IMAGE_SIZE_X><IMAGE_SIZE_Y>4</IMAGE_SIZE_Y>"
             "<FOV_X>1</FOV_X><FOV_Y>1</FOV_Y><DATE>2020-01-01</DATE></GENERAL></xml>")
    for name, members in (("nolayer", {"index.xml": index, "recipe.txt": "<xml/>"}),
                          ("norecipe", {"index.xml": index})):
        f = tmp_path / f"{name}.plux"
        with zipfile.ZipFile(f, "w") as z:
            for k, v in members.items():
                z.writestr(k, v)
        with pytest.raises(InputError, match=r"no height data"):
            read_surface(f)
    with zipfile.ZipFile(tmp_path / "empty.plux", "w"):
        pass
    with pytest.raises(InputError, match=r"not a Sensofar \.plux file \(no index\.xml"):
        read_surface(tmp_path / "empty.plux")


# ------------------------------------------------------------------ bounds
def _npy(tmp_path, name, z, pixel=0.001, units="mm"):
    f = tmp_path / f"{name}.npy"
    np.save(f, z)
    f.with_suffix(".json").write_text(json.dumps({"pixel_mm": pixel, "units": units}))
    return f


@pytest.mark.parametrize("z, pixel, match", [
    (np.full((20, 20), np.iinfo(np.uint64).max, dtype=np.uint64), 0.001,
     r"heights must lie within \+-10000 mm .*1\.84e\+19 mm"),
    (np.full((20, 20), 1e300), 0.001, r"heights must lie within .*1e\+300 mm"),
    (np.zeros((20, 20)), 1e300, r"pixel_x \(pixel_mm in the file\) must lie within 1e-07 \.\. 100 mm"),
    (np.zeros((20, 20)), 1e-12, r"pixel_x \(pixel_mm in the file\) must lie within"),
    (np.zeros((20, 2000)), 50.0, r"the field \(2000 x pixel_x = 1e\+05 mm\) must be at most"),
    (np.full((20, 20), np.nan), 0.001, r"no valid \(finite\) heights"),
])
def test_implausible_maps_are_refused_naming_the_value(tmp_path, z, pixel, match):
    with pytest.raises(InputError, match=match):
        read_surface(_npy(tmp_path, "m", z, pixel))


def test_exr_and_store_pixel_out_of_bounds_name_pixel_size_mm(tmp_path):
    z = np.zeros((8, 8), dtype=np.float32)
    f = write_exr(tmp_path / "m.exr", {"height": z}, {"pixel_size_mm": 1e300, "origin_mm": [0.0, 0.0]})
    with pytest.raises(InputError, match=r"pixel_size_mm in the file\) must lie within"):
        read_surface(f)
    store = write_heightmap_zarr(tmp_path / "s.zarr", z, z, chunk=8, attrs=grid_attrs(1e300, (0, 0), {}, {}))
    with pytest.raises(InputError, match=r"pixel_size_mm must lie within .*1e\+300"):
        read_surface(store)


def test_a_bool_shape_in_a_npy_header_is_refused(tmp_path):
    f = _npy(tmp_path, "m", np.zeros((8, 8)))
    f.write_bytes(f.read_bytes().replace(b"(8, 8)", b"(True, True)"))
    with pytest.raises(InputError, match=r"shape must be non-negative integers, received \(True, True\)"):
        read_surface(f)


# ------------------------------------------------------------------ hostile stores
def _store(tmp_path, name="s.zarr", shape=(64, 64), chunk=32):
    z = np.random.default_rng(0).normal(0, 1e-5, shape)
    return write_heightmap_zarr(tmp_path / name, z, z, chunk=chunk, levels=0,
                                attrs=grid_attrs(0.001, (0.0, 0.0), {}, {}))


def _edit(store, fn):
    for ch in ("design", "machined", "residual"):
        p = store / ch / "zarr.json"
        d = json.loads(p.read_text())
        fn(d, store / ch)
        p.write_text(json.dumps(d))


def _declare_huge_chunk(d, folder):
    d["shape"] = [40000, 40000]
    d["chunk_grid"]["configuration"]["chunk_shape"] = [40000, 40000]
    shutil.rmtree(folder / "c")


@pytest.mark.parametrize("edit, match", [
    (lambda d, f: d["chunk_grid"]["configuration"].update(chunk_shape=[0, 0]),
     r"chunk_shape must be two whole numbers >= 1, received \[0, 0\]"),
    (lambda d, f: d.update(data_type="string", fill_value=""),
     r"array 'design' must hold real numbers .*'string'"),
    (lambda d, f: d.update(data_type="complex128", fill_value=[0.0, 0.0]),
     r"holds complex numbers \(complex128\); a height map must be real"),
    (_declare_huge_chunk, r"a chunk of 40000 x 40000 values decodes to 6104 MiB, more than the 1024 MiB"),
])
def test_hostile_zarr_metadata_is_refused_before_reading(tmp_path, edit, match):
    store = _store(tmp_path)
    _edit(store, edit)
    with pytest.raises(InputError, match=match):
        read_surface(store)


def test_zarr_chunks_that_are_links_damaged_or_oversized_are_refused(tmp_path):
    store = _store(tmp_path)
    chunk = store / "machined" / "c" / "0" / "0"
    chunk.write_bytes(b"garbage" * 10)
    with pytest.raises(InputError, match=r"array 'machined' cannot be read \(a damaged chunk"):
        read_surface(store)
    chunk.unlink()
    os.symlink("/dev/zero", chunk)
    with pytest.raises(InputError, match=r"'machined/c/0/0' is a symbolic link.*refused"):
        read_surface(store)
    chunk.unlink()
    chunk.write_bytes(b"\0" * (2 * 32 * 32 * 4 + 2 ** 17))
    with pytest.raises(InputError, match=r"'machined/c/0/0' holds \d+ bytes, more than a chunk"):
        read_surface(store)


# ------------------------------------------------------------------ mostly empty, filters
def test_a_mostly_unmeasured_map_gets_a_warning():
    z = np.random.default_rng(1).normal(0, 1e-5, (60, 60))
    z[:, :53] = np.nan  # 88 % not measured
    m = analyze_map(z, pixel=0.001, form="none").metrics
    assert any(w.startswith("88% of the map is not measured (more than 50%)") for w in m["warnings"])
    z = np.random.default_rng(2).normal(0, 1e-5, (60, 60))
    z[:, :20] = np.nan  # 33 %: below the threshold
    assert not any("not measured" in w for w in
                   analyze_map(z, pixel=0.001, form="none").metrics["warnings"])


def test_filters_the_map_cannot_carry_are_refused_naming_the_unit():
    shape, pixel = (1000, 1000), 0.001          # a 1 mm map of 1 um pixels
    assert filter_range(pixel, shape) == (0.002, 1.0)
    with pytest.raises(InputError) as e:
        check_filter(*parse_filter("2.5,800"), pixel=pixel, shape=shape)
    msg = str(e.value)
    assert msg.startswith("--filter S must lie within 0.002 .. 1 mm") and "received 2.5 mm" in msg
    assert "looks like micrometres: --filter 0.0025,0.8 (mm) was probably meant" in msg
    for spec, part in (("1e-9,1e300", "S"), (",1e308", "L"), ("0.0025,1.5", "L"),
                       ("0.001,0.5", "S")):
        with pytest.raises(InputError, match=rf"^--filter {part} must lie within 0\.002 \.\. 1 mm.*received"):
            check_filter(*parse_filter(spec), pixel=pixel, shape=shape)
    check_filter(*parse_filter("0.0025,0.8"), pixel=pixel, shape=shape)
    for spec in ("1,2,3", "a,b", "nan,1", ",inf", "-1,2", "1,0.5"):
        with pytest.raises(InputError, match="^--filter"):
            parse_filter(spec)


def test_analyze_map_refuses_a_map_its_memory_cannot_hold():
    z = np.random.default_rng(0).normal(0, 1e-5, (200, 200))
    with pytest.raises(MemoryBudgetError, match=r"analysing a 200 x 200 map would need about .* crop or resample"):
        analyze_map(z, pixel=0.001, budget=2 ** 20)


def test_frames_without_a_finite_pixel_are_refused():
    from render_inspect.io._limits import check_frames

    frames = np.random.default_rng(0).random((4, 6, 7))
    frames[2, 1, 1] = np.nan
    valid = np.ones((6, 7), bool)
    valid[0, 0] = False
    usable = check_frames(frames, valid, what="frames", path="f.exr")
    assert not usable[1, 1] and not usable[0, 0] and usable.sum() == 40
    with pytest.raises(InputError, match=r"frames 'f.exr' has no pixel with a finite intensity in "
                                         r"every frame \(42 of 42 pixels"):
        check_frames(np.full((4, 6, 7), np.nan), None, what="frames", path="f.exr")


# ------------------------------------------------------------------ Digital Surf z offset
@pytest.mark.parametrize("unit,to_mm", [("mm", 1.0), ("nm", 1e-6), ("m", 1e3), ("µm", 1e-3)])
def test_sur_heights_carry_the_z_offset_in_the_unit_of_the_z_step(tmp_path, unit, to_mm):
    """A .sur height is count x z step + z offset, both in the z step's unit (Gwyddion):
    a tilted sinusoid written with an offset of 0.25 mm in each unit comes back to the
    nanometre, its missing point as NaN (surfalize alone adds the offset as micrometres)."""
    from render_inspect.io._sur import sur_bytes

    ny, nx = 12, 17
    yy, xx = np.mgrid[0:ny, 0:nx]
    counts = np.round(20000 * np.sin(2 * np.pi * xx / 8.0) + 300 * yy).astype(np.int64)
    measured = np.ones((ny, nx), bool)
    measured[4, 5] = False
    step_mm, offset_mm = 1e-6, 0.25  # 1 nm per count
    f = tmp_path / "a.sur"
    f.write_bytes(sur_bytes(counts, pixel=(2e-3 / to_mm, 3e-3 / to_mm), z_step=step_mm / to_mm,
                            unit=unit, z_offset=offset_mm / to_mm, measured=measured))
    m = read_surface(f)
    expect = np.where(measured, counts * step_mm + offset_mm, np.nan)
    assert_allclose(m.z, expect, atol=2e-8, rtol=0, equal_nan=True)  # float32 step, offset
    assert_allclose(m.pixel, (2e-3, 3e-3), rtol=1e-6)
    assert m.meta["n_invalid"] == 1 and m.meta["z_offset_in_file"]["unit"] == unit


def test_sur_without_offset_reads_as_before_and_an_inverted_header_is_said(tmp_path):
    from render_inspect.io._sur import sur_bytes

    counts = np.arange(30, dtype=np.int64).reshape(5, 6) * 1000
    f = tmp_path / "b.sur"
    f.write_bytes(sur_bytes(counts, pixel=(1e-3, 1e-3), z_step=1e-6, unit="mm"))
    m = read_surface(f)
    assert_allclose(m.z, counts * 1e-6, atol=5e-9, rtol=0)
    assert "z_offset_in_file" not in m.meta and not m.meta.get("warnings")
    f.write_bytes(sur_bytes(counts, pixel=(1e-3, 1e-3), z_step=1e-6, unit="mm", inverted=1))
    m = read_surface(f)
    assert any("marks its heights as inverted (code 1)" in w for w in m.meta["warnings"])
