"""Render benchmark (issue 3): the Mitsuba interferogram and diffuse image, and a
4000 x 4000 height map meshed and rendered within memory.

Figures (printed and returned by :func:`main`):

* ``interferogram``: a 1024 x 1024 PSI interferogram (4 frames, 2 x 2 = 4 sub-pixel
  samples per pixel, camera noise on) of a mesh of >= 2 M triangles (a 1025 x 1025 height
  map window), wall time and its parts (mesh, BVH load, ray tracing, interference model);
* ``diffuse``: the 512 x 512 macro view at 64 spp of seed 000's machined grid (the scene
  ``bench_cycles.py`` renders it in Blender Cycles);
* ``large_map``: a 4000 x 4000 map: full-resolution mesh arrays (bytes, seconds), then an
  interferogram of a 1024 x 1024 window and a 512 x 512 macro diffuse view (decimated to
  1024 cells a side), with the process's peak resident memory.

Run: ``.venv/bin/python benchmarks/bench_render.py [--quick]`` (``--quick`` skips the
4000 x 4000 part).  Timings are wall-clock seconds, best of ``repeats``.
"""

from __future__ import annotations

import json
import math
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def synthetic_heightmap(n: int, *, pixel: float = 0.001):
    """A sinusoidal grid (2 um, 2.5 mm) with 10 um-pitch turning marks (20 nm), n x n."""
    from render_inspect.machining import HeightMap

    c = (np.arange(n) - (n - 1) / 2) * pixel
    x = c[None, :]
    y = c[:, None]
    design = 2e-3 * np.sin(2 * np.pi * x / 2.5) * np.sin(2 * np.pi * y / 2.5)
    r = np.hypot(x, y)
    machined = design + 2e-5 * (0.5 + 0.5 * np.cos(2 * np.pi * r / 0.01))
    return HeightMap(design, machined, pixel, (float(c[0]), float(c[0])))


def _timed_interferogram(hm, cfg, repeats):
    import render_inspect.instruments._imaging as M
    import render_inspect.instruments._interferometer as I
    import render_inspect.render._scene_dicts as S

    parts = {}
    orig_load, orig_frames = S.load_scene_dict, M.interference_intensity

    def load(d):
        t = time.perf_counter()
        r = orig_load(d)
        parts["bvh_load_s"] = time.perf_counter() - t
        return r

    def frames(*a, **k):
        t = time.perf_counter()
        r = orig_frames(*a, **k)
        parts["interference_model_s"] = time.perf_counter() - t
        return r

    best, best_parts, ig = math.inf, {}, None
    S.load_scene_dict, M.interference_intensity = load, frames
    try:
        for _ in range(repeats):
            t = time.perf_counter()
            ig = I.render_interferogram(hm, cfg, seed=0)
            wall = time.perf_counter() - t
            if wall < best:
                best, best_parts = wall, dict(parts)
    finally:
        S.load_scene_dict, M.interference_intensity = orig_load, orig_frames
    return best, best_parts, ig


def bench_interferogram(repeats: int = 2) -> dict:
    from render_inspect.mesh import heightmap_mesh
    from render_inspect.render import mitsuba_variant
    from render_inspect.scene import InterferometerConfig

    mitsuba_variant()
    hm = synthetic_heightmap(1025)
    x0, y0 = float(hm.x[0]), float(hm.y[0])  # the mesh spans the pixel centres
    fov = (x0, y0, x0 + 1.024, y0 + 1.024)
    cfg = InterferometerConfig(pixel=0.001, field_of_view=fov, subsamples=2, noise=True)
    t = time.perf_counter()
    gm = heightmap_mesh(hm, window=list(fov), margin=2)
    mesh_s = time.perf_counter() - t
    wall, parts, ig = _timed_interferogram(hm, cfg, repeats)
    return {"shape": list(ig.shape), "frames": int(ig.frames.shape[0]),
            "samples_per_pixel": ig.subsamples ** 2, "mesh_triangles": gm.n_faces,
            "mesh_build_s": round(mesh_s, 3), "wall_s": round(wall, 2),
            **{k: round(v, 2) for k, v in parts.items()},
            "valid_fraction": float(ig.valid.mean()), "mitsuba_variant": ig.variant}


def bench_diffuse(repeats: int = 2) -> dict:
    from render_inspect.pipeline import simulate as simulate_scene
    from render_inspect.render import render_diffuse
    from render_inspect.scene import DiffuseConfig, load_scene

    scene = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                       ["simulation.region=[-0.5, -0.5, 0.5, 0.5]", "simulation.pixel=0.002"])
    hm = simulate_scene(scene).heightmap
    render_diffuse(hm, DiffuseConfig(resolution=16, spp=1))  # warm-up (JIT)
    dcfg = DiffuseConfig(resolution=512, spp=64)
    best = math.inf
    for _ in range(repeats):
        t = time.perf_counter()
        rgb, meta = render_diffuse(hm, dcfg, view="macro", seed=0)
        best = min(best, time.perf_counter() - t)
    return {"shape": list(rgb.shape[:2]), "spp": 64, "view": "macro", "light": dcfg.light,
            "mesh_triangles": meta["mesh_triangles"], "wall_s": round(best, 2),
            "mean_radiance": round(float(rgb.mean()), 4), "mitsuba_variant": meta["mitsuba_variant"]}


def bench_large_map(n: int = 4000) -> dict:
    from render_inspect.instruments import render_interferogram
    from render_inspect.mesh import heightmap_mesh
    from render_inspect.render import render_diffuse
    from render_inspect.scene import DiffuseConfig, InterferometerConfig

    rss0 = _peak_rss_mb()
    t = time.perf_counter()
    hm = synthetic_heightmap(n)
    gen_s = time.perf_counter() - t
    t = time.perf_counter()
    gm = heightmap_mesh(hm, normals=True)
    full = {"vertices": gm.n_vertices, "triangles": gm.n_faces,
            "bytes_MiB": round(gm.nbytes / 2**20, 1), "build_s": round(time.perf_counter() - t, 2)}
    del gm
    rss_mesh = _peak_rss_mb()
    x0, x1, y0, y1 = hm.extent
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    cfg = InterferometerConfig(pixel=0.001, field_of_view=(cx - 0.512, cy - 0.512, cx + 0.512, cy + 0.512),
                               subsamples=2, noise=True)
    t = time.perf_counter()
    ig = render_interferogram(hm, cfg)
    ig_s = time.perf_counter() - t
    t = time.perf_counter()
    rgb, meta = render_diffuse(hm, DiffuseConfig(resolution=512, spp=64), view="macro")
    dif_s = time.perf_counter() - t
    return {"map_shape": [n, n], "map_generate_s": round(gen_s, 2),
            "full_mesh": full, "peak_rss_after_full_mesh_MiB": round(rss_mesh, 0),
            "interferogram_window": list(ig.shape), "interferogram_s": round(ig_s, 2),
            "diffuse_macro_triangles": meta["mesh_triangles"],
            "diffuse_macro_stride": meta["mesh_stride"], "diffuse_macro_s": round(dif_s, 2),
            "peak_rss_MiB": round(_peak_rss_mb(), 0), "peak_rss_before_MiB": round(rss0, 0)}


def main(quick: bool = False) -> dict:
    out = {"cpu_count": os.cpu_count(), "load_average_1min": round(os.getloadavg()[0], 2)}
    out["interferogram"] = bench_interferogram()
    print(json.dumps({"interferogram": out["interferogram"]}, indent=1), flush=True)
    out["diffuse"] = bench_diffuse()
    print(json.dumps({"diffuse": out["diffuse"]}, indent=1), flush=True)
    if not quick:
        out["large_map"] = bench_large_map()
        print(json.dumps({"large_map": out["large_map"]}, indent=1), flush=True)
    out["load_average_1min_end"] = round(os.getloadavg()[0], 2)
    return out


if __name__ == "__main__":
    res = main(quick="--quick" in sys.argv[1:])
    print(json.dumps(res, indent=2))
