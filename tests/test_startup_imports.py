"""A mistake in a scene, a key or a path is answered before any heavy library is imported:
the command line checks the scene (or the instrument) first and imports the pipeline
after it, and the modules that define the scene's sections load numba and SciPy only
where a kernel or a SciPy function is first used (render_inspect.core.lazy).

How long the answer takes is a benchmark (benchmarks/bench_command.py); here the
subprocess's ``sys.modules`` after the error says what was imported."""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from render_inspect.core.lazy import LazyDispatcher, njit, prange

REPO = Path(__file__).resolve().parents[1]

HEAVY = ("numba", "llvmlite", "scipy", "matplotlib", "mitsuba", "drjit", "dask", "distributed",
         "zarr", "OpenEXR", "trimesh", "bpy")

#: runs the command line's main() on argv[1:], then prints its exit code and the heavy
#: modules imported meanwhile
_DRIVER = """
import json, sys
from render_inspect.cli import main
try:
    rc = main(sys.argv[1:])
except SystemExit as e:
    rc = e.code
heavy = %r
print(json.dumps({"rc": rc, "heavy": sorted(m for m in heavy if m in sys.modules)}))
""" % (HEAVY,)


def _run(tmp_path, *argv):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", _DRIVER, *argv], capture_output=True, text=True,
                       timeout=300, env=env, cwd=tmp_path)
    return json.loads(r.stdout.strip().splitlines()[-1]), r.stderr


@njit(inline="always")
def _square(x):  # pragma: no cover - numba
    return x * x


@njit(cache=False)
def _sum_squares(a):  # pragma: no cover - numba
    out = np.zeros(a.shape[0])
    for i in prange(a.shape[0]):
        s = 0.0
        for j in range(a.shape[1]):
            s += _square(a[i, j])
        out[i] = s
    return out


@pytest.mark.slow
@pytest.mark.parametrize("argv,says", [
    (["simulate", "sts_fig16_overcut", "--set", "tool.nose_radiuz=1"], "did you mean 'nose_radius'"),
    (["simulate", "sts_fig16_overcut", "--set", "tool.nose_radius=-1"], "received -1"),
    (["simulate", "no_such_scene_file.toml"], "scene file not found"),
    (["toolpath", "sts_sinusoidal_grid", "--set", "proces.spindle_rpm=10"], "proces"),
    (["render", "sts_sinusoidal_grid", "--set", "simulation.pixel=0"], "simulation.pixel"),
    (["compare", "sts_fig16_overcut", "--set", "tool.rake_angle_deg=400"], "rake_angle_deg"),
    (["simulate", "sts_fig16_overcut", "--program", "no_such_program.nc"], "process.program"),
    (["analyze", "no_such_map.exr"], "measured file not found"),
])
def test_a_mistake_is_answered_before_any_heavy_import(tmp_path, argv, says):
    res, err = _run(tmp_path, *argv, "--out", str(tmp_path / "o"))
    assert res["rc"] == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and says in lines[0] and "Traceback" not in err, err
    assert res["heavy"] == [], res
    assert not (tmp_path / "o").exists()


@pytest.mark.slow
def test_importing_the_scene_schema_imports_no_heavy_module(tmp_path):
    code = ("import sys\nfrom render_inspect.scene import load_scene\n"
            "load_scene('sts_fig16_overcut', [])\n"
            f"print(sorted(m for m in {HEAVY!r} if m in sys.modules))")
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env=env, cwd=tmp_path)
    assert out.stdout.strip() == "[]", out.stdout


def test_a_lazy_kernel_is_numbas_kernel_once_used():
    # a kernel calling another kernel, with prange, compiles and gives numba's answer; the
    # module's globals then hold numba's dispatchers
    a = np.arange(12.0).reshape(3, 4)
    want = (a * a).sum(axis=1)
    assert _sum_squares.py_func(a).tolist() == want.tolist()  # (prange as range)
    again = pickle.loads(pickle.dumps(_sum_squares))  # a reference to the module's kernel
    assert np.array_equal(_sum_squares(a), want)
    assert np.array_equal(again(a), want)
    assert _sum_squares.signatures  # numba's dispatcher answers
    import numba

    assert isinstance(globals()["_square"], numba.core.registry.CPUDispatcher)
    assert isinstance(globals()["_sum_squares"], numba.core.registry.CPUDispatcher)
    from render_inspect.machining import _burr_kernels

    assert isinstance(_burr_kernels.__dict__["_smooth_axis0"], (LazyDispatcher, numba.core.registry.CPUDispatcher))


def test_lazy_scipy_names_are_scipys():
    from render_inspect.core.lazy import lazy_attr, lazy_module

    nd = lazy_module("scipy.ndimage")
    from scipy import ndimage

    x = np.arange(25.0).reshape(5, 5)
    assert np.array_equal(nd.uniform_filter(x, 3), ndimage.uniform_filter(x, 3))
    rot = lazy_attr("scipy.spatial.transform", "Rotation")
    assert np.allclose(rot.from_euler("xyz", [0, 0, 0]).as_matrix(), np.eye(3))


#: runs the ``render-inspect`` program (``sys.argv[0]`` its name, so that the simulate
#: command draws its figures in its second process) on argv[1:], and prints the heavy
#: modules its own process imported (at exit: the program ends without the interpreter's
#: teardown, after what is registered to run at exit)
_PROGRAM = """
import atexit, json, sys
heavy = %r
atexit.register(lambda: print(json.dumps(sorted(m for m in heavy if m in sys.modules)),
                              flush=True))
sys.argv = ["render-inspect", *sys.argv[1:]]
from render_inspect.cli import main
sys.exit(main())
""" % (HEAVY + ("PIL", "scipy.linalg", "scipy.ndimage"),)


@pytest.mark.slow
@pytest.mark.parametrize("argv,needs,never", [
    # the figures are drawn by the second process: the command's own imports no drawing
    # library, no renderer, no cluster or chunked store (an in-memory map), no SciPy linear
    # algebra or image filters (the servo loops' matrix exponential and the burrs'
    # smoothing weights are the package's own: 0.05 s of imports)
    (["simulate", "sts_sinusoidal_grid", "--set", "simulation.region=[-0.2,-0.2,0.2,0.2]"],
     {"numba", "OpenEXR"}, {"matplotlib", "PIL", "mitsuba", "drjit", "dask", "distributed",
                            "zarr", "trimesh", "bpy", "scipy.linalg", "scipy.ndimage"}),
    # the interferometer writes its frames and a fringe image (Pillow): no matplotlib, no
    # cluster, no chunked store, no mesh library, no Blender
    (["render", "sts_sinusoidal_grid", "--kind", "interferometer", "--surface", "design",
      "--set", "render.interferometer.objective='50x'"],
     {"mitsuba", "drjit", "numba", "OpenEXR", "PIL"},
     {"matplotlib", "dask", "distributed", "zarr", "trimesh", "bpy"}),
], ids=["simulate", "render-interferometer"])
def test_a_command_imports_only_what_it_uses(tmp_path, argv, needs, never):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               MPLBACKEND="Agg")
    # twice: the second run loads its kernels from numba's cache (a kernel that compiles
    # sets up numba's whole compiler, SciPy's linear algebra with it: the first run after
    # a source changed)
    for run in ("first", "second"):
        r = subprocess.run([sys.executable, "-c", _PROGRAM, "-q", *argv, "--out", str(tmp_path / run)],
                           capture_output=True, text=True, timeout=600, env=env, cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-800:]
    imported = set(json.loads(r.stdout.strip().splitlines()[-1]))
    assert needs <= imported, sorted(needs - imported)
    assert not imported & never, sorted(imported & never)


#: the program's start: the collector paused while the command line's modules are
#: imported, on again once a command runs (here one that ends on a mistake)
_COLLECTOR = """
import gc, json, sys
sys.argv = ["render-inspect"]
n = [0]
gc.callbacks.append(lambda phase, info: phase == "start" and n.__setitem__(0, n[0] + 1))
import render_inspect
before = n[0]
import render_inspect.cli as cli
state = {"paused": not gc.isenabled(), "collections": n[0] - before}
state["rc"] = cli.main(["simulate", "no_such_scene_file.toml", "--out", "o"])
state["on_after"] = gc.isenabled()
print(json.dumps(state))
"""


@pytest.mark.slow
def test_the_programs_start_up_pauses_the_collector_until_the_command_runs(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", _COLLECTOR], capture_output=True, text=True,
                       timeout=300, env=env, cwd=tmp_path)
    assert json.loads(r.stdout.strip().splitlines()[-1]) == {
        "paused": True, "collections": 0, "rc": 1, "on_after": True}, r.stderr[-800:]


def test_a_paused_collector_is_put_back_as_it_was():
    import gc

    from render_inspect.core.lazy import collector_paused

    was = gc.isenabled()
    try:
        for start in (True, False):
            (gc.enable if start else gc.disable)()
            with collector_paused():
                assert not gc.isenabled()
            assert gc.isenabled() is start
            with pytest.raises(KeyError):  # (also when the block fails)
                with collector_paused():
                    raise KeyError("x")
            assert gc.isenabled() is start
    finally:
        (gc.enable if was else gc.disable)()


def test_a_host_that_embeds_the_package_keeps_its_objects_collectable():
    """Outside the program (Blender, a script, a Dask worker) nothing is frozen: frozen
    objects are never collected, and a host's own objects must still end (Blender 4.5
    hangs at exit when its objects' cleanup never runs)."""
    import gc

    from render_inspect.core.lazy import collector_paused

    before = gc.get_freeze_count()
    with collector_paused():
        made = [[i] for i in range(1000)]
    assert gc.get_freeze_count() == before, "the block froze the host's objects"
    del made


def test_the_collector_stays_paused_until_the_last_block_of_any_thread_ends():
    import gc
    import threading

    from render_inspect.core.lazy import collector_paused

    was = gc.isenabled()
    gc.enable()
    inside, leave = threading.Event(), threading.Event()

    def other():
        with collector_paused():
            inside.set()
            leave.wait(30)

    t = threading.Thread(target=other)
    try:
        with collector_paused():
            t.start()
            inside.wait(30)
        assert not gc.isenabled()  # (the other thread's block still runs)
        leave.set()
        t.join()
        assert gc.isenabled()
    finally:
        leave.set()
        t.join()
        (gc.enable if was else gc.disable)()
