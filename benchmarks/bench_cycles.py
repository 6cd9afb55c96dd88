"""Benchmark (issue 3, Cycles half): the 512 x 512, 64 spp diffuse-light image of the
machined seed-000 grid rendered by Mitsuba (``render_inspect.render.render_diffuse``) and by
Blender Cycles on the CPU (``render_inspect.render._cycles.render_cycles``) from the same
scene description (``diffuse_scene_spec``: mesh, camera, light, aluminium, exaggeration,
samples, path depth).  Reports both render times and the image difference (RMSE of the
linear images, mean FLIP of the sRGB images), next to each renderer's own Monte-Carlo noise
(the same renderer with another seed).  Goal: Mitsuba faster than Cycles.

Usage: ``.venv/bin/python benchmarks/bench_cycles.py [resolution] [spp]``; the images go
to ``out/bench_cycles/``.
"""

from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "out" / "bench_cycles"


def _srgb(linear: np.ndarray) -> np.ndarray:
    a = np.clip(np.nan_to_num(linear), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055).astype(np.float32)


def image_difference(reference: np.ndarray, test: np.ndarray) -> dict:
    """RMSE and mean absolute difference of two linear (H, W, 3) images, and the mean
    LDR-FLIP of their sRGB encodings (0 = identical, 1 = as different as can be)."""
    import flip_evaluator

    ref = np.ascontiguousarray(reference, dtype=np.float32)
    tst = np.ascontiguousarray(test, dtype=np.float32)
    if ref.shape != tst.shape or ref.ndim != 3 or ref.shape[2] != 3:
        raise ValueError(f"images must both be H x W x 3, got {ref.shape} and {tst.shape}")
    flip_map, flip_mean, _ = flip_evaluator.evaluate(_srgb(ref), _srgb(tst), "LDR",
                                                     inputsRGB=True, applyMagma=False)
    d = tst.astype(np.float64) - ref
    return {"rmse": float(np.sqrt(np.mean(d * d))), "mean_abs": float(np.mean(np.abs(d))),
            "mean_ref": float(ref.mean()), "mean_test": float(tst.mean()),
            "flip_mean": float(flip_mean), "flip_map": np.asarray(flip_map)}


def main(resolution: int = 512, spp: int = 64, *, exaggeration: float | None = None,
         noise_floor: bool = True) -> dict:
    """Render both, compare, print and return the figures (``exaggeration`` None: the
    scene's ``render.diffuse.exaggeration``, 200)."""
    from render_inspect.io import save_png
    from render_inspect.pipeline import simulate as simulate_scene
    from render_inspect.render import render_diffuse
    from render_inspect.render._cycles import render_cycles
    from render_inspect.scene import DiffuseConfig, load_scene

    scene = load_scene(REPO / "scenes" / "sts_sinusoidal_grid.toml",
                       ["simulation.region=[-0.5, -0.5, 0.5, 0.5]", "simulation.pixel=0.002"])
    hm = simulate_scene(scene).heightmap
    dcfg = scene.render.diffuse.model_copy(update={"resolution": resolution, "spp": spp})
    if exaggeration is not None:
        dcfg = dcfg.model_copy(update={"exaggeration": float(exaggeration)})
    small = DiffuseConfig(resolution=16, spp=1)

    # warm-up: Mitsuba's variant choice and JIT, Cycles' kernel load
    render_diffuse(hm, small)
    render_cycles(hm, small)

    t0 = time.perf_counter()
    mi_img, mi_meta = render_diffuse(hm, dcfg, seed=0)
    mi_wall = time.perf_counter() - t0
    t0 = time.perf_counter()
    cy_img, cy_meta = render_cycles(hm, dcfg, seed=0)
    cy_wall = time.perf_counter() - t0

    diff = image_difference(mi_img, cy_img)
    fig = {
        "resolution": [int(mi_img.shape[1]), int(mi_img.shape[0])], "spp": spp,
        "view": mi_meta["view"], "light": dcfg.light,
        "vertical_exaggeration": mi_meta["vertical_exaggeration"],
        "heightmap_shape": list(hm.shape),
        "mesh_triangles": {"mitsuba": mi_meta["mesh_triangles"], "cycles": cy_meta["mesh_triangles"]},
        "mitsuba_variant": mi_meta["mitsuba_variant"],
        "cycles": cy_meta["renderer"], "cpu_threads": os.cpu_count(),
        "mitsuba_wall_s": round(mi_wall, 2),
        "cycles_wall_s": round(cy_wall, 2), "cycles_render_s": round(cy_meta["render_time_s"], 2),
        "cycles_mesh_s": round(cy_meta["mesh_time_s"], 2),
        "cycles_over_mitsuba": round(cy_wall / mi_wall, 2),
        "mitsuba_faster": bool(mi_wall < cy_wall),
        "rmse": round(diff["rmse"], 5), "mean_abs": round(diff["mean_abs"], 5),
        "flip_mean": round(diff["flip_mean"], 4),
        "mean_mitsuba": round(diff["mean_ref"], 4), "mean_cycles": round(diff["mean_test"], 4),
    }
    OUT.mkdir(parents=True, exist_ok=True)
    save_png(OUT / "mitsuba.png", _srgb(mi_img))
    save_png(OUT / "cycles.png", _srgb(cy_img))
    save_png(OUT / "flip.png", np.squeeze(diff["flip_map"]))
    if noise_floor:
        mi2, _ = render_diffuse(hm, dcfg, seed=1)
        cy2, _ = render_cycles(hm, dcfg, seed=1)
        n_mi = image_difference(mi_img, mi2)
        n_cy = image_difference(cy_img, cy2)
        fig["noise_rmse"] = {"mitsuba_seed0_vs_seed1": round(n_mi["rmse"], 5),
                             "cycles_seed0_vs_seed1": round(n_cy["rmse"], 5)}
        fig["noise_flip_mean"] = {"mitsuba_seed0_vs_seed1": round(n_mi["flip_mean"], 4),
                                  "cycles_seed0_vs_seed1": round(n_cy["flip_mean"], 4)}
    fig["images"] = str(OUT.relative_to(REPO))
    print(json.dumps(fig, indent=2))
    return fig


if __name__ == "__main__":
    args = [int(a) for a in sys.argv[1:3]]
    main(*args, **({"exaggeration": float(sys.argv[3])} if len(sys.argv) > 3 else {}))
