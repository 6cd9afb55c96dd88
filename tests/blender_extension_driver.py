"""Drive the built extension in a Python that has only ``bpy`` (no render_inspect).

Run by tests/test_blender_extension.py as ``<venv>/bin/python blender_extension_driver.py
ZIP OUT_JSON WORK_DIR``: installs the zip with ``package_install_files``, enables it,
picks a preset, runs Simulate, Render, Compare and Export, re-imports the GLB, starts and
cancels a long Simulate in a worker process, runs a Render in a worker process, draws every
panel in every state through a recording layout, disables and removes the extension.  It
records what it saw in OUT_JSON; the test asserts on it.
"""

import json
import os
import sys
import time
import traceback
from pathlib import Path

import bpy  # first: it puts Blender's script modules (addon_utils) on the path
import numpy as np

import addon_utils  # noqa: E402

MODULE = "bl_ext.user_default.render_inspect"
#: A 0.2 x 0.2 mm window at 4 um: 51 x 51 points per variant, seconds per step.
SMALL_PIXEL = 0.004
SMALL_REGION = "simulation.region=[-0.1, -0.1, 0.1, 0.1]"
#: Small renders for Compare.
COMPARE_SMALL = ("render.interferometer.field_of_view=[-0.05, -0.05, 0.05, 0.05]; "
                 "render.diffuse.resolution=32; render.diffuse.spp=4")


class Recorder:
    """A stand-in for ``UILayout`` that records what a panel draws and checks every
    property and operator it names exists (a typo fails here as it would in Blender)."""

    def __init__(self, log):
        self.log = log
        self.alert = False
        self.enabled = True

    def _sub(self, kind, **kw):
        self.log.append((kind, kw))
        return Recorder(self.log)

    row = lambda self, **kw: self._sub("row", **kw)  # noqa: E731
    column = lambda self, **kw: self._sub("column", **kw)  # noqa: E731
    box = lambda self, **kw: self._sub("box", **kw)  # noqa: E731
    split = lambda self, **kw: self._sub("split", **kw)  # noqa: E731
    grid_flow = lambda self, **kw: self._sub("grid_flow", **kw)  # noqa: E731

    def label(self, *, text="", icon="NONE"):
        self.log.append(("label", text))

    def prop(self, data, name, **kw):
        if name not in data.bl_rna.properties:
            raise AttributeError(f"panel draws missing property {name!r} of {data}")
        self.log.append(("prop", name))

    def operator(self, idname, **kw):
        cat, op = idname.split(".")
        getattr(getattr(bpy.ops, cat), op).get_rna_type()  # raises when not registered
        self.log.append(("operator", idname))

    def progress(self, *, factor=0.0, type="BAR", text=""):
        self.log.append(("progress", round(float(factor), 3), text))


def draw_panels(mod):
    """Draw every panel once; return {panel: what it drew}."""
    out = {}
    for cls in mod.panel.CLASSES:
        log = []
        fake = type("PanelSelf", (), {"layout": Recorder(log)})()
        cls.draw(fake, bpy.context)
        out[cls.__name__] = log
    return out


def flat(log):
    return [" ".join(map(str, e)) for e in log]


REPORT = {"blender": bpy.app.version_string, "steps": []}


def main(zip_path, out_json, work):
    work = Path(work)
    rep = REPORT

    def step(name, **info):
        rep["steps"].append(name)
        rep[name] = info

    # -- install & enable ----------------------------------------------------------------
    bpy.ops.wm.read_factory_settings(use_empty=True)
    t = time.perf_counter()
    res = bpy.ops.extensions.package_install_files(filepath=str(zip_path), repo="user_default",
                                                   enable_on_install=True)
    enabled = MODULE in {m.__name__ for m in addon_utils.modules() if addon_utils.check(m.__name__)[1]}
    mod = sys.modules[MODULE]
    lib = mod._lib.module  # render_inspect inside the extension (shipped as source)
    render_inspect = lib()

    step("install", result=sorted(res), enabled=enabled, seconds=time.perf_counter() - t,
         addon_file=mod.__file__, render_inspect_file=render_inspect.__file__,
         render_inspect_name=render_inspect.__name__, numpy=np.__version__,
         numba_cache_dir=os.environ.get("NUMBA_CACHE_DIR", ""),
         missing=[m[0] for m in mod._deps.missing()],
         presets=[i[0] for i in mod._scenes._PRESET_ITEMS])

    s = bpy.context.scene.render_inspect
    rep["panels_before"] = {k: flat(v) for k, v in draw_panels(mod).items()}
    # drawing the panel (and polling its buttons) must stay instant: no pipeline import
    rep["install"]["pipeline_imported_by_draw"] = f"{render_inspect.__name__}.pipeline" in sys.modules

    # -- error state: a missing scene file --------------------------------------------------
    s.scene_path = str(work / "missing.toml")
    try:
        bpy.ops.render_inspect.simulate()
        err = None
    except RuntimeError as e:
        err = str(e)
    step("error", message=err, last_error=s.last_error,
         objects=[o.name for o in bpy.data.objects])
    rep["panels_error"] = {k: flat(v) for k, v in draw_panels(mod).items()}
    s.scene_path = ""

    # -- preset, parameters, Simulate --------------------------------------------------------
    s.preset = "sts_sinusoidal_grid"
    params = {p.key: p.value for p in s.params}
    pix = next(p for p in s.params if p.key == "simulation.pixel")
    pix.value = SMALL_PIXEL
    s.extra_overrides = SMALL_REGION
    s.output_dir = str(work / "out")
    overrides = mod.properties.overrides(s)
    t = time.perf_counter()
    res = bpy.ops.render_inspect.simulate()
    objs = mod.operators.variant_objects()
    HeightMap = lib("core.heightmap").HeightMap  # noqa: N806
    read_heightmap_exr = lib("io").read_heightmap_exr

    checks = {}
    for variant, obj in objs.items():
        hm = read_heightmap_exr(obj["render_inspect_heightmap_path"])
        co = np.empty(len(obj.data.vertices) * 3, np.float32)
        obj.data.vertices.foreach_get("co", co)
        z = co.reshape(-1, 3)[:, 2].reshape(hm.shape)
        ex = obj["render_inspect_exaggeration"]
        checks[variant] = {"name": obj.name, "vertices": len(obj.data.vertices),
                           "shape": list(hm.shape), "exaggeration": ex,
                           "max_abs_z_error": float(np.max(np.abs(z - ex * hm.machined))),
                           "z_ptp": float(np.ptp(z)), "location_x": obj.location.x,
                           "width_mm": float(hm.extent[1] - hm.extent[0]),
                           "compensation": json.loads(obj["render_inspect_scene"])["process"]["compensation"],
                           "pixel": json.loads(obj["render_inspect_scene"])["simulation"]["pixel"],
                           "materials": [m.name for m in obj.data.materials]}
    cache = Path(os.environ.get("NUMBA_CACHE_DIR", "/nonexistent"))
    installed = Path(mod.__file__).parent
    step("simulate", result=sorted(res), seconds=time.perf_counter() - t, params=params,
         overrides=overrides, objects=checks, output=s.output_path,
         numba_cache_files=len(list(cache.rglob("*.nbi"))),
         numba_files_in_install=len(list(installed.rglob("*.nbi"))))
    rep["panels_after_simulate"] = {k: flat(v) for k, v in draw_panels(mod).items()}

    # -- Render (Cycles + interferogram) in this process -------------------------------------
    s.resolution, s.samples, s.variant = 32, 4, "compensated"
    t = time.perf_counter()
    res = bpy.ops.render_inspect.render()
    images = {}
    for img in bpy.data.images:
        if img.name.startswith("render_inspect_"):
            px = np.empty(img.size[0] * img.size[1] * img.channels, np.float32)
            img.pixels.foreach_get(px)
            images[img.name] = {"size": list(img.size), "std": float(px.std()),
                                "path": img.filepath}
    mat = bpy.data.materials.get("render_inspect_cycles_aluminium")
    step("render", result=sorted(res), seconds=time.perf_counter() - t, images=images,
         message=s.last_message,
         material_model=mat.get("render_inspect_material_model") if mat else None,
         user_scene_camera=bpy.context.scene.camera is not None)

    # -- Export + GLB re-import -----------------------------------------------------------------
    s.export_formats = {"EXR", "PLY", "GLB", "X3P"}
    t = time.perf_counter()
    res = bpy.ops.render_inspect.export()
    out = Path(s.output_path) / "export" / "compensated"
    files = sorted(p.name for p in out.iterdir())
    glb = out / "compensated_machined.glb"
    obj = mod.operators.variant_objects()["compensated"]
    heightmap_mesh = lib("mesh").heightmap_mesh

    hm = read_heightmap_exr(obj["render_inspect_heightmap_path"])
    gm = heightmap_mesh(hm, channel="machined", exaggeration=obj["render_inspect_exaggeration"])
    before = set(bpy.data.objects)
    bpy.ops.import_scene.gltf(filepath=str(glb))
    imported = [o for o in bpy.data.objects if o not in before and o.type == "MESH"]
    imp = imported[0]
    co = np.array([imp.matrix_world @ v.co for v in imp.data.vertices])
    ref = gm.vertices.astype(np.float64) * 1e-3  # the same points, metres, Blender Z-up
    order_i = np.lexsort(co.T[::-1])
    order_r = np.lexsort(ref.T[::-1])
    step("export", result=sorted(res), seconds=time.perf_counter() - t, files=files,
         glb_vertices=len(co), mesh_vertices=len(ref),
         glb_max_error_m=float(np.max(np.abs(co[order_i] - ref[order_r]))),
         glb_dimensions_m=list(imp.dimensions),
         glb_exaggeration=imp.get("vertical_exaggeration"),
         glb_units=imp.get("units"))
    for o in imported:
        bpy.data.objects.remove(o, do_unlink=True)

    # -- Compare ----------------------------------------------------------------------------------
    s.extra_overrides = SMALL_REGION + "; " + COMPARE_SMALL
    t = time.perf_counter()
    res = bpy.ops.render_inspect.compare()
    comp = json.loads(s.compare_json or "{}")
    metrics = json.loads(Path(comp["metrics_json"]).read_text()) if comp else {}
    step("compare", result=sorted(res), seconds=time.perf_counter() - t, rows=comp.get("rows"),
         report=comp.get("report"), report_exists=Path(comp.get("report", "/nonexistent")).is_file(),
         metrics_keys=sorted(metrics))
    rep["panels_after_compare"] = {k: flat(v) for k, v in draw_panels(mod).items()}

    # -- running state, and a Render in a worker process ------------------------------------------
    jobs = mod._jobs
    obj = mod.operators.variant_objects()["compensated"]
    params = {"heightmap": obj["render_inspect_heightmap_path"], "variant": "compensated",
              "surface": "machined", "exaggeration": float(obj["render_inspect_exaggeration"]),
              "view": "micro", "resolution": 24, "samples": 4, "seed": 1,
              "out": str(work / "worker_render"), "interferogram": False}
    t = time.perf_counter()
    job = jobs.Job("render", params, out_dirs=[params["out"]])
    while job.state == "running":
        time.sleep(0.05)
    messages = list(job.steps)
    step("worker_render", state=job.state, error=job.error, seconds=time.perf_counter() - t,
         messages=sorted(set(messages)), result=job.result,
         files=sorted(p.name for p in Path(params["out"]).iterdir()) if Path(params["out"]).is_dir() else [])
    job.clean()

    # -- cancel a long Simulate in a worker ---------------------------------------------------------
    n_objects = len(bpy.data.objects)
    long_out = work / "long"
    params = {"scene_path": mod.properties.preset_path("sts_sinusoidal_grid"),
              "overrides": ["simulation.region=[-1.0, -1.0, 1.0, 1.0]", "simulation.pixel=0.001"],
              "out": str(long_out), "surface": "machined", "exaggeration": None}
    job = jobs.start("simulate", params, out_dirs=[long_out])
    s.job_running, s.job_label = True, "Simulate"
    t_end = time.monotonic() + 120
    while job.progress < 0.05 and job.state == "running" and time.monotonic() < t_end:
        time.sleep(0.05)
    s.job_progress, s.job_message = job.progress, job.message
    rep["panels_running"] = {k: flat(v) for k, v in draw_panels(mod).items()}
    poll_while_running = bpy.ops.render_inspect.simulate.poll()
    time.sleep(1.0)  # into the cut
    state_before = job.state
    error_before = job.error  # why, should it have stopped by itself
    tail_before = list(job.tail)[-5:]
    t = time.perf_counter()
    job.cancel()
    jobs.finish_current()
    s.job_running = False
    partials = sorted(p.name for p in long_out.parent.glob(f".{long_out.name}.partial-*"))
    step("cancel", state_before=state_before, error_before=error_before,
         tail_before=tail_before, message_before=s.job_message, state=job.state,
         seconds=time.perf_counter() - t, returncode=job.proc.returncode,
         out_exists=long_out.exists(), partials=partials,
         objects_unchanged=len(bpy.data.objects) == n_objects,
         poll_while_running=poll_while_running)

    # -- the 4.2 fallback material against the conductor Fresnel equation --------------------
    light_profile = lib("render").light_profile
    cyc = lib("render._cycles")
    ALUMINIUM_ETA, ALUMINIUM_K = cyc.ALUMINIUM_ETA, cyc.ALUMINIUM_K  # noqa: N806
    fresnel_conductor, render_cycles = cyc.fresnel_conductor, cyc.render_cycles

    mirror = {}
    for tilt_deg in (7.5, 30.0):
        x = np.linspace(-0.5, 0.5, 33)
        X, _ = np.meshgrid(x, x)
        z = np.tan(np.radians(tilt_deg)) / 10.0 * X
        hm = HeightMap(z, z.copy(), x[1] - x[0], (-0.5, -0.5))
        # the micro view's own light is a microscope's brightfield by default: the closed
        # form below is that of the dome, so the dome lights the micro view here
        rgb, meta = render_cycles(hm, {"light": "dome", "micro_light": "dome", "exaggeration": 10.0,
                                       "resolution": 32, "spp": 4}, view="micro")
        a = np.radians(tilt_deg)
        expected = fresnel_conductor(np.cos(a), ALUMINIUM_ETA, ALUMINIUM_K) * light_profile(2 * a, "dome")
        mirror[str(tilt_deg)] = {"median": np.median(rgb[4:-4, 4:-4].reshape(-1, 3), axis=0).tolist(),
                                 "expected": np.asarray(expected).tolist()}
    step("mirror", values=mirror)
    # render_cycles read the factory settings, which disables add-ons: enable it again
    addon_utils.enable(MODULE, default_set=True)
    step("enable_again", registered=hasattr(bpy.types, "RENDER_INSPECT_OT_simulate"),
         settings=hasattr(bpy.context.scene, "render_inspect"))

    # -- disable and remove -------------------------------------------------------------------------
    addon_utils.disable(MODULE, default_set=True)
    gone = {name: not hasattr(bpy.types, name) for name in
            ("RENDER_INSPECT_OT_simulate", "RENDER_INSPECT_OT_render", "RENDER_INSPECT_OT_compare",
             "RENDER_INSPECT_OT_export", "RENDER_INSPECT_PT_main")}
    gone["Scene.render_inspect"] = not hasattr(bpy.types.Scene, "render_inspect")
    pkg_dir = Path(mod.__file__).parent
    repo = next(r for r in bpy.context.preferences.extensions.repos if r.module == "user_default")
    res = bpy.ops.extensions.package_uninstall(repo_directory=repo.directory, pkg_id="render_inspect")
    step("remove", disabled=gone, uninstall=sorted(res), dir_exists=pkg_dir.exists())
    rep["done"] = True
    Path(out_json).write_text(json.dumps(rep, indent=1, default=str))


if __name__ == "__main__":
    try:
        main(*sys.argv[1:4])
    except Exception:
        REPORT["failed"] = traceback.format_exc()
        Path(sys.argv[2]).write_text(json.dumps(REPORT, indent=1, default=str))
        traceback.print_exc()
        sys.exit(1)
    # a normal exit: the test checks that Blender shuts down cleanly (exit code 0)
