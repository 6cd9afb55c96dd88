"""Messages in the scene's words, and unit mistakes named with the value probably meant.

Every error type of the validation library has a wording of the project (key, what is
allowed, value received); a seeded fuzz of the shipped scenes (every key set to hostile
values, or left out) never lets the library's own phrases through.  A region typed in
micrometres is refused with the region in mm; a feed per revolution typed as a feed per
minute and a pixel too coarse for the feed marks are warned about."""

from __future__ import annotations

import copy
import math
import tomllib
import typing

import numpy as np
import pytest
from pydantic_core import PydanticKnownError, core_schema

from render_inspect.cli import main
from render_inspect.core.messages import LIBRARY_WORDING, validation_line
from render_inspect.errors import SceneError
from render_inspect.scene import find_scene, load_scene, scene_from_dict, shipped_scenes, unit_warnings

_CTX = {"gt": 0, "ge": 0, "lt": 1, "le": 1, "multiple_of": 2, "min_length": 1, "max_length": 4,
        "actual_length": 5, "expected": "'a' or 'b'", "discriminator": "'type'", "tag": "x",
        "expected_tags": "'a', 'b'", "error": "boom", "pattern": "x", "field_type": "Value",
        "class_name": "X", "max_digits": 3, "decimal_places": 2, "whole_digits": 1,
        "expected_plural": "x", "expected_schemes": "'http'", "method_name": "m",
        "encoding": "utf-8", "expected_version": 4, "tz_expected": 0, "tz_actual": 1,
        "class": "X", "context": "x"}
ERROR_TYPES = typing.get_args(core_schema.ErrorType)


def _library_message(t: str) -> str:
    for ctx in (_CTX, None):
        try:
            return PydanticKnownError(t, ctx).message()
        except Exception:  # the type needs other context: try the next
            continue
    return "Input should be something else"


@pytest.mark.parametrize("t", ERROR_TYPES)
def test_every_validation_error_type_speaks_the_scene_language(t):
    assert len(ERROR_TYPES) > 100
    e = {"type": t, "loc": ("process", "spindle_rpm"), "msg": _library_message(t),
         "input": [1, 2] if "tuple" in t else "12x", "ctx": dict(_CTX)}
    key, text = validation_line(e, key="process.spindle_rpm", tags=["plane", "sphere"])
    assert key.startswith("process.spindle_rpm"), (t, key)
    for phrase in LIBRARY_WORDING:
        assert phrase not in text, (t, text)
    if t not in ("value_error", "assertion_error"):  # (their text is the project's own check)
        assert text.split()[0] in ("must", "is", "unknown", "has", "cannot", "takes", "nests"), \
            (t, text)
    if t not in ("missing", "extra_forbidden", "union_tag_not_found", "missing_argument",
                 "missing_keyword_only_argument", "missing_positional_only_argument",
                 "missing_sentinel_error", "default_factory_not_called"):
        assert "received" in text, (t, text)


HOSTILE = [None, True, "x", "", 1, -1, 0, 1.5, 1e300, math.nan, math.inf, [], [1], [1, 2, 3],
           [1, 2, 3, 4, 5], {}, {"a": 1}, [[1]], [None], {"type": "nope"}, ["a", "b", "c", "d"],
           2 ** 70, "12 mm"]


def _paths(d, pre=()):
    for k, v in d.items():
        yield pre + (k,)
        if isinstance(v, dict):
            yield from _paths(v, pre + (k,))


def test_fuzz_scene_messages_never_carry_the_library_wording():
    """Every key of every shipped scene set to a hostile value or left out (seeded, one
    value per key and scene plus the removal): refused in the scene's words, naming the
    key or its section."""
    rng = np.random.default_rng(25)
    refused = 0
    for name in shipped_scenes():
        base = tomllib.loads(find_scene(name).read_text())
        for path in _paths(base):
            for value in [HOSTILE[int(rng.integers(len(HOSTILE)))], "__remove__"]:
                d = copy.deepcopy(base)
                node = d
                for k in path[:-1]:
                    node = node[k]
                if value == "__remove__":
                    del node[path[-1]]
                else:
                    node[path[-1]] = value
                try:
                    scene_from_dict(d)
                except SceneError as err:
                    msg = str(err)
                    refused += 1
                    for phrase in LIBRARY_WORDING:
                        assert phrase not in msg, (name, path, value, msg)
                    assert path[0] in msg or "(top level)" in msg, (name, path, value, msg)
    assert refused > 200


def test_region_items_missing_is_one_line():
    d = tomllib.loads(find_scene("sts_sinusoidal_grid").read_text())
    d["simulation"]["region"] = [0, 0, 1]
    with pytest.raises(SceneError, match=r"simulation\.region: must hold 4 values; received \[0, 0, 1\]$"):
        scene_from_dict(d)


# ------------------------------------------------------------------------- unit mistakes
def test_a_region_in_micrometres_is_refused_with_the_region_in_mm():
    with pytest.raises(SceneError, match=r"simulation\.region: must be in mm: .* looks like "
                                         r"micrometres; in mm it is \[-0\.5, -0\.5, 0\.5, 0\.5\]"):
        load_scene("sts_sinusoidal_grid", ["simulation.region=[-500,-500,500,500]"])
    with pytest.raises(SceneError, match=r"in mm it is \[-0\.3, -0\.3, 0\.3, 0\.3\]"):
        load_scene("sculpt_quad_mla", ["simulation.region=[-300,-300,300,300]"])
    # a large region that is no unit mistake (it does not lie on the part read as um)
    load_scene("sts_sinusoidal_grid", ["simulation.region=[-5,-5,5,5]"])


def test_a_feed_per_revolution_typed_per_minute_is_named():
    (w,) = unit_warnings(load_scene("sts_sinusoidal_grid", ["process.feed_mm_per_min=0.01"]))
    assert "process.feed_mm_per_min = 0.01" in w and "0.2 um per revolution" in w
    assert "set process.feed_mm_per_min = 0.5" in w


def test_a_pixel_that_cannot_resolve_the_feed_marks_is_named():
    (w,) = unit_warnings(load_scene("sts_sinusoidal_grid", ["simulation.pixel=0.008"]))
    assert "simulation.pixel = 0.008 mm" in w and "1.2 pixels per period" in w
    assert "simulation.pixel <= 0.0025 mm" in w
    (w,) = unit_warnings(load_scene("sts_sinusoidal_grid", ["simulation.pixel=0.5"]))
    assert "if 0.5 is in micrometres, simulation.pixel = 0.0005" in w
    assert unit_warnings(load_scene("sts_sinusoidal_grid", ["simulation.pixel=0.008"]),
                         sampling=False) == []


@pytest.mark.parametrize("name", list(shipped_scenes()))
def test_shipped_scenes_carry_no_unit_mistake(name):
    assert unit_warnings(load_scene(name)) == []


def test_the_command_line_prints_the_warning_and_runs(tmp_path, capsys):
    rc = main(["toolpath", "sts_sinusoidal_grid", "--set", "process.feed_mm_per_min=0.01",
               "--set", "process.workpiece_radius=0.02", "--out", str(tmp_path / "o"), "-q"])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert "warning: process.feed_mm_per_min = 0.01" in err and "0.5" in err


# ------------------------------------------------------------------------- measured data
@pytest.mark.slow  # its comparison sets the registration against 19 surrogates
def test_force_compares_a_map_in_another_height_unit(tmp_path):
    """A measured map whose heights span 1000 x the design's (micrometres read as mm) is
    refused naming the likely unit and --force; with force it is compared, warned."""
    import warnings

    from render_inspect.design import make_surface
    from render_inspect.metrology import compare_measured
    from render_inspect.pipeline import check_measured

    scene = load_scene("sts_sinusoidal_grid")
    surface = make_surface(scene.design)
    px = 0.004
    x = -0.2 + px * np.arange(100)
    z = np.asarray(surface.height(x[None, :], x[:, None]), float) * 1000.0  # um read as mm
    np.save(tmp_path / "um.npy", z)
    (tmp_path / "um.json").write_text(f'{{"pixel_mm": {px}, "origin_mm": [-0.2, -0.2]}}')
    with pytest.raises(Exception) as err:
        check_measured(tmp_path / "um.npy", scene, surface)
    msg = str(err.value)
    assert "micrometres or nanometres read as millimetres" in msg and "--force" in msg
    m, comp = check_measured(tmp_path / "um.npy", scene, surface, force=True)
    assert comp.metrics["measured"] is not None
    with warnings.catch_warnings(record=True) as caught:  # said in the comparison's warnings
        warnings.simplefilter("always")
        compare_measured(m, surface, region=tuple(scene.simulation.region), force=True)
    assert any("compared anyway (--force)" in str(w.message) for w in caught)


@pytest.mark.slow
def test_compare_measured_takes_a_zarr_store(tmp_path, capsys):
    """``--measured heightmap.zarr`` (a folder) is a height map, not "file not found"."""
    from render_inspect.design import make_surface
    from render_inspect.pipeline import check_measured, run_simulate

    scene = load_scene("sts_sinusoidal_grid", ["material.preset='ideal'",
                                               "simulation.region=[-0.1,-0.1,0.1,0.1]",
                                               "simulation.pixel=0.002",
                                               "process.workpiece_radius=0.2"])
    run_simulate(scene, tmp_path / "sim", tiled=True, tile=64)
    store = tmp_path / "sim" / "heightmap.zarr"
    assert store.is_dir()
    m, comp = check_measured(store, scene, make_surface(scene.design), force=True)
    assert m.z.shape == (101, 101) and np.isfinite(m.z).mean() > 0.9
    rc = main(["compare", "sts_sinusoidal_grid", "--measured", str(store), "--vary",
               "process.nope=1,2", "--out", str(tmp_path / "cmp"), "-q"])
    err = capsys.readouterr().err
    assert rc == 1 and "process.nope" in err and "not found" not in err, err
    # and the folder that holds it is not replaced
    rc = main(["compare", "sts_sinusoidal_grid", "--measured", str(store), "--out",
               str(tmp_path / "sim"), "--overwrite", "-q"])
    err = capsys.readouterr().err
    assert rc == 1 and "holds the input" in err, err


def test_measure_refuses_frames_without_a_finite_pixel(tmp_path, capsys):
    """All-NaN frames: refused in one line (they gave an empty map and exit 0)."""
    from render_inspect.instruments import Camera, Microscope, artefacts, objective, psi_frames
    from render_inspect.io import write_frames_exr

    h, nrm = artefacts.sinusoid((32, 32), 5e-4, period=0.008, amplitude=2e-5)
    fr = psi_frames(h + 2e-3, nrm, pixel=5e-4, microscope=Microscope(objective=objective("20x"),
                                                                      camera=Camera(noise=False)))
    fr.frames = np.full_like(fr.frames, np.nan)
    write_frames_exr(tmp_path / "nan.exr", fr)
    rc = main(["measure", str(tmp_path / "nan.exr"), "--out", str(tmp_path / "m"), "-q"])
    err = capsys.readouterr().err
    assert rc == 1 and "no pixel with a finite intensity" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "m").exists()


def test_the_mesh_refusal_names_the_address_space_limit(monkeypatch):
    """Under ``ulimit -v`` the budget can be 0 MiB: the refusal says where it comes from
    and to raise the limit, not only to raise the stride."""
    from render_inspect.core.errors import MemoryBudgetError
    from render_inspect.mesh import _grid

    monkeypatch.setattr(_grid, "address_space_room", lambda: 0)
    monkeypatch.setattr(_grid, "address_space_limit", lambda: 1536 * 2 ** 20)
    with pytest.raises(MemoryBudgetError, match=r"capped by the address-space limit \(ulimit -v\) "
                                                r"of 1536 MiB.*raise the limit"):
        _grid.grid_mesh(np.zeros((64, 64)), pixel=0.001, memory_budget=0)
    monkeypatch.setattr(_grid, "address_space_room", lambda: None)
    with pytest.raises(MemoryBudgetError, match=r"from simulation\.max_memory_gb.*raise stride"):
        _grid.grid_mesh(np.zeros((64, 64)), pixel=0.001, memory_budget=1000)


def test_log_lines_go_to_the_stderr_of_the_moment(capsys):
    """The command line's log handler writes to the current ``sys.stderr``: one made while
    another stream was stderr (an earlier run under a captured or redirected stderr, since
    closed) does not end in "--- Logging error ---"."""
    import argparse
    import io
    import sys

    from render_inspect import cli

    earlier, sys.stderr = sys.stderr, io.StringIO()
    try:
        cli._setup_logging(argparse.Namespace(quiet=False, verbose=0))
    finally:
        sys.stderr.close()
        sys.stderr = earlier
    cli.log.warning("warning: %s", "process.feed_mm_per_min = 0.01 (100 % too slow)")
    err = capsys.readouterr().err
    assert "warning: process.feed_mm_per_min = 0.01 (100 % too slow)" in err
    assert "Logging error" not in err


def test_a_registry_kind_names_its_key_and_the_value_received():
    from render_inspect.errors import SceneError
    from render_inspect.scene import load_scene

    for value, shown in (("'STS'", "'STS'"), ("1", "1")):
        with pytest.raises(SceneError) as e:
            load_scene("sts_sinusoidal_grid", [f"process.kind={value}"])
        assert "process.kind: must be one of ['fts', 'hts', 'rcse', 'sculpt', 'sts']; received " \
            + shown in str(e.value), str(e.value)


def test_a_damaged_exr_is_one_line_with_the_librarys_words(tmp_path, capfd):
    """OpenEXR's C core and binding print their own lines on a damaged file: held back and
    put into the one error line (a whole file's reading prints nothing extra)."""
    import numpy as np

    from render_inspect.errors import InputError
    from render_inspect.io import read_exr, write_exr

    good = tmp_path / "good.exr"
    write_exr(good, {"z": np.arange(256 * 256, dtype=np.float32).reshape(256, 256)}, tile=64)
    read_exr(good)
    assert capfd.readouterr() == ("", "")
    bad = tmp_path / "bad.exr"
    data = good.read_bytes()
    bad.write_bytes(data[:len(data) // 2])
    with pytest.raises(InputError) as e:
        read_exr(bad)
    out, err = capfd.readouterr()
    assert (out, err) == ("", ""), (out, err)
    assert "damaged or truncated EXR" in str(e.value) and "the library:" in str(e.value)
    assert "\n" not in str(e.value)


def test_a_program_that_is_a_folder_is_named_as_one(tmp_path):
    from render_inspect.errors import InputError
    from render_inspect.io import read_program

    with pytest.raises(InputError, match=r"process.program: '.*' is a folder, not a file"):
        read_program(tmp_path)


def test_held_library_messages_leave_the_streams_as_they_were_across_threads():
    """A read in a second thread while one holds the streams runs with them as they are;
    when both end, stdout and stderr (the objects and the descriptors) are the process's
    own again (two redirections that overlap without nesting cannot be undone in order)."""
    import os
    import sys
    import threading

    from render_inspect.io._native import library_messages

    before = (sys.stdout, sys.stderr, os.readlink("/proc/self/fd/1"),
              os.readlink("/proc/self/fd/2"))
    entered, release = threading.Event(), threading.Event()

    def first():
        with library_messages():
            entered.set()
            release.wait(10)

    t = threading.Thread(target=first)
    t.start()
    entered.wait(10)
    with library_messages() as held:  # begins after the other and ends after it
        release.set()
        t.join(10)
    assert held.text == ""
    assert (sys.stdout, sys.stderr, os.readlink("/proc/self/fd/1"),
            os.readlink("/proc/self/fd/2")) == before


def test_a_region_reaching_off_the_part_is_named():
    """A square region around a round part of radius 0.1 mm: its corners lie off the part
    (pi r^2 / (2 x 0.08)^2 of the region is on it), where the map holds the tool's flank."""
    scene = load_scene("sts_sinusoidal_grid", ["simulation.region=[-0.08,-0.08,0.08,0.08]",
                                               "process.workpiece_radius=0.1"])
    (w,) = unit_warnings(scene)
    on_part = math.pi * 0.1 ** 2 - 4 * (0.1 ** 2 * math.acos(0.8) - 0.08 * 0.06)  # circle inside the square
    off = 1 - on_part / 0.16 ** 2
    assert "reaches 0.113137 mm from the spindle axis" in w and "process.workpiece_radius = 0.1 mm" in w
    share = float(w.split(": ")[1].split("%")[0])
    assert share == pytest.approx(100 * off, abs=0.3)
    assert unit_warnings(load_scene("sts_sinusoidal_grid", ["simulation.region=[-0.07,-0.07,0.07,0.07]",
                                                            "process.workpiece_radius=0.1"])) == []
