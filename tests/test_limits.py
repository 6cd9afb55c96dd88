"""Memory: estimates before allocating, measured against what is really allocated
(tracemalloc sees numpy's buffers), refusals that name the parameter and how far to
change it, readers that check declared sizes before loading, and renderer limits."""

from __future__ import annotations

import io
import os
import re
import struct
import tracemalloc
import zipfile

import numpy as np
import pytest

from render_inspect.core.limits import (
    AUTO_FRACTION,
    Driver,
    available_memory,
    check_memory,
    format_bytes,
    memory_budget,
)
from render_inspect.design import make_surface
from render_inspect.errors import InputError, MemoryBudgetError, SceneError
from render_inspect.io import (
    check_npy,
    export_program,
    read_exr,
    read_measured,
    read_x3p,
    write_exr,
    write_x3p,
)
from render_inspect.pipeline import check_render_limits, plan_program
from render_inspect.processes import process_of
from render_inspect.render import mitsuba_seed, render_passes
from render_inspect.scene import load_scene
from render_inspect.toolpath import plan_memory, turning_point_count

#: within this factor of the measured peak
FACTOR = 1.5


def _traced(fn):
    tracemalloc.start()
    try:
        out = fn()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return out, peak


def _no_long_numbers(msg: str):
    assert not re.search(r"\d{13,}", msg), msg
    assert len(msg) < 700, msg


# ------------------------------------------------------------------ budget
def test_default_budget_follows_the_available_memory():
    b, source = memory_budget(None)
    avail = available_memory()
    assert 0.5 * AUTO_FRACTION * avail < b < 1.5 * AUTO_FRACTION * avail
    assert "set simulation.max_memory_gb" in source
    assert memory_budget(2.0) == (2 * 2 ** 30, "simulation.max_memory_gb = 2")


def test_refusal_names_the_driver_and_the_value_that_fits():
    with pytest.raises(MemoryBudgetError) as e:
        check_memory(1e300, what="the thing", budget=(2 ** 30, "test"),
                     drivers=[Driver("process.points_per_rev", 1e7, 1),
                              Driver("simulation.pixel", 1e-6, -2, "mm")])
    msg = str(e.value)
    assert "process.points_per_rev <= " in msg and "simulation.pixel >= " in msg
    assert "TiB" in msg and "now 1e+07" in msg
    _no_long_numbers(msg)
    assert format_bytes(float("inf")) == "an unbounded amount of memory"


# ------------------------------------------------------------------ tool paths
@pytest.mark.parametrize("over", [
    [],
    ["process.compensation='normal'"],
    ["process.sampling='constant_arc'", "process.arc_length=0.002"],
    ["process.sampling='constant_arc'", "process.arc_length=0.002", "process.compensation='normal'"],
    ["process.sampling='hybrid'", "process.arc_length=0.002", "process.switch_radius=0.5"],
])
def test_toolpath_estimate_is_within_a_factor_of_the_measured_peak(over):
    """A path of about a million points: the estimate the planner checks before
    allocating against tracemalloc's peak of the whole plan (program + facts +
    kinematics)."""
    scene = load_scene("sts_sinusoidal_grid", over + ["process.workpiece_radius=1.5",
                                                      "process.points_per_rev=7200"])
    p = scene.process
    plan_program(scene.with_overrides(["process.workpiece_radius=0.1"]))  # compile first
    plan, peak = _traced(lambda: plan_program(scene))
    n_est = turning_point_count(sampling=p.sampling, feed_per_rev=p.feed_per_rev,
                                workpiece_radius=p.workpiece_radius, r_in=0.0,
                                r_out=p.workpiece_radius, inner_radius=p.inner_radius,
                                points_per_rev=p.points_per_rev, arc_length=p.arc_length,
                                switch_radius=p.switch_radius, parts=True)
    assert plan.program.points <= sum(n_est) < 1.1 * plan.program.points + 100
    est = plan_memory(n_est, sampling=p.sampling, compensation=p.compensation)
    assert plan.program.points > 3e5
    assert peak / FACTOR <= est <= peak * FACTOR, (est, peak)


@pytest.mark.slow
def test_writers_stream_the_program(tmp_path):
    """NC and CSV writers hold a chunk of text, not the whole program: the writers' peak
    does not grow when the program doubles, and stays below the size of the text."""
    progs = [plan_program(load_scene("sts_sinusoidal_grid", [f"process.workpiece_radius={r}"])
                          ).program for r in (0.25, 0.5)]
    assert progs[1].points > 1.9 * progs[0].points
    for fmt in ("nc", "csv"):
        peaks = [_traced(lambda: export_program(p, tmp_path / fmt, fmt=fmt))[1] for p in progs]
        text = (tmp_path / fmt / f"toolpath.{fmt}").stat().st_size
        assert peaks[1] < 1.2 * peaks[0] + 2 ** 20 and peaks[1] < text, (fmt, peaks, text)
    # npz: numpy copies each array into the archive in pieces of at most 16 MiB
    _, peak = _traced(lambda: export_program(progs[1], tmp_path / "npz", fmt="npz"))
    assert peak < 17 * 2 ** 20


@pytest.mark.parametrize("over, key", [
    (["process.points_per_rev=10000000"], "process.points_per_rev <= "),
    (["process.chordal_tolerance=1e-12"], "process.chordal_tolerance >= "),
    (["process.feed_mm_per_min=1e-6"], "process.feed_mm_per_min >= "),
    (["process.sampling='constant_arc'", "process.arc_length=1e-9"], "process.arc_length >= "),
    (["process.sampling='hybrid'", "process.arc_length=1e-9"], "process.arc_length >= "),
])
def test_toolpath_refused_before_allocating_naming_the_parameter(over, key):
    scene = load_scene("sts_sinusoidal_grid", over + ["simulation.max_memory_gb=1"])
    with pytest.raises(MemoryBudgetError) as e:
        _, peak = _traced(lambda: plan_program(scene))
    msg = str(e.value)
    assert key in msg and "simulation.max_memory_gb = 1" in msg
    _no_long_numbers(msg)


def test_chordal_tolerance_raising_the_points_is_checked_in_the_planner():
    """The pre-check passes (3600 points per revolution fit); the tolerance then asks for
    far more, and the planner refuses before allocating, naming the tolerance."""
    scene = load_scene("sts_sinusoidal_grid", ["process.chordal_tolerance=1e-13",
                                               "simulation.max_memory_gb=0.5"])
    kind = process_of(scene)
    cfg = kind.inputs_of(scene)
    kind.precheck(cfg, None)  # fits
    surface = make_surface(scene.design)
    with pytest.raises(MemoryBudgetError, match=r"chordal_tolerance = 1e-13 mm sets .* points "
                                                r"per revolution") as e:
        _, peak = _traced(lambda: kind.plan(cfg, surface, region=None))
    assert "process.chordal_tolerance >= " in str(e.value)


def test_sculpturing_program_is_checked_before_planning():
    scene = load_scene("sculpt_quad_mla", ["process.arc_length=1e-12"])
    with pytest.raises(MemoryBudgetError, match=r"process.arc_length >= "):
        plan_program(scene)


@pytest.mark.slow
def test_simulation_grid_refusal_names_the_pixel():
    from render_inspect.pipeline import simulate

    scene = load_scene("sts_sinusoidal_grid", ["simulation.region=[-5,-5,5,5]",
                                               "simulation.pixel=0.0001",
                                               "simulation.max_memory_gb=1"])
    with pytest.raises(MemoryBudgetError, match=r"simulation.pixel >= .* or shrink simulation.region"):
        simulate(scene)


# ------------------------------------------------------------------ readers
def _npy_header(shape, descr="<f8") -> bytes:
    head = repr({"descr": descr, "fortran_order": False, "shape": shape}).encode()
    head += b" " * (63 - (10 + len(head)) % 64) + b"\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(head)) + head


def test_npy_header_claiming_terabytes_is_refused_without_allocating(tmp_path):
    f = tmp_path / "huge.npy"
    f.write_bytes(_npy_header((10 ** 6, 10 ** 6)) + b"\0" * 64)
    (tmp_path / "huge.json").write_text('{"pixel_mm": 0.001}')
    with pytest.raises(MemoryBudgetError, match=r"declares a 1e\+06 x 1e\+06 array") as e:
        _, peak = _traced(lambda: read_measured(f))
    _no_long_numbers(str(e.value))
    f.write_bytes(_npy_header((1000, 1000)) + b"\0" * 64)  # fits, but truncated
    with pytest.raises(InputError, match="truncated"):
        read_measured(f)


@pytest.mark.parametrize("content, why", [
    (b"", "not a .npy array"),
    (b"garbage" * 10, "not a .npy array"),
    (_npy_header((4, 4), "|O") + b"\x80\x04K\x01." * 10, "pickle"),
    (_npy_header((4, 4), "<c16") + b"\0" * 256, "complex"),
    (_npy_header((4, 4), "<U3") + b"\0" * 256, "real numbers"),
    (_npy_header((4,)) + b"\0" * 32, "2-D"),
    (b"\x93NUMPY\x01\x00\x10\x00{'descr': 'x'", "header"),
])
def test_bad_npy_files_are_input_errors(tmp_path, content, why):
    f = tmp_path / "z.npy"
    f.write_bytes(content)
    with pytest.raises(InputError, match=why):
        check_npy(f, what="design.path")
    (tmp_path / "z.json").write_text('{"pixel_mm": 0.001}')
    with pytest.raises(InputError):
        read_measured(f)


def _zip_bomb(path, size: int):
    """An X3P-shaped archive whose data member is ``size`` zero bytes, deflated."""
    main = (b"<?xml version='1.0'?><ISO5436_2><Record3><MatrixDimension><SizeX>16</SizeX>"
            b"<SizeY>16</SizeY><SizeZ>1</SizeZ></MatrixDimension></Record3></ISO5436_2>")
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("main.xml", main)
        with zf.open("bindata/data.bin", "w", force_zip64=True) as fh:
            chunk = b"\0" * 2 ** 20
            for _ in range(size // len(chunk)):
                fh.write(chunk)


def test_x3p_zip_bomb_is_refused_before_decompressing(tmp_path):
    f = tmp_path / "bomb.x3p"
    _zip_bomb(f, 256 * 2 ** 20)
    assert f.stat().st_size < 2 ** 20
    with pytest.raises(InputError, match="zip bomb") as e:
        _, peak = _traced(lambda: read_x3p(f))
    assert "256 MiB" in str(e.value)
    _, peak = _traced(lambda: pytest.raises(InputError, read_measured, f))
    assert peak < 32 * 2 ** 20


def test_x3p_declared_grid_beyond_the_budget_is_refused(tmp_path):
    z = np.zeros((8, 8))
    f = write_x3p(tmp_path / "a.x3p", z, pixel=0.001)
    data = f.read_bytes()
    zin = zipfile.ZipFile(io.BytesIO(data))
    main = zin.read("main.xml").replace(b"<SizeX>8</SizeX>", b"<SizeX>1000000</SizeX>")
    main = main.replace(b"<SizeY>8</SizeY>", b"<SizeY>1000000</SizeY>")
    g = tmp_path / "big.x3p"
    with zipfile.ZipFile(g, "w") as zout:
        for i in zin.infolist():
            zout.writestr(i, main if i.filename == "main.xml" else zin.read(i))
    with pytest.raises(MemoryBudgetError, match="1000000 x 1000000"):
        read_x3p(g)


def _small_budget(monkeypatch, nbytes: int):
    """Make the automatic budget (a share of the available memory) ``nbytes``."""
    import render_inspect.core.limits as L

    monkeypatch.setattr(L, "available_memory", lambda: int(nbytes / AUTO_FRACTION))


def _tmd(path, rows: int, cols: int) -> None:
    """A TrueMap .tmd file (GelSight's layout) of zeros."""
    head = b"Binary TrueMap Data File v2.0\r\n\x00" + b"\x00"
    head += struct.pack("<2I4f", cols, rows, 0.001 * cols, 0.001 * rows, 0.0, 0.0)
    path.write_bytes(head + np.zeros(rows * cols, dtype="<f4").tobytes())


def test_measured_files_read_whole_are_refused_by_their_size(tmp_path, monkeypatch):
    from render_inspect.io import read_surface

    f = tmp_path / "m.tmd"
    _tmd(f, 400, 500)
    assert read_surface(f).shape == (400, 500)
    _small_budget(monkeypatch, 2 ** 20)     # 200 000 values need about 5 MiB to read
    with pytest.raises(MemoryBudgetError, match=r"m.tmd.*memory budget of 1 MiB"):
        _traced(lambda: read_surface(f))
    _, peak = _traced(lambda: pytest.raises(MemoryBudgetError, read_surface, f))
    assert peak < 2 ** 20                    # refused before the file was read


def test_zarr_window_and_frame_stack_are_checked_before_reading(tmp_path, monkeypatch):
    from PIL import Image

    from render_inspect.io import read_frame_stack, read_surface
    from render_inspect.io._heightmap import grid_attrs
    from render_inspect.io._zarr import write_heightmap_zarr

    z = np.zeros((300, 400))
    store = write_heightmap_zarr(tmp_path / "heightmap.zarr", z, z, chunk=128,
                                 attrs=grid_attrs(0.001, (0.0, 0.0), {}, {}))
    assert read_surface(store).shape == (300, 400)
    assert read_surface(store, region=(0, 0, 0.0495, 0.0495)).shape == (50, 50)
    stack = tmp_path / "frames"
    stack.mkdir()
    for i in range(4):
        Image.fromarray(np.full((300, 400), 60 * i, dtype=np.uint8)).save(stack / f"f{i}.png")
    (stack / "settings.json").write_text('{"mode": "psi", "pixel_size_mm": 0.001, '
                                         '"wavelength_nm": 550}')
    assert read_frame_stack(stack).frames.shape == (4, 300, 400)
    _small_budget(monkeypatch, 2 ** 20)
    with pytest.raises(MemoryBudgetError, match="a 300 x 400 window"):
        read_surface(store)
    assert read_surface(store, region=(0, 0, 0.0495, 0.0495)).shape == (50, 50)
    with pytest.raises(MemoryBudgetError, match="frame stack .*480000 pixels"):
        read_frame_stack(stack)


@pytest.mark.slow
def test_a_map_too_big_for_the_automatic_budget_is_tiled_not_refused(tmp_path, monkeypatch):
    """With no simulation.max_memory_gb the budget is a share of the memory available: a
    scene whose map does not fit it takes the tiled path (and fits there)."""
    from render_inspect.pipeline import run_simulate
    from render_inspect.pipeline import wants_tiles

    scene = load_scene("sts_sinusoidal_grid", ["simulation.region=[-0.2,-0.15,0.22,0.2]",
                                               "simulation.pixel=0.0002", 'material.preset="ideal"',
                                               'machine.preset="ideal"'])
    assert scene.simulation.max_memory_gb is None
    need = process_of(scene).estimate_memory(process_of(scene).inputs_of(scene))
    assert not wants_tiles(scene)
    _small_budget(monkeypatch, int(0.6 * need))
    assert wants_tiles(scene)
    m = run_simulate(scene, tmp_path / "o", tile=128)
    assert (tmp_path / "o" / "heightmap.zarr").is_dir() and m["tiles"]["tile_px"] == 128
    assert m["tiles"]["memory_estimate_bytes"] < 0.6 * need
    # a process that cannot be tiled is refused, naming the grid's key
    burrs = scene.with_overrides(["artifacts.burrs.height=0.0001", "artifacts.burrs.width=0.002"])
    with pytest.raises(MemoryBudgetError, match="simulation.pixel >= "):
        run_simulate(burrs, tmp_path / "b")
    assert not (tmp_path / "b").exists()


def test_garbage_and_truncated_exr_are_input_errors(tmp_path):
    good = write_exr(tmp_path / "g.exr", {"height": np.zeros((32, 32), np.float32)},
                     {"pixel_size_mm": 0.001, "origin_mm": [0.0, 0.0]})
    raw = good.read_bytes()
    for name, content in [("empty", b""), ("garbage", b"garbage" * 100),
                          ("truncated", raw[: len(raw) // 2]), ("header", raw[:40])]:
        f = tmp_path / f"{name}.exr"
        f.write_bytes(content)
        with pytest.raises(InputError, match="measured file"):
            read_measured(f)
        with pytest.raises(InputError):
            read_exr(f)


@pytest.mark.parametrize("sidecar, why", [
    ("{not json", "not valid JSON"),
    ('{"pixel_mm": NaN}', "not valid JSON"),
    ("[1, 2]", "JSON object"),
    ('{"pixel_mm": "0.001"}', "pixel_mm must be a finite number"),
    ('{"pixel_mm": -1}', "pixel_mm must be a finite number"),
    ('{"pixel_mm": 0.001, "origin_mm": [1]}', "origin_mm"),
    ('{"pixel_mm": 0.001, "units": 5}', "units"),
    ("\xff\xfe", "not valid JSON"),
])
def test_malformed_sidecar_json_is_an_input_error(tmp_path, sidecar, why):
    np.save(tmp_path / "m.npy", np.zeros((4, 4)))
    (tmp_path / "m.json").write_bytes(sidecar.encode("latin1"))
    with pytest.raises(InputError, match=why):
        read_measured(tmp_path / "m.npy")


def test_pickled_and_garbage_npz_are_refused(tmp_path):
    np.savez(tmp_path / "obj.npz", z=np.array([{"a": 1}, None], dtype=object))
    with pytest.raises(InputError, match="pickle"):
        read_measured(tmp_path / "obj.npz", pixel=0.001)
    (tmp_path / "g.npz").write_bytes(b"PK\x03\x04garbage")
    with pytest.raises(InputError, match="npz"):
        read_measured(tmp_path / "g.npz", pixel=0.001)
    np.savez(tmp_path / "c.npz", z=np.zeros((4, 4), complex))
    with pytest.raises(InputError, match="complex"):
        read_measured(tmp_path / "c.npz", pixel=0.001)


# ------------------------------------------------------------------ renderers
def test_render_passes_keep_every_pass_under_the_mitsuba_limit():
    from render_inspect.render import MAX_SAMPLES_PER_PASS

    for w, h, spp in [(4096, 4096, 300), (8192, 8192, 65536), (256, 256, 64), (16, 16, 1),
                      (8192, 8192, 1), (1000, 3, 777)]:
        passes = render_passes(w, h, spp)
        assert sum(passes) == spp and all(p >= 1 for p in passes)
        assert max(passes) * w * h <= MAX_SAMPLES_PER_PASS
    assert render_passes(256, 256, 64) == [64]  # the usual images: one pass, as before
    seeds = {mitsuba_seed(s, k) for s in (0, 1, 2 ** 32, 2 ** 63 - 1) for k in range(4)}
    assert len(seeds) == 16 and all(0 <= s < 2 ** 32 for s in seeds)
    assert mitsuba_seed(7) == 7


def test_render_limits_are_checked_from_the_scene_before_any_work():
    base = load_scene("sts_sinusoidal_grid")
    need = check_render_limits(base.with_overrides(["render.diffuse.resolution=4096",
                                                    "render.diffuse.spp=300",
                                                    "simulation.max_memory_gb=64"]))
    # the turned part renders spectrally, about 1 kB per pixel: a render once estimated at
    # 897 MiB was killed at 12 GiB
    assert 12 * 2 ** 30 < need["diffuse_macro"] < 24 * 2 ** 30
    with pytest.raises(InputError, match=r"render.diffuse.window .* pixels high"):
        check_render_limits(base.with_overrides(["render.diffuse.window=[0,-0.5,0.001,0.5]"]))
    with pytest.raises(MemoryBudgetError, match="render.diffuse.resolution <= "):
        check_render_limits(base.with_overrides(["render.diffuse.resolution=8192",
                                                 "simulation.max_memory_gb=0.5"]), kind="diffuse")
    with pytest.raises(SceneError, match=r"render.diffuse.resolution: must be an integer in "
                                         r"\[16, 8192\]"):
        base.with_overrides(["render.diffuse.resolution=16384"])


@pytest.mark.mitsuba
def test_a_render_in_passes_equals_one_pass_within_the_noise(monkeypatch):
    """The pass mechanism (used beyond 2^26 samples) on a small image: 8 passes of 4 spp
    average to the 32-spp image within the Monte Carlo noise, and are repeatable."""
    import render_inspect.render._diffuse as D
    from render_inspect.core.heightmap import HeightMap
    from render_inspect.render import DiffuseConfig, render_diffuse

    x = np.linspace(-1, 1, 41)
    z = 0.002 * np.cos(2 * np.pi * x / 0.5)[None, :] * np.ones((41, 1))
    hm = HeightMap(z, z, 0.05, (-1.0, -1.0))
    dcfg = DiffuseConfig(resolution=32, spp=32, exaggeration=50.0)
    one, meta1 = render_diffuse(hm, dcfg, view="macro", seed=3)
    monkeypatch.setattr(D, "MAX_SAMPLES_PER_PASS", 32 * 32 * 4)
    many, meta8 = render_diffuse(hm, dcfg, view="macro", seed=3)
    again, _ = render_diffuse(hm, dcfg, view="macro", seed=2 ** 40)
    assert meta1["passes"] == 1 and meta8["passes"] == 8
    assert np.array_equal(many, render_diffuse(hm, dcfg, view="macro", seed=3)[0])
    # the same light reaches the image: means agree to the noise of 32 x 32 x 32 samples
    np.testing.assert_allclose(many.mean(), one.mean(), rtol=0.02)
    np.testing.assert_allclose(again.mean(), one.mean(), rtol=0.02)
    assert not np.array_equal(many, one)  # other samples were drawn


# ------------------------------------------------------------------ address space
def _under_address_limit(code: str, limit_bytes: int, *args, timeout=300):
    """Run Python ``code`` in a fresh process whose address space is capped (RLIMIT_AS,
    what ``ulimit -v`` / ``prlimit --as`` set)."""
    import resource
    import subprocess
    import sys

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    return subprocess.run([sys.executable, "-c", code, *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, preexec_fn=cap)


@pytest.mark.slow
def test_the_budget_follows_the_address_space_limit():
    """Under ``ulimit -v`` the budget is 80 % of the room left under the limit, and says
    so; a scene's max_memory_gb above it is capped."""
    code = ("from render_inspect.core.limits import memory_budget, address_space_limit;"
            "b, s = memory_budget(); c, t = memory_budget(64.0);"
            "print(b, c, address_space_limit()); print(s); print(t)")
    r = _under_address_limit(code, 3 * 2 ** 30)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    b, c, limit = (int(v) for v in lines[0].split())
    assert limit == 3 * 2 ** 30 and 0 < b < 0.8 * limit and b < c < limit
    assert "80% of the room under the address-space limit (ulimit -v) of 3 GiB" in lines[1]
    assert "simulation.max_memory_gb = 64, capped by the address-space limit (ulimit -v)" in lines[2]


@pytest.mark.slow
def test_a_capped_simulation_is_refused_at_the_start_naming_the_limit(tmp_path):
    """A grid that fits the machine but not ``ulimit -v`` is refused before any work, one
    line naming the limit and the pixel that would fit, not a late MemoryError (burrs: a
    scene that cannot be simulated tile by tile, which a map this large otherwise is)."""
    code = "import sys; from render_inspect.cli import main; sys.exit(main(sys.argv[1:]))"
    out = tmp_path / "o"
    r = _under_address_limit(code, 2 * 2 ** 30, "simulate", "sts_sinusoidal_grid", "--out", out,
                             "-q", "--set", "simulation.region=[-1,-1,1,1]",
                             "--set", "simulation.pixel=0.0003",
                             "--set", "artifacts.burrs.height=0.0001", "--set", "artifacts.burrs.width=0.002")
    assert r.returncode == 1, r.stderr
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and "Traceback" not in r.stderr
    assert "the address-space limit (ulimit -v) of 2 GiB" in err[0]
    assert "simulation.pixel >=" in err[0] and not out.exists()


@pytest.mark.slow
def test_mitsuba_is_refused_up_front_when_its_address_space_does_not_fit():
    """A Mitsuba render reserves about 0.5 to 0.7 GiB of address space beyond the process's
    (LLVM, Dr.Jit's threads; measured, see MITSUBA_ADDRESS_SPACE) and ends with a
    segmentation fault when the limit refuses it: check_address_space says so first."""
    from render_inspect.core.limits import (MITSUBA_ADDRESS_SPACE, check_address_space,
                                            mitsuba_address_space)

    assert mitsuba_address_space(4) == MITSUBA_ADDRESS_SPACE + 4 * 16 * 2 ** 20
    check_address_space(10 ** 15, what="anything")  # no limit in this process: nothing to say
    code = ("from render_inspect.core.limits import check_address_space as c, "
            "mitsuba_address_space as m, address_space_used as u, address_space_limit as l\n"
            "try:\n    c(m(2), what='a Mitsuba render')\nexcept Exception as e:\n    print(e)\n"
            "else:\n    print('fits', u(), l())")
    tight = _under_address_limit(code, 600 * 2 ** 20)
    assert tight.returncode == 0, tight.stderr
    msg = tight.stdout.strip()
    assert msg.startswith("a Mitsuba render reserves about 672 MiB of address space, more than")
    assert "address-space limit (ulimit -v, RLIMIT_AS) of 600 MiB" in msg
    assert "(ulimit -v unlimited)" in msg and "\n" not in msg
    roomy = _under_address_limit(code, 4 * 2 ** 30)
    assert roomy.stdout.startswith("fits"), roomy.stdout


# ------------------------------------------------------------------ analyze
@pytest.mark.slow
def test_analyze_estimate_is_within_a_factor_of_the_measured_peak(tmp_path):
    """The peak resident memory of ``analyze`` on a 2000 x 2000 map (above the
    interpreter's with the package imported), against analyze_memory: within 1.5 x, and
    not below it by more than that either."""
    import json
    import subprocess
    import sys

    from render_inspect.metrology._analysis import analyze_memory

    n = 2000
    z = np.random.default_rng(0).normal(0, 1e-5, (n, n))
    np.save(tmp_path / "m.npy", z)
    (tmp_path / "m.json").write_text(json.dumps({"pixel_mm": 0.001}))
    del z
    # the peak resident memory above what the process held before the command ran (the
    # interpreter and the package, measured in the same process)
    # (VmHWM of /proc: getrusage's ru_maxrss would start from the parent's at the fork)
    probe = ("import sys, render_inspect.cli, render_inspect.pipeline, "
             "render_inspect.metrology, render_inspect.io\n"
             "def r():\n    for line in open('/proc/self/status'):\n"
             "        if line.startswith('VmHWM'):\n            return int(line.split()[1]) * 1024\n"
             "before = r()\nrc = render_inspect.cli.main(sys.argv[1:])\nprint(rc, r() - before)")
    run = subprocess.run([sys.executable, "-c", probe, "analyze", str(tmp_path / "m.npy"),
                          "--out", str(tmp_path / "o"), "-q"], capture_output=True, text=True,
                         check=True)
    rc, peak = (int(v) for v in run.stdout.split()[-2:])
    assert rc == 0 and (tmp_path / "o" / "metrics.json").is_file(), run.stderr
    est = analyze_memory((n, n), holes=False)
    print("analyze peak", format_bytes(peak), "estimate", format_bytes(est))
    assert peak / FACTOR < est < peak * FACTOR, (format_bytes(est), format_bytes(peak))


def test_a_map_too_big_to_analyse_is_refused_before_it_is_read(tmp_path, monkeypatch):
    """read_surface with the analysis' bytes per point checks the file's declared size
    against what analysing it needs, not just reading it."""
    from render_inspect.io import read_surface
    from render_inspect.metrology._analysis import analyze_memory_per_point

    np.save(tmp_path / "m.npy", np.zeros((300, 400)))
    (tmp_path / "m.json").write_text('{"pixel_mm": 0.001}')
    _small_budget(monkeypatch, 8 * 2 ** 20)  # reading 120 000 values needs about 3 MiB
    assert read_surface(tmp_path / "m.npy").shape == (300, 400)
    per_point = analyze_memory_per_point()
    with pytest.raises(MemoryBudgetError, match=r"a 300 x 400 array, which would need about "
                                                r"[\d.]+ MiB to read and analyse"):
        _traced(lambda: read_surface(tmp_path / "m.npy", bytes_per_value=per_point))
    _, peak = _traced(lambda: pytest.raises(MemoryBudgetError, read_surface, tmp_path / "m.npy",
                                            bytes_per_value=per_point))
    assert peak < 2 ** 20


def test_usable_cpus_follows_the_cpu_affinity():
    """Threads are sized by the CPUs the process may run on (``taskset``, a batch
    scheduler's CPU set), not by the machine's count."""
    from render_inspect.core.limits import usable_cpus

    cpus = os.sched_getaffinity(0)
    assert usable_cpus() == len(cpus)
    try:
        os.sched_setaffinity(0, {min(cpus)})
        assert usable_cpus() == 1
    finally:
        os.sched_setaffinity(0, cpus)


def test_the_tiled_refusal_names_a_tile_that_fits_or_what_holds_the_memory():
    """The advice is worked out with the estimate itself: the largest --tile (a power of
    two, as --tile takes) that fits; where none does because the burr model's halo holds the memory, the
    pixel and the burrs are named, not --tile."""
    from render_inspect.core.errors import MemoryBudgetError
    from render_inspect.pipeline._simulate_command import _tiled_check
    from render_inspect.scene import load_scene

    sim = load_scene("sts_sinusoidal_grid", ["simulation.max_memory_gb=1"]).simulation
    gib = 1 << 30

    def plain(t, k):  # a fixed part and the tiles' share
        return int(0.2 * gib + k * t * t * 1500)

    with pytest.raises(MemoryBudgetError) as e:
        _tiled_check(sim, plain, tile=1024, in_flight=2, points=10, workers=None, scheduler=None)
    fit = int(str(e.value).split("--tile ")[1].split(" ")[0])
    assert fit & (fit - 1) == 0 and plain(fit, 2) <= gib < plain(2 * fit, 2), str(e.value)
    assert _tiled_check(sim, plain, tile=fit, in_flight=2, points=10, workers=None,
                        scheduler=None) == plain(fit, 2)

    def halo(t, k):  # a block of 26 000 pixels around each tile: no tile fits
        return k * (t + 2 * 26_000) ** 2 * 100

    with pytest.raises(MemoryBudgetError) as e:
        _tiled_check(sim, halo, tile=1024, in_flight=2, points=10, workers=None, scheduler=None,
                     halo=26_000)
    msg = str(e.value)
    assert "--tile" not in msg.split("would need")[1] and "simulation.pixel" in msg \
        and "material.burrs = false" in msg, msg
