"""The Blender add-on (blender_addon/) from the source tree, against real bpy in this
environment: settings contract, presets and parameters, Simulate (both variants) checked
against the simulation run here, default output folder, errors, the worker process (a job
that fails, a job that is cancelled), missing dependencies, panels drawn in every state,
the manifest's wheel list, and a GLB re-imported with Blender's glTF importer.

The installed extension (zip with wheels, bpy-only Pythons 4.2 and 5.0) is tested in
tests/test_blender_extension.py.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.blender

REPO = Path(__file__).resolve().parents[1]
SMALL = ["simulation.region=[-0.1, -0.1, 0.1, 0.1]", "simulation.pixel=0.004"]
SCENES = sorted(p.stem for p in (REPO / "scenes").glob("*.toml"))


@pytest.fixture(scope="module")
def addon():
    """The add-on package, loaded from blender_addon/ and registered."""
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    spec = importlib.util.spec_from_file_location(
        "render_inspect_addon", REPO / "blender_addon" / "__init__.py",
        submodule_search_locations=[str(REPO / "blender_addon")])
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    mod.register()
    yield mod
    mod.unregister()
    del sys.modules[spec.name]


@pytest.fixture
def settings(addon, tmp_path):
    import bpy

    from render_inspect import pipeline

    pipeline.remove_blender_surfaces()
    s = bpy.context.scene.render_inspect
    s.scene_path = ""
    s.program_path = s.edge_path = s.measured_path = s.measured_units = s.measured_line = ""
    s.preset = "sts_sinusoidal_grid"
    addon.properties.load_params(s)
    s.output_dir = str(tmp_path / "out")
    s.extra_overrides = "; ".join(SMALL)
    s.exaggeration = 0.0
    s.compensation = "SCENE"
    s.surface = "machined"
    s.last_error = s.last_message = s.last_warnings = s.simulation_json = s.compare_json = ""
    s.variant = "compensated"  # (the variants listed are those of the last Simulate)
    s.job_running = False
    return s


def _draw(addon):
    sys.path.insert(0, str(REPO / "tests"))
    from blender_extension_driver import draw_panels, flat

    return {k: flat(v) for k, v in draw_panels(addon).items()}


def test_contract_names(addon):
    import bpy

    from render_inspect import pipeline

    for op in ("simulate", "render", "compare", "export"):
        assert getattr(bpy.ops.render_inspect, op).get_rna_type() is not None
    s = bpy.context.scene.render_inspect
    items = [i.identifier for i in s.bl_rna.properties["preset"].enum_items]
    assert items == SCENES
    assert s.bl_rna.properties["preset"].default == "sts_sinusoidal_grid"
    assert s.bl_rna.properties["scene_path"].subtype == "FILE_PATH"
    assert items == sorted(pipeline.blender_presets())
    assert addon.operators.VARIANT_PROPERTY == pipeline.VARIANT_PROPERTY


def test_scene_path_is_used_instead_of_the_preset(settings, addon):
    settings.scene_path = str(REPO / "scenes" / "sts_mla_2x2.toml")
    assert addon.properties.scene_file(settings) == str(REPO / "scenes" / "sts_mla_2x2.toml")
    assert settings.params_source == settings.scene_path  # reloaded by the update
    assert settings.scene_name == "sts_mla_2x2"
    settings.scene_path = ""
    assert Path(addon.properties.scene_file(settings)).name == "sts_sinusoidal_grid.toml"


def test_changed_parameters_become_overrides(settings, addon):
    data = tomllib.loads((REPO / "scenes" / "sts_sinusoidal_grid.toml").read_text())
    params = {p.key: p for p in settings.params}
    assert params["design.amplitude_x"].original == pytest.approx(data["design"]["amplitude_x"], rel=1e-7)
    assert params["process.points_per_rev"].is_int
    assert "process.kind" not in params  # strings are not listed
    assert addon.properties.overrides(settings) == SMALL
    params["process.spindle_rpm"].value = 40.0
    params["process.points_per_rev"].value = 1800
    params["tool.nose_radius"].value = 0.3
    settings.compensation = "none"
    params["process.feed_mm_per_min"].value = 0.45
    assert addon.properties.overrides(settings) == [
        "tool.nose_radius=0.3", "process.spindle_rpm=40", "process.feed_mm_per_min=0.45",
        "process.points_per_rev=1800", 'process.compensation="none"'] + SMALL


def test_simulate_makes_both_variants_from_the_simulation(settings, addon):
    import bpy

    from render_inspect.pipeline import compare_variants, simulate
    from render_inspect.scene import load_scene

    next(p for p in settings.params if p.key == "process.spindle_rpm").value = 40.0
    settings.exaggeration = 300.0
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    objs = addon.operators.variant_objects()
    assert sorted(objs) == ["compensated", "uncompensated"]
    # forward model: the same scene simulated here, heights x exaggeration = vertex z
    scene = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                       ["process.spindle_rpm=40.0"] + SMALL)
    for variant, sc in zip(("compensated", "uncompensated"), compare_variants(scene)):
        obj = objs[variant]
        assert obj.name == f"render_inspect_{variant}_x300"
        assert obj["render_inspect_exaggeration"] == 300.0
        rec = json.loads(obj["render_inspect_scene"])
        assert rec["process"]["spindle_rpm"] == 40.0
        assert rec["process"]["compensation"] == sc.process.compensation
        expected = simulate(sc).heightmap.machined
        co = np.empty(len(obj.data.vertices) * 3, np.float32)
        obj.data.vertices.foreach_get("co", co)
        z = co.reshape(expected.shape + (3,))[..., 2]
        np.testing.assert_allclose(z, 300.0 * expected, rtol=1e-6, atol=1e-9)
    assert objs["uncompensated"].location.x == pytest.approx(0.204 * 1.15, rel=1e-6)
    assert "UNDO" not in bpy.types.RENDER_INSPECT_OT_simulate.bl_options
    sim = json.loads(settings.simulation_json)
    assert sim["variants"]["uncompensated"]["residual"]["min_nm"] < \
        sim["variants"]["compensated"]["residual"]["min_nm"]
    # simulating again replaces the meshes
    settings.exaggeration = 100.0
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    assert sorted(o.name for o in addon.operators.variant_objects().values()) == [
        "render_inspect_compensated_x100", "render_inspect_uncompensated_x100"]


def test_simulate_follows_the_process_pair_and_the_panel_names_it(settings, addon):
    """Sculpturing is compared with its vibration on and off (the pair ``compare``
    shows): Simulate makes those two meshes, the Variant choice lists them, and the
    Comparison panel heads its columns with the variants' names."""
    import bpy

    from render_inspect.pipeline import compare_pair
    from render_inspect.scene import load_scene

    settings.preset = "sculpt_quad_mla"
    addon.properties.load_params(settings)
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    pair = compare_pair(load_scene(REPO / "scenes" / "sculpt_quad_mla.toml", SMALL))
    names = [v.name for v in pair.variants]
    assert names == ["vibration_on", "vibration_off"]
    objs = addon.operators.variant_objects()
    assert sorted(objs) == sorted(names)
    sim = json.loads(settings.simulation_json)
    assert list(sim["variants"]) == names and sim["pair"]["key"] == pair.key
    assert [sim["variants"][n]["label"] for n in names] == [v.label for v in pair.variants]
    items = [i[0] for i in addon.properties.variant_items(settings, bpy.context)]
    assert items == names
    settings.variant = "vibration_off"
    assert addon.operators._variant_source(settings)["variant"] == "vibration_off"
    # the residual of the vibrated cut differs from the plain one
    rv = [sim["variants"][n]["residual"]["Sq_nm"] for n in names]
    assert rv[0] != rv[1]
    settings.compare_json = json.dumps({"variants": names, "rows": [
        {"label": "Residual Sq", "unit": "nm", "values": [1.5, 2.5]}]})
    results = _draw(addon)["RENDER_INSPECT_PT_results"]
    assert results[1:7] == ["label ", "label vibration_on", "label vibration_off",
                            "label Residual Sq (nm)", "label 1.5", "label 2.5"]


def test_empty_output_folder_goes_to_temp_and_render_writes_there(settings, addon, tmp_path,
                                                                   monkeypatch):
    import tempfile

    import bpy

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    settings.output_dir = ""
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    base = tmp_path / "render_inspect_out" / "sts_sinusoidal_grid"
    assert (base / "compensated" / "heightmap.exr").is_file()
    assert (base / "uncompensated" / "heightmap.exr").is_file()
    settings.resolution, settings.samples, settings.render_interferogram = 16, 2, False
    assert bpy.ops.render_inspect.render() == {"FINISHED"}
    assert (base / "compensated" / "cycles.png").is_file()
    assert "render_inspect_compensated_cycles" in bpy.data.images
    # neither the panel nor the scene sets an exaggeration: the renderer's automatic one
    from render_inspect.io import read_heightmap_exr
    from render_inspect.render import auto_exaggeration

    hm = read_heightmap_exr(base / "compensated" / "heightmap.exr")
    ex = addon.operators.variant_objects()["compensated"]["render_inspect_exaggeration"]
    assert ex == auto_exaggeration(hm, "machined")


def test_errors_are_one_line_and_leave_nothing(settings, addon):
    import bpy

    with pytest.raises(RuntimeError, match="run Simulate first"):
        bpy.ops.render_inspect.export()
    settings.extra_overrides = "; ".join(SMALL) + "; process.spindle_rpm=-5"
    with pytest.raises(RuntimeError, match="process.spindle_rpm"):
        bpy.ops.render_inspect.simulate()
    assert settings.last_error.startswith("Simulate:") and "\n" not in settings.last_error.strip()
    assert addon.operators.variant_objects() == {}
    assert not Path(settings.output_dir).exists()


def test_program_file_field(settings, addon, tmp_path):
    """A program file beside the scene: it becomes process.program, the panel shows it, a
    malformed one is refused with the reader's one line, and Simulate cuts the program
    against the planned spiral (the pair a program gets)."""
    import bpy

    assert bpy.context.scene.render_inspect.bl_rna.properties["program_path"].subtype == "FILE_PATH"
    bad = tmp_path / "bad.nc"
    bad.write_text("G90\nG01 X0.05 Z0\nG32 X0 Z-1\n")
    settings.program_path = str(bad)
    assert addon.properties.overrides(settings)[-1 - len(SMALL)] == \
        f"process.program={json.dumps(str(bad))}"
    drawn = _draw(addon)["RENDER_INSPECT_PT_main"]
    assert "prop program_path Program" in drawn or any("program_path" in x for x in drawn)
    with pytest.raises(RuntimeError, match="G32"):
        bpy.ops.render_inspect.simulate()
    assert f"{bad}:3:" in settings.last_error and "\n" not in settings.last_error.strip()
    good = tmp_path / "spiral.nc"
    n = 8 * 720 + 1
    c = np.arange(n) * 0.5
    x = 0.2 - 0.01 * c / 360.0
    good.write_text("".join(f"C{ci % 360:.4f} X{xi:.6f} Z0.000000\n" for ci, xi in zip(c, x)))
    settings.program_path = str(good)
    settings.last_error = ""
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    sim = json.loads(settings.simulation_json)
    assert list(sim["variants"]) == ["program", "planned"]


def test_a_failing_worker_reports_the_error(settings, addon, tmp_path):
    job = addon._jobs.Job("simulate", {"scene_path": str(tmp_path / "nope.toml"), "overrides": [],
                                       "out": str(tmp_path / "o"), "surface": "machined",
                                       "exaggeration": None}, out_dirs=[tmp_path / "o"])
    assert job.wait(120) == "failed"
    assert job.error.startswith("scene file not found") and "nope.toml" in job.error
    assert not (tmp_path / "o").exists()


def test_cancel_stops_the_worker_and_leaves_no_files(settings, addon, tmp_path):
    out = tmp_path / "long"
    params = {"scene_path": str(REPO / "scenes" / "sts_sinusoidal_grid.toml"),
              "overrides": ["simulation.region=[-1.0, -1.0, 1.0, 1.0]", "simulation.pixel=0.001"],
              "out": str(out), "surface": "machined", "exaggeration": None}
    job = addon._jobs.start("simulate", params, out_dirs=[out])
    try:
        t_end = time.monotonic() + 120
        while job.progress < 0.05 and job.state == "running" and time.monotonic() < t_end:
            time.sleep(0.05)
        assert job.state == "running" and job.message.startswith("simulating")
        time.sleep(0.5)
        job.cancel()
    finally:
        addon._jobs.cancel_current()
    assert job.state == "cancelled" and job.proc.returncode is not None
    assert not out.exists()
    assert list(tmp_path.glob(".long.partial-*")) == []


def test_missing_dependency_is_named_and_greys_out_what_needs_it(settings, addon, monkeypatch):
    import bpy

    deps = addon._deps
    fake = (("render_inspect_no_such_module", "no-such-dist", "a test feature"),)
    monkeypatch.setattr(deps, "X3P", deps.X3P + fake)
    monkeypatch.setitem(deps.NEEDS, "export", deps.NEEDS["export"] + fake)
    drawn = _draw(addon)["RENDER_INSPECT_PT_main"]
    assert "label no-such-dist (a test feature)" in drawn
    assert not bpy.ops.render_inspect.export.poll()
    assert bpy.ops.render_inspect.simulate.poll()


def test_panels_draw_in_every_state(settings, addon):
    import bpy

    before = _draw(addon)
    assert "operator render_inspect.simulate" in before["RENDER_INSPECT_PT_main"]
    assert "label Run Compare to see the metrics here" in before["RENDER_INSPECT_PT_results"]
    settings.last_error = "Simulate: scene file not found: 'x.toml'"
    assert any("scene file not found" in x for x in _draw(addon)["RENDER_INSPECT_PT_main"])
    settings.last_error = ""
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    after = _draw(addon)
    assert any(x.startswith("label compensated: Sq") for x in after["RENDER_INSPECT_PT_main"])
    assert sum(x == "prop value" for x in after["RENDER_INSPECT_PT_parameters"]) == len(settings.params)
    settings.job_running, settings.job_label, settings.job_message = True, "Render", "Cycles sample 3/8"
    settings.job_progress = 0.3
    running = _draw(addon)["RENDER_INSPECT_PT_main"]
    assert "progress 0.3 30 %" in running and "operator render_inspect.cancel" in running
    assert not bpy.ops.render_inspect.render.poll()
    settings.job_running = False
    settings.compare_json = json.dumps({"rows": [{"label": "Residual Sq", "unit": "nm",
                                                  "compensated": 1.5, "uncompensated": 2.5}],
                                        "difference_rms_nm": 0.25, "report": "r.html"})
    results = _draw(addon)["RENDER_INSPECT_PT_results"]
    assert results[1:7] == ["label ", "label compensated", "label uncompensated",
                            "label Residual Sq (nm)", "label 1.5", "label 2.5"]


def test_manifest_follows_blenders_rules_and_lists_no_wheels():
    """The wheels are not listed by hand: the build writes each platform's list from the
    lock (tests/test_blender_extension.py builds one)."""
    manifest = tomllib.loads((REPO / "blender_addon" / "blender_manifest.toml").read_text())
    assert "wheels" not in manifest
    assert manifest["blender_version_min"] == "4.2.0"
    # 5.1 runs Python 3.13, where the bundled CPython 3.11 wheels do not load
    assert manifest["blender_version_max"] == "5.1.0"
    assert manifest["platforms"] == ["linux-x64", "windows-x64", "macos-arm64", "macos-x64"]
    assert set(manifest["permissions"]) == {"files"}
    assert manifest["copyright"] and manifest["license"] == ["SPDX:BSD-3-Clause"]
    assert manifest["maintainer"]


def test_property_callbacks_keep_no_module_alive(addon):
    """Blender holds the property callbacks until it shuts down; in 4.2 a callback whose
    globals reach ``bpy`` keeps the bpy module alive, Blender never shuts down, and the
    process crashes at exit.  Every callback lives in _callbacks.py, whose globals hold
    no module."""
    import types

    callbacks = sys.modules[addon.__name__ + "._callbacks"]
    assert not [k for k, v in vars(callbacks).items() if isinstance(v, types.ModuleType)]
    found = []
    for cls in addon.properties.CLASSES:
        for name, prop in cls.__annotations__.items():
            for key, value in getattr(prop, "keywords", {}).items():
                if callable(value) and key in {"update", "items", "get", "set", "poll", "search"}:
                    found.append((cls.__name__, name, key))
                    assert value.__module__ == callbacks.__name__, (cls.__name__, name, key)
    assert ("RenderInspectSettings", "variant", "items") in found
    assert ("RenderInspectSettings", "preset", "update") in found


def test_glb_reimports_in_blender_upright_and_in_metres(tmp_path):
    import bpy

    from render_inspect.core.heightmap import HeightMap
    from render_inspect.mesh import export_mesh, heightmap_mesh

    bpy.ops.wm.read_factory_settings(use_empty=True)
    x = np.linspace(0.0, 2.0, 21)
    y = np.linspace(-1.0, 0.0, 11)
    X, Y = np.meshgrid(x, y)
    z = 1e-3 * X + 2e-3 * np.exp(-((X - 1.5) ** 2 + (Y + 0.2) ** 2) / 0.05)  # no symmetry
    hm = HeightMap(z, z.copy(), 0.1, (0.0, -1.0))
    gm = heightmap_mesh(hm, exaggeration=50.0, z_offset=0.0)
    export_mesh(gm, tmp_path / "part.glb")
    bpy.ops.import_scene.gltf(filepath=str(tmp_path / "part.glb"))
    (obj,) = [o for o in bpy.data.objects if o.type == "MESH"]
    co = np.array([obj.matrix_world @ v.co for v in obj.data.vertices])
    ref = gm.vertices.astype(np.float64) * 1e-3
    assert co.shape == ref.shape
    # Blender's importer turns glTF's +Y up back into +Z up: the part lies flat, metres
    np.testing.assert_allclose(co[np.lexsort(co.T[::-1])], ref[np.lexsort(ref.T[::-1])],
                               atol=1e-9)
    np.testing.assert_allclose(obj.dimensions, [2e-3, 1e-3, np.ptp(gm.vertices[:, 2]) * 1e-3],
                               rtol=1e-5)
    assert obj["vertical_exaggeration"] == 50.0 and obj["units"] == "m"


def test_the_add_on_calls_only_the_pipeline():
    """blender_addon/ reaches render_inspect through render_inspect.pipeline alone (and
    its error classes, to report them): no stage of its own."""
    import ast

    allowed = {"render_inspect.pipeline", "render_inspect.errors"}
    offenders = []
    for py in sorted((REPO / "blender_addon").glob("*.py")):
        for node in ast.walk(ast.parse(py.read_text())):
            # _lib.module("pipeline"): render_inspect inside the extension or installed
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "module" \
                    and getattr(node.func.value, "id", "") == "_lib":
                sub = node.args[0].value if node.args else ""
                if f"render_inspect.{sub}" not in allowed:
                    offenders.append(f"{py.name}:{node.lineno} imports render_inspect.{sub}")
                continue
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "import_module" \
                    and node.args and isinstance(node.args[0], ast.Constant):
                names = [node.args[0].value]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module] if node.module != "render_inspect" else \
                    [f"render_inspect.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                if name.split(".")[0] == "render_inspect" and \
                        not any(name == a or name.startswith(a + ".") for a in allowed):
                    offenders.append(f"{py.name}:{node.lineno} imports {name}")
    assert not offenders, offenders


def test_a_render_in_a_worker_process_reports_cycles_progress(settings, addon, tmp_path):
    import bpy

    from render_inspect import pipeline

    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    src = pipeline.surface_info(pipeline.blender_surfaces()["uncompensated"])
    params = dict(src, view="micro", resolution=16, samples=3, seed=2, out=str(tmp_path / "r"),
                  interferogram=False)
    job = addon._jobs.Job("render", params, out_dirs=[tmp_path / "r"])
    assert job.wait(300) == "finished", job.error
    assert "Cycles sample 3/3" in job.steps and job.progress == 1.0
    # the folder's marker (docs/formats.md, output folders) and the images
    assert sorted(p.name for p in (tmp_path / "r").iterdir()) == [".render_inspect.json",
                                                                   "cycles.exr", "cycles.png"]
    # what the worker rendered is what this process renders from the same mesh
    here = pipeline.render_variant(src["heightmap"], variant="uncompensated",
                                   surface=src["surface"], exaggeration=src["exaggeration"],
                                   view="micro", resolution=16, samples=3, seed=2,
                                   out=tmp_path / "here", interferogram=False)
    from render_inspect.io import read_exr

    a, _ = read_exr(tmp_path / "r" / "cycles.exr")
    b, _ = read_exr(here["cycles_exr"])
    np.testing.assert_allclose(a["G"], b["G"], atol=1e-6)


def _edge_file(path: Path, half_range_deg: float = 10.0) -> Path:
    """A measured cutting edge covering only +-``half_range_deg`` of the nose."""
    rows = [(a, 20.0 * np.sin(np.radians(a) * 3.0))
            for a in np.linspace(-half_range_deg, half_range_deg, 11)]
    path.write_text("angle_deg, deviation_nm\n" + "".join(f"{a:.3f}, {d:.4f}\n" for a, d in rows))
    return path


def test_a_measured_tool_edge_field_and_the_warnings_the_command_line_gives(settings, addon,
                                                                             tmp_path):
    """The Tool edge field becomes tool.edge_profile; Simulate says, as ``simulate``
    does, that the nose arc reaches beyond the measured angles (the same line
    ``edge_warnings`` gives for that scene), in the operator's report and in the panel."""
    import bpy

    from render_inspect.pipeline import edge_warnings
    from render_inspect.scene import load_scene

    edge = _edge_file(tmp_path / "edge.csv")
    settings.edge_path = str(edge)
    ov = addon.properties.overrides(settings)
    assert f"tool.edge_profile={json.dumps(str(edge))}" in ov
    expected = edge_warnings(load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml", ov))
    assert expected and "-10 to 10 deg" in expected[0]
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    shown = settings.last_warnings.splitlines()
    assert shown[0] == expected[0]
    assert json.loads(settings.simulation_json)["warnings"][0] == expected[0]
    assert settings.last_message.endswith(f"({len(shown)} warning{'s' if len(shown) > 1 else ''}, "
                                          f"in the panel)")
    drawn = _draw(addon)["RENDER_INSPECT_PT_main"]
    assert "prop edge_path" in drawn
    assert any(x.startswith("label tool edge (edge.csv) is measured") for x in drawn)
    # the measured edge was cut with: the meshes record it
    rec = json.loads(addon.operators.variant_objects()["compensated"]["render_inspect_scene"])
    assert rec["tool"]["edge_profile"] == str(edge)
    # a run without warnings clears them
    settings.edge_path = ""
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    assert settings.last_warnings == ""
    assert not any("tool edge" in x for x in _draw(addon)["RENDER_INSPECT_PT_main"])


@pytest.mark.parametrize("field, label", [("edge_path", "Tool edge file"),
                                          ("program_path", "Program file"),
                                          ("scene_path", "Scene file")])
def test_a_file_field_that_is_not_a_file_is_named(settings, addon, tmp_path, field, label):
    import bpy

    for value, what in ((tmp_path / "missing.csv", "does not exist"), (tmp_path, "is a folder")):
        setattr(settings, field, str(value))
        with pytest.raises(RuntimeError, match=f"{label}: '{value}' {what}; choose a file"):
            bpy.ops.render_inspect.simulate()
        assert settings.last_error.startswith(f"Simulate: {label}:")
        assert addon.operators.variant_objects() == {}
        assert not Path(settings.output_dir).exists()


def test_simulating_again_leaves_no_stale_data(settings, addon):
    """Simulate, Render, Simulate again: the meshes, material and images are the same
    number as after the first Simulate; the image of the render made of the replaced
    mesh (its file went with the variant's folder) is gone."""
    import bpy

    def count():  # (Blender's own "Render Result" image is not the add-on's)
        n = {k: len(getattr(bpy.data, k)) for k in ("objects", "meshes", "materials")}
        return dict(n, images=sum(i.name != "Render Result" for i in bpy.data.images))

    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    first = count()
    settings.resolution, settings.samples, settings.render_interferogram = 16, 2, False
    assert bpy.ops.render_inspect.render() == {"FINISHED"}
    img = bpy.data.images["render_inspect_compensated_cycles"]
    png = Path(bpy.path.abspath(img.filepath))
    assert png.is_file() and settings.last_message.endswith(f"-> {png.parent}")
    for _ in range(2):
        assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
        assert not png.exists()
        assert "render_inspect_compensated_cycles" not in bpy.data.images
        now = count()
        assert {k: now[k] for k in ("meshes", "materials", "images")} == \
            {k: first[k] for k in ("meshes", "materials", "images")}


def test_compare_with_a_measured_profile(settings, addon, tmp_path):
    """The Measured field, with its units and line, runs ``compare --measured PROFILE``:
    the Comparison panel shows the measured profile, the simulated measurement and the
    simulated cut side by side, the numbers of the same comparison run here, and its
    warnings as the command line gives them."""
    import bpy

    from render_inspect.pipeline import run_compare_command
    from render_inspect.scene import load_scene

    # the measured profile: the design's sinusoid along the line, 1 um apart, with the
    # feed marks of a 20 um feed as parabolic scallops (a forward model of a cut)
    s_um = np.arange(0.0, 200.0, 1.0)
    z_nm = 50.0 * np.sin(2 * np.pi * s_um / 100.0) + 8.0 * ((s_um % 20.0) - 10.0) ** 2 / 100.0
    prof = tmp_path / "profile.txt"
    prof.write_text("".join(f"{a:.3f} {b:.4f}\n" for a, b in zip(s_um, z_nm)))
    settings.measured_path = str(prof)
    settings.measured_units = "um,nm"
    settings.measured_line = "-0.1,0,0.1,0"
    assert bpy.ops.render_inspect.compare() == {"FINISHED"}
    comp = json.loads(settings.compare_json)
    assert comp["kind"] == "profile"
    assert comp["variants"] == ["measured", "simulated_measured", "true"]
    ref = run_compare_command(load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml", SMALL),
                              tmp_path / "ref", measured=prof, units="um,nm", line="-0.1,0,0.1,0")
    rq = next(r for r in comp["rows"] if r["label"] == "Rq")
    assert rq["values"] == pytest.approx(
        [ref["profiles"][k]["profile"]["Rq_nm"] for k in comp["variants"]], rel=1e-9)
    assert comp["warnings"] == ref["warnings"]
    assert settings.last_warnings.splitlines() == ref["warnings"]
    assert Path(comp["report"]).is_file() and settings.last_message.startswith(
        "compared with profile.txt:")
    results = _draw(addon)["RENDER_INSPECT_PT_results"]
    assert results[1:5] == ["label ", "label measured", "label simulated measurement",
                            "label simulated cut"]
    assert any(x.startswith("label Registered") for x in results)
    assert "prop measured_units" in _draw(addon)["RENDER_INSPECT_PT_main"]
    # units without a measured profile, and a measured file that is not there, are named
    settings.measured_path = ""
    with pytest.raises(RuntimeError, match="Profile units and Profile line are for a measured"):
        bpy.ops.render_inspect.compare()
    settings.measured_path = str(tmp_path / "nope.txt")
    with pytest.raises(RuntimeError, match="Measured file: .*nope.txt' does not exist"):
        bpy.ops.render_inspect.compare()
