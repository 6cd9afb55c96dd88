"""Command implementations: simulate, toolpath, demo.  Each writes its output folder
atomically (a failed or interrupted run leaves nothing half-written)."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from . import __version__

DEMO_SCENE = Path(__file__).resolve().parent.parent / "scenes" / "sts_sinusoidal_grid.toml"


def _log(msg: str):
    print(msg, file=sys.stderr, flush=True)


def build_metrics(scene, res) -> dict:
    """metrics.json content of one simulation (contract keys of ARCHITECTURE.md)."""
    m = {"software_version": __version__, "scene_name": scene.name,
         "process": scene.process.kind, "compensation": scene.process.compensation,
         "seed": scene.simulation.seed, "samples": int(res.heightmap.design.size),
         "grid": {"shape": list(res.heightmap.shape), "pixel_mm": res.heightmap.pixel,
                  "origin_mm": list(res.heightmap.origin)},
         "timing_s": dict(res.timing_s)}
    for k, v in res.metrics.items():
        if k == "toolpath" and isinstance(v, dict):
            m.setdefault("toolpath", {}).update(v)
        else:
            m[k] = v
    if "lenslets" not in m and _is_lenslet_array(scene.design):
        m["lenslets"] = lenslet_metrics(scene, res.heightmap)
    tp = res.toolpath
    if tp is not None:
        m.setdefault("toolpath", {}).setdefault("points", int(tp.points))
        m["toolpath"].setdefault("revolutions", tp.revolutions)
        m["toolpath"].setdefault("feed_per_rev_mm", scene.process.feed_per_rev)
        if "x_velocity_max_mm_s" not in m["toolpath"]:
            kin = _kinematics(tp, scene)
            for k, v in (kin or {}).items():
                m["toolpath"].setdefault(k, v)
    return m


def _is_lenslet_array(design) -> bool:
    if design.type == "compound":
        return _is_lenslet_array(design.feature)
    return design.type == "lenslet_array"


def lenslet_metrics(scene, heightmap) -> list:
    """The ``lenslets`` table (centres, dislocations, form errors) of a lenslet-array part."""
    import warnings

    from .design import make_surface
    from .metrology import lenslet_table

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # lenslets outside the simulated window are left out
        return lenslet_table(heightmap, make_surface(scene.design), which="machined")


def _kinematics(path, scene) -> dict | None:
    try:
        from .toolpath._kinematics import kinematics
    except ImportError:
        return None
    limits = {k: getattr(scene.process, k) for k in ("x_velocity_limit_mm_s", "x_acceleration_limit_mm_s2",
                                                      "z_velocity_limit_mm_s", "z_acceleration_limit_mm_s2")}
    return kinematics(path, limits=limits)


def write_simulation(scene, res, out_dir: Path, *, preview: bool = True) -> dict:
    """Write heightmap.exr, metrics.json, toolpath.npz and residual.png into ``out_dir``."""
    from .io import save_map_png, write_json

    hm = res.heightmap
    hm.to_exr(out_dir / "heightmap.exr")
    if res.toolpath is not None:
        res.toolpath.save_npz(out_dir / "toolpath.npz")
    metrics = build_metrics(scene, res)
    if preview:
        r = metrics["residual"]
        save_map_png(out_dir / "residual.png", (hm.residual - r["mean_nm"] * 1e-6) * 1e6,
                     extent=hm.extent, cmap="RdBu_r", symmetric=True, label="machined - design (nm)",
                     title=f"{scene.name}: residual, compensation {scene.process.compensation}\n"
                           f"Sq {r['Sq_nm']:.2f} nm, Sz {r['Sz_nm']:.1f} nm, min {r['min_nm']:.1f} nm")
        for name, draw in res.plots.items():
            draw(out_dir / name)
        if res.toolpath is not None and "rcse_kinematics.png" not in res.plots:
            from .toolpath._kinematics import plot_kinematics

            plot_kinematics(res.toolpath, out_dir / "kinematics.png",
                            labels=(f"{scene.process.kind.upper()} path", ""),
                            title=f"{scene.name}: axis motion")
    write_json(out_dir / "metrics.json", metrics)
    (out_dir / "scene.json").write_text(json.dumps(scene.to_dict(), indent=2, sort_keys=True))
    return metrics


def run_simulate(scene, out) -> dict:
    """``render-inspect simulate``: heightmap.exr, metrics.json, toolpath.npz, residual.png."""
    from .io import atomic_output_dir
    from .machining import simulate_scene

    t0 = time.perf_counter()
    res = simulate_scene(scene)
    _log(f"simulated {res.heightmap.design.size:,} samples in {time.perf_counter() - t0:.2f} s")
    with atomic_output_dir(out) as tmp:
        metrics = write_simulation(scene, res, Path(tmp))
    r = metrics["residual"]
    _log(f"residual Sq {r['Sq_nm']:.3f} nm, Sz {r['Sz_nm']:.2f} nm, min {r['min_nm']:.2f} nm -> {out}")
    return metrics


def run_toolpath(scene, out, *, fmt: str = "npz"):
    """``render-inspect toolpath``: the full spiral path (npz, csv or nc) and its facts."""
    from .design import make_surface
    from .io import atomic_output_dir, write_json
    from .toolpath import build_toolpath

    if scene.process.kind == "sculpt":
        return _run_sculpt_program(scene, out, fmt)
    surface = make_surface(scene.design)
    region = None if scene.process.kind == "sts" else scene.simulation.region
    if scene.process.kind == "rcse":
        from .toolpath._rcse import build_rcse_toolpath

        path = build_rcse_toolpath(scene)
    else:
        path = build_toolpath(scene, surface, region=region)
    with atomic_output_dir(out) as tmp:
        tmp = Path(tmp)
        from .toolpath._export import export_toolpath

        export_toolpath(path, tmp, fmt=fmt, scene=scene)
        info = {"software_version": __version__, "scene_name": scene.name,
                "toolpath": {"points": path.points, "revolutions": path.revolutions,
                             "feed_per_rev_mm": scene.process.feed_per_rev,
                             **{k: v for k, v in path.meta.items() if k != "accessibility"}}}
        if "accessibility" in path.meta:
            info["accessibility"] = path.meta["accessibility"]
        kin = _kinematics(path, scene)
        if kin:
            info["toolpath"].update(kin)
        write_json(tmp / "toolpath.json", info)
    _log(f"tool path: {path.points:,} points, {path.revolutions:.1f} revolutions -> {out}")
    return path


def run_demo(out, *, quick: bool = False):
    """``render-inspect demo``: the seed-000 grid, compensated and uncompensated, then the
    renders and the comparison report when those stages are available."""
    from .scene import load_scene

    out = Path(out)
    overrides = ["simulation.region=[-0.25,-0.25,0.25,0.25]", "simulation.pixel=0.002"] if quick else []
    scene = load_scene(DEMO_SCENE, overrides)
    _log(f"demo: scene {DEMO_SCENE.name} -> {out}")
    try:
        from .report import run_compare
    except ImportError:
        run_compare = None
    if run_compare is not None:
        run_compare(scene, out)
        return
    run_simulate(scene, out / "compensated")
    run_simulate(scene.with_overrides(["process.compensation='none'"]), out / "uncompensated")


def _run_sculpt_program(scene, out, fmt):
    """Sculpturing is linear X-Y-Z, not turning: the program is (x, y, z, t) per target line.
    npz holds the arrays; csv one row per point; nc a generic G01 X Y Z program."""
    import io

    import numpy as np

    from .io import atomic_output_dir, atomic_write_bytes, atomic_write_text, write_json
    from .machining._sculpt import sculpt_program

    prog = sculpt_program(scene)
    n = prog["x"].size
    with atomic_output_dir(out) as tmp:
        tmp = Path(tmp)
        if fmt == "npz":
            buf = io.BytesIO()
            np.savez(buf, **prog)
            atomic_write_bytes(tmp / "toolpath.npz", buf.getvalue())
        elif fmt == "csv":
            rows = np.column_stack([prog["t"], prog["x"], prog["y"], prog["z"], prog["line"]])
            buf = io.StringIO()
            np.savetxt(buf, rows, fmt=["%.9f", "%.6f", "%.6f", "%.6f", "%d"], delimiter=",",
                       header="t_s,x_mm,y_mm,z_mm,line", comments="")
            atomic_write_text(tmp / "toolpath.csv", buf.getvalue())
        else:
            vc = scene.process.feed_mm_per_min
            lines = ["; render_inspect generic X-Y-Z sculpturing program (mm, mm/min)",
                     f"; software_version: {__version__}", f"; scene: {scene.name}",
                     f"; cutting speed: {vc} mm/min; vibration (not programmed): "
                     f"{scene.artifacts.vibration.frequency_hz} Hz, {scene.artifacts.vibration.amplitude} mm",
                     "G90 G94 G21"]
            prev = None
            for i in range(n):
                if prev is not None and prog["line"][i] != prev:
                    lines.append(f"; line {int(prog['line'][i])}")
                prev = prog["line"][i]
                lines.append(f"N{i + 1} G01 X{prog['x'][i]:.6f} Y{prog['y'][i]:.6f} Z{prog['z'][i]:.6f} F{vc:g}")
            atomic_write_text(tmp / "toolpath.nc", "\n".join(lines) + "\n")
        write_json(tmp / "toolpath.json", {"software_version": __version__, "scene_name": scene.name,
                                           "toolpath": {"points": int(n), "lines": int(prog["line"].max()) + 1,
                                                        "kind": "sculpt", "cut_time_s": float(prog["t"][-1])}})
    _log(f"sculpturing program: {n:,} points -> {out}")
    return prog
