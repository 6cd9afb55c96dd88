"""Benchmark: ``render-inspect fit`` - forward-model evaluations per second and the time to a
fit.

The case is the one of ``tests/test_fit.py`` on the shipped defaults: the sinusoidal-grid
scene (``sts_sinusoidal_grid``, sts_lathe machine and Al 6082 with their random parts) cut
with a tool nose radius of 0.525 mm and a feed of 0.51 mm/min, imaged over a 0.2 x 0.2 mm
field (centre 0.35 mm from the axis) by the 20x virtual interferometer and measured; then
fitted from the shipped values (0.514 mm, 0.5 mm/min).

Figures (printed and returned by :func:`main`):

* ``evaluation_s``: one evaluation (simulate the 0.22 mm window at 0.5 um, image 227 x 227
  camera pixels at 3 x 3 sub-samples, measure), median of 5 in this process;
* ``evaluations_per_s``: its inverse; ``dask_evaluations_per_s``: a batch of 8 evaluations
  on a LocalCluster of 2 workers (after the workers' start);
* ``scene_reuse``: the ray tracer's scene of an evaluation's mesh loaded afresh
  (``load_s``) against another evaluation's scene with the vertices replaced
  (``update_s``: the acceleration structure is rebuilt either way), and whether they
  trace the same heights;
* ``fit_s``, ``fit_cpu_s``, ``fit_evaluations``: the two-parameter fit in this process
  (the evaluations of a batch two at once, ``fit_threads``; its six realisations of the
  random parts included), its wall and CPU seconds (all threads), its result, error and
  standard error; ``fit_load_average``: the 1-minute load average before and after it
  (the CPU seconds are what the fit needs whatever the load: on a quiet machine with
  two cores its wall time is at most about them, and at least half of them);
* ``evaluation_stages_s``: the median seconds of one evaluation's stages (``simulate``, of
  which ``machine_following``; ``interferometer``, of which ``scene_build`` (the ray
  tracer's acceleration structure), ``ray_trace`` (the rest of the tracing), ``autofocus``
  and ``imaging``; ``measure``) and ``evaluation_cpu_s``;

Run: ``.venv/bin/python benchmarks/bench_fit.py`` (or ``make bench ONLY=fit``).
"""

from __future__ import annotations

import contextlib
import json
import os
import resource
import statistics
import sys
import tempfile
import time
from pathlib import Path

FIELD = (0.25, -0.1, 0.45, 0.1)
TRUTH = {"tool.nose_radius": 0.525, "process.feed_mm_per_min": 0.51}


def _truth(folder: Path) -> Path:
    from render_inspect.pipeline import run_measure, run_render
    from render_inspect.scene import load_scene

    x0, y0, x1, y1 = FIELD
    m = 0.03
    scene = load_scene("sts_sinusoidal_grid", [
        *[f"{k}={v}" for k, v in TRUTH.items()], "simulation.pixel=0.0005",
        f"simulation.region=[{x0 - m}, {y0 - m}, {x1 + m}, {y1 + m}]",
        f"render.interferometer.field_of_view=[{x0}, {y0}, {x1}, {y1}]"])
    run_render(scene, folder / "render", kind="interferometer")
    run_measure(folder / "render" / "interferogram.exr", folder / "measure")
    return folder / "measure" / "height.exr"


def _cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


@contextlib.contextmanager
def _stage_timer(seconds: dict):
    """Accumulate the wall seconds of the forward model's stages into ``seconds`` (the
    functions are wrapped where the forward model looks them up, and restored after)."""
    from render_inspect.instruments import _interferometer, _modes
    from render_inspect.pipeline import _fit_model
    from render_inspect.processes import _mechanics
    from render_inspect.render import _scene_dicts

    places = [(_fit_model, "simulate", "simulate"), (_mechanics, "follow", "machine_following"),
              (_interferometer, "trace_heights", "trace"),
              (_scene_dicts, "load_scene_dict", "scene_build"),
              (_modes, "autofocus", "autofocus"), (_interferometer, "psi_frames", "frames"),
              (_fit_model, "measure_frames", "measure")]
    saved = []

    def wrap(fn, name):
        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - t0
        return timed

    for mod, attr, name in places:
        saved.append((mod, attr, getattr(mod, attr)))
        setattr(mod, attr, wrap(getattr(mod, attr), name))
    try:
        yield seconds
    finally:
        for mod, attr, fn in saved:
            setattr(mod, attr, fn)


def _scene_update(spec: dict) -> dict:
    """The ray tracer's scene of an evaluation's mesh loaded afresh against the scene of
    another evaluation's mesh with its vertices and normals replaced (``params.update()``):
    seconds of each (median of 3) and whether the traced heights agree bit for bit."""
    import copy

    import numpy as np

    from render_inspect.mesh import heightmap_mesh
    from render_inspect.pipeline._simulate import simulate
    from render_inspect.render._scene_dicts import load_scene_dict, mitsuba_mesh
    from render_inspect.render._variant import import_mitsuba, single_thread
    from render_inspect.scene import scene_from_dict

    mi, dr, _ = import_mitsuba()
    meshes = []
    for feed in (0.5, 0.51):
        d = copy.deepcopy(spec["scene"])
        d["process"]["feed_mm_per_min"] = feed
        hm = simulate(scene_from_dict(d, "(bench)")).heightmap
        meshes.append(heightmap_mesh(hm, channel="machined", exaggeration=1.0, margin=2,
                                     normals=True))

    def trace(scene, gm):
        lo, hi = gm.vertices.min(axis=0), gm.vertices.max(axis=0)
        xs = np.linspace(lo[0], hi[0], 700, dtype=np.float32) + np.float32(1.23e-5)
        ys = np.linspace(lo[1], hi[1], 700, dtype=np.float32) + np.float32(2.71e-5)
        o = mi.Point3f(mi.Float(np.tile(xs, ys.size)), mi.Float(np.repeat(ys, xs.size)),
                       float(hi[2]) + 1.0)
        si = scene.ray_intersect(mi.Ray3f(o, mi.Vector3f(0, 0, -1)))
        dr.eval(si.p.z)
        return np.array(si.p.z)

    load, update, same = [], [], True
    scene = load_scene_dict({"type": "scene", "part": mitsuba_mesh(meshes[0])})
    params = mi.traverse(scene)
    for i in (1, 0, 1):
        gm = meshes[i]
        m = mitsuba_mesh(gm)
        t0 = time.perf_counter()
        fresh = load_scene_dict({"type": "scene", "part": m})
        load.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        with single_thread():
            tf = type(params["part.vertex_positions"])
            params["part.vertex_positions"] = tf(np.ascontiguousarray(gm.vertices,
                                                                      dtype=np.float32).ravel())
            params["part.vertex_normals"] = tf(np.ascontiguousarray(gm.normals,
                                                                    dtype=np.float32).ravel())
            params.update()
        update.append(time.perf_counter() - t0)
        same = same and np.array_equal(trace(fresh, gm), trace(scene, gm), equal_nan=True)
    return {"triangles": int(meshes[0].n_faces),
            "load_s": round(statistics.median(load), 3),
            "update_s": round(statistics.median(update), 3), "same_heights": bool(same)}


def main() -> dict:
    # the threads of numba's kernels wait asleep, as in the fit command (which sets this
    # before its first kernel; here the truth's render runs kernels first)
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
    from render_inspect.batch import dask_client
    from render_inspect.pipeline import predict_measurement, preset_value, run_fit
    from render_inspect.pipeline._fit_model import LOCAL_THREADS
    from render_inspect.scene import load_scene

    out = {"cpus": os.cpu_count(), "load_average": os.getloadavg()[0]}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        meas = _truth(tmp)
        scene = load_scene("sts_sinusoidal_grid")
        load0 = os.getloadavg()[0]
        t0, c0 = time.perf_counter(), _cpu_s()
        rec = run_fit(meas, scene, [",".join(TRUTH)], tmp / "fit", seed=1, profile_points=0,
                      cache=tmp / "cache")
        out["fit_s"] = round(time.perf_counter() - t0, 1)
        out["fit_cpu_s"] = round(_cpu_s() - c0, 1)
        out["fit_load_average"] = [round(load0, 2), round(os.getloadavg()[0], 2)]
        out["fit_threads"] = LOCAL_THREADS
        out["fit_evaluations"] = rec["evaluations"]
        out["fit_per_evaluation_s"] = round(rec["timing_s"]["per_evaluation"], 3)
        for k, v in TRUTH.items():
            got = rec["parameters"][k]["value"]
            out[f"fit_{k}"] = got
            out[f"fit_{k}_error_percent"] = round(100 * (got - v) / v, 4)
            out[f"fit_{k}_stderr_percent"] = round(100 * rec["parameters"][k]["stderr"] / v, 4)
        # single evaluations: the task of the fit's solution, its seed moved so that the
        # cache is not used
        fitted = json.loads((tmp / "fit" / "fit.json").read_text())
        from render_inspect.fit import set_value

        d = scene.to_dict()
        for k, v in {**TRUTH, **{k: 0.0 for k in fitted["random_parts"]
                                  ["held_at_zero_in_evaluations"]}}.items():
            set_value(d, k, v, fill=lambda key: preset_value(scene, key))
        d["simulation"]["region"] = fitted["simulation"]["region_mm"]
        d["simulation"]["pixel"] = fitted["simulation"]["pixel_mm"]
        icfg = load_scene("sts_sinusoidal_grid").render.interferometer.model_dump(mode="json")
        icfg.update(pixel=fitted["measured"]["pixel_mm"], noise=False,
                    field_of_view=fitted["placement"]["window_mm"],
                    subsamples=fitted["instrument"]["subsamples"])
        d["render"]["interferometer"] = icfg
        spec = {"scene": d, "seed": 7}
        predict_measurement(spec)
        times, cpus, stages = [], [], []
        for _ in range(5):
            with _stage_timer({}) as st:
                t0, c0 = time.perf_counter(), _cpu_s()
                predict_measurement(spec)
                times.append(time.perf_counter() - t0)
                cpus.append(_cpu_s() - c0)
            stages.append(st)
        out["evaluation_s"] = round(statistics.median(times), 3)
        out["evaluation_cpu_s"] = round(statistics.median(cpus), 3)
        med = {k: statistics.median(st.get(k, 0.0) for st in stages) for k in stages[0]}
        out["evaluation_stages_s"] = {
            "simulate": med["simulate"], "machine_following": med["machine_following"],
            "interferometer": med["trace"] + med["frames"], "scene_build": med["scene_build"],
            "ray_trace": med["trace"] - med["scene_build"], "autofocus": med["autofocus"],
            "imaging": med["frames"] - med["autofocus"], "measure": med["measure"]}
        out["evaluation_stages_s"] = {k: round(v, 3) for k, v in out["evaluation_stages_s"].items()}
        out["evaluations_per_s"] = round(1 / statistics.median(times), 3)
        out["scene_reuse"] = _scene_update(spec)
        with dask_client(workers=2) as client:
            client.gather(client.map(predict_measurement, [spec, spec], pure=False))  # warm
            t0 = time.perf_counter()
            client.gather(client.map(predict_measurement, [spec] * 8, pure=False))
            dt = time.perf_counter() - t0
        out["dask_workers"] = 2
        out["dask_evaluations_per_s"] = round(8 / dt, 3)
    out["load_average_after"] = os.getloadavg()[0]
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
