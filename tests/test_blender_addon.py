"""The Blender add-on (blender_addon/), against real bpy: build the extension zip with
Blender's own ``blender_ext.py``, install it into a temporary user repository, enable
it, run its operators, and unregister it again."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.blender

REPO = Path(__file__).resolve().parents[1]
MODULE = "bl_ext.user_default.render_inspect"
SMALL = "simulation.region=[-0.1, -0.1, 0.1, 0.1]; simulation.pixel=0.004"


def _blender_ext() -> Path:
    import bpy

    path = Path(bpy.utils.system_resource("SCRIPTS")) / "addons_core/bl_pkg/cli/blender_ext.py"
    assert path.is_file(), f"blender_ext.py not found at {path}"
    return path


@pytest.fixture(scope="module")
def addon_zip(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("ext")
    subprocess.run([sys.executable, str(_blender_ext()), "build", "--source-dir",
                    str(REPO / "blender_addon"), "--output-dir", str(out)],
                   check=True, capture_output=True, text=True)
    zips = list(out.glob("render_inspect-*.zip"))
    assert len(zips) == 1, zips
    check = subprocess.run([sys.executable, str(_blender_ext()), "validate", str(zips[0])],
                           capture_output=True, text=True)
    assert check.returncode == 0, check.stdout + check.stderr
    return zips[0]


@pytest.fixture(scope="module")
def addon(addon_zip):
    import addon_utils
    import bpy

    bpy.ops.wm.read_factory_settings(use_empty=True)
    res = bpy.ops.extensions.package_install_files(filepath=str(addon_zip), repo="user_default",
                                                   enable_on_install=True)
    assert res == {"FINISHED"}
    assert MODULE in {m.__name__ for m in addon_utils.modules() if addon_utils.check(m.__name__)[1]}
    yield MODULE
    addon_utils.disable(MODULE, default_set=True)


@pytest.fixture
def settings(addon, tmp_path):
    import bpy

    from render_inspect.render._cycles import OBJECT_NAME, remove_object

    remove_object(OBJECT_NAME)
    s = bpy.context.scene.render_inspect
    s.scene_path = str(REPO / "scenes" / "sts_sinusoidal_grid.toml")
    s.output_dir = str(tmp_path / "out")
    s.extra_overrides = SMALL
    s.spindle_rpm = s.feed_mm_per_min = s.nose_radius = s.exaggeration = 0.0
    s.compensation = "SCENE"
    s.surface = "machined"
    return s


def test_installed_into_the_user_repository(addon):
    import addon_utils
    import bpy

    mod = sys.modules[addon]
    assert Path(mod.__file__).parent.name == "render_inspect"
    # installed into the temporary user resources, not run from the source tree
    assert os.environ["BLENDER_USER_RESOURCES"] in mod.__file__
    assert addon_utils.check(addon) == (True, True)
    for name in ("RENDER_INSPECT_OT_simulate", "RENDER_INSPECT_OT_render",
                 "RENDER_INSPECT_PT_main"):
        assert hasattr(bpy.types, name), name
    assert mod.properties.RenderInspectSettings.is_registered
    s = bpy.context.scene.render_inspect
    for prop in ("scene_path", "output_dir", "spindle_rpm", "feed_mm_per_min", "nose_radius",
                 "compensation", "extra_overrides", "exaggeration", "resolution", "samples"):
        assert hasattr(s, prop), prop
    assert {i.identifier for i in s.bl_rna.properties["compensation"].enum_items} == \
        {"SCENE", "none", "normal", "z"}


def test_simulate_loads_the_machined_heights_as_a_mesh(settings):
    import bpy

    from render_inspect.io import read_heightmap_exr
    from render_inspect.pipeline import simulate as simulate_scene
    from render_inspect.scene import load_scene

    settings.spindle_rpm = 40.0
    settings.compensation = "none"
    settings.exaggeration = 300.0
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}

    obj = bpy.data.objects["render_inspect_surface"]
    assert obj.name in bpy.context.scene.objects
    assert len(obj.data.vertices) == 51 * 51
    assert obj["render_inspect_exaggeration"] == 300.0
    rec = json.loads(obj["render_inspect_scene"])
    assert rec["process"]["spindle_rpm"] == 40.0
    assert rec["process"]["compensation"] == "none"
    assert rec["simulation"]["pixel"] == 0.004

    # forward model: the same scene simulated here, heights x exaggeration = vertex z
    scene = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                       [o.strip() for o in SMALL.split(";")] +
                       ["process.spindle_rpm=40.0", 'process.compensation="none"'])
    expected = simulate_scene(scene).heightmap.machined
    co = np.empty(51 * 51 * 3, np.float32)
    obj.data.vertices.foreach_get("co", co)
    z = co.reshape(51, 51, 3)[..., 2]
    np.testing.assert_allclose(z, 300.0 * expected, rtol=1e-6, atol=1e-9)
    assert np.ptp(z) > 0
    # and the height map written beside it holds the same heights
    hm = read_heightmap_exr(Path(settings.output_dir) / "heightmap.exr")
    np.testing.assert_allclose(hm.machined, expected, rtol=1e-6, atol=1e-12)


def test_simulate_reports_bad_input(settings):
    import bpy

    settings.scene_path = str(Path(settings.output_dir) / "missing.toml")
    with pytest.raises(RuntimeError, match="scene file not found"):
        bpy.ops.render_inspect.simulate()
    settings.scene_path = str(REPO / "scenes" / "sts_sinusoidal_grid.toml")
    settings.extra_overrides = SMALL + "; process.spindle_rpm=-5"
    with pytest.raises(RuntimeError, match="process.spindle_rpm"):
        bpy.ops.render_inspect.simulate()
    assert "render_inspect_surface" not in bpy.data.objects


def test_render_writes_a_cycles_image(settings):
    import bpy
    from PIL import Image

    with pytest.raises(RuntimeError, match="Simulate first"):
        bpy.ops.render_inspect.render()
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    settings.resolution = 32
    settings.samples = 4
    assert bpy.ops.render_inspect.render() == {"FINISHED"}
    png = Path(settings.output_dir) / "cycles.png"
    img = np.asarray(Image.open(png), dtype=np.float64)
    assert img.shape[:2] == (32, 32)
    assert img.std() > 1.0  # not a constant image
    assert "cycles.png" in bpy.data.images
    # the user's scene is untouched: the render happened in a private scene
    assert bpy.context.scene.name != "render_inspect_cycles"
    assert bpy.context.scene.camera is None


def test_default_output_goes_to_temp_not_the_addon_folder(settings, tmp_path, monkeypatch):
    import tempfile

    import bpy

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    addon_dir = Path(sys.modules[MODULE].__file__).parent
    before = {p for p in addon_dir.rglob("*") if "__pycache__" not in p.parts}
    settings.output_dir = ""
    assert bpy.ops.render_inspect.simulate() == {"FINISHED"}
    assert (tmp_path / "render_inspect_out" / "sts_sinusoidal_grid" / "heightmap.exr").is_file()
    assert {p for p in addon_dir.rglob("*") if "__pycache__" not in p.parts} == before
    # neither the panel nor the scene sets an exaggeration: the renderer's automatic one
    from render_inspect.pipeline import simulate as simulate_scene
    from render_inspect.render._diffuse import auto_exaggeration
    from render_inspect.scene import load_scene

    scene = load_scene(settings.scene_path, [o.strip() for o in SMALL.split(";")])
    assert scene.render.diffuse.exaggeration is None
    expected = auto_exaggeration(simulate_scene(scene).heightmap, "machined")
    assert bpy.data.objects["render_inspect_surface"]["render_inspect_exaggeration"] == expected


def test_unregister_and_register_mirror(addon):
    import addon_utils
    import bpy

    addon_utils.disable(addon, default_set=True)
    for name in ("RENDER_INSPECT_OT_simulate", "RENDER_INSPECT_OT_render",
                 "RENDER_INSPECT_PT_main"):
        assert not hasattr(bpy.types, name), name
    assert not sys.modules[addon].properties.RenderInspectSettings.is_registered
    assert not hasattr(bpy.types.Scene, "render_inspect")
    addon_utils.enable(addon, default_set=True)
    assert hasattr(bpy.types, "RENDER_INSPECT_OT_simulate")
    assert hasattr(bpy.context.scene, "render_inspect")


def test_enabled_again_in_a_new_process(addon):
    code = ("import bpy, addon_utils\n"
            f"addon_utils.enable({addon!r}, default_set=True)\n"
            "assert hasattr(bpy.types, 'RENDER_INSPECT_OT_simulate')\n"
            "assert hasattr(bpy.context.scene, 'render_inspect')\n"
            f"addon_utils.disable({addon!r}, default_set=True)\n"
            "assert not hasattr(bpy.types, 'RENDER_INSPECT_OT_simulate')\n"
            "print('ok')\n")
    res = subprocess.run([sys.executable, "-c", code], env=dict(os.environ),
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0 and "ok" in res.stdout, res.stdout + res.stderr
