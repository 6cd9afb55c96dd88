"""Benchmark: the seed-004 RCSE tool path (1,368,001 CCPs) against the conventional method.

Times (best of ``repeats``, this machine):
- RCSE: CCPs generated directly on the spiral, exact element heights (target < 1 s;
  the paper: 1,791 s in MATLAB);
- conventional: modelling the design on a rectangular point cloud (5 um) and taking the
  spiral's CCPs from it by interpolation (the paper: 4,734 s + 9,809 s = 14,543 s);
- kinematics of the full path and its NC / CSV export.

``python benchmarks/bench_rcse.py`` prints the figures and writes them into the marked
block of docs/rcse_and_kinematics.md (``--no-docs`` to skip).
"""

from __future__ import annotations

import json
import platform
import sys
import tempfile
import time
from pathlib import Path

from _timing import best_of

REPO = Path(__file__).resolve().parents[1]
DOC = REPO / "docs" / "rcse_and_kinematics.md"
BEGIN, END = "<!-- bench_rcse:begin -->", "<!-- bench_rcse:end -->"


def main(repeats: int = 3, export: bool = True, write_docs: bool = True) -> dict:
    import numpy as np

    from render_inspect.design import make_surface
    from render_inspect.io import write_csv, write_nc
    from render_inspect.scene import load_scene
    from render_inspect.toolpath import ToolPath
    from render_inspect.toolpath._kinematics import kinematics
    from render_inspect.toolpath._rcse import RingLayout, conventional_ccps, rcse_ccps

    scene = load_scene(REPO / "scenes" / "rcse_circular_array.toml")
    p = scene.process
    layout = RingLayout.from_config(scene.design)
    surface = make_surface(scene.design)

    def gen():
        return rcse_ccps(layout, r_outer=p.workpiece_radius, pitch=p.feed_per_rev,
                         points_per_rev=p.points_per_rev)

    gen()  # warm caches
    t_rcse, c = best_of(gen, repeats)
    res = {"ccps": int(c.theta.size), "rcse_s": t_rcse,
           "rcse_ccps_per_s": c.theta.size / t_rcse}

    t0 = time.perf_counter()
    conv = conventional_ccps(surface, c.theta, c.rho, grid_spacing=0.005, interpolation="linear",
                             snap_to_rows=True)
    res["conventional_wall_s"] = time.perf_counter() - t0
    res["conventional_modelling_s"] = conv["modelling_s"]
    res["conventional_toolpath_s"] = conv["toolpath_s"]
    res["conventional_grid"] = conv["grid_shape"]
    res["conventional_profile_error_max_nm"] = float(np.max(np.abs(conv["profile_error"])) * 1e6)
    res["conventional_profile_error_rms_nm"] = float(np.sqrt(np.mean(conv["profile_error"] ** 2)) * 1e6)
    conv3 = conventional_ccps(surface, c.theta, c.rho, grid_spacing=0.005, interpolation="cubic",
                              snap_to_rows=False)
    res["conventional_cubic_exact_xy_toolpath_s"] = conv3["toolpath_s"]
    res["conventional_cubic_exact_xy_profile_error_max_nm"] = float(np.max(np.abs(conv3["profile_error"])) * 1e6)
    err = c.z - surface.height(c.x, c.y)
    res["rcse_profile_error_max_nm"] = float(np.max(np.abs(err)) * 1e6)

    omega = 2 * np.pi * p.spindle_rpm / 60
    t = c.theta / omega
    rp = ToolPath(c.theta, c.rho, c.z, t, {"spindle_rpm": p.spindle_rpm})
    cp = ToolPath(c.theta, conv["rho"], conv["z"], t, {})
    t0 = time.perf_counter()
    kr = kinematics(rp)
    res["kinematics_s"] = time.perf_counter() - t0
    kc = kinematics(cp)
    for name, k in (("rcse", kr), ("conventional", kc)):
        for key in ("x_velocity_max_mm_s", "x_acceleration_max_mm_s2", "x_velocity_mean_mm_s", "x_reversals"):
            res[f"{name}_{key}"] = k[key]
    if export:
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            f = write_nc(Path(tmp) / "toolpath.nc", rp, header={"scene": scene.name})
            res["nc_write_s"] = time.perf_counter() - t0
            res["nc_mb"] = f.stat().st_size / 1e6
            t0 = time.perf_counter()
            write_csv(Path(tmp) / "toolpath.csv", rp)
            res["csv_write_s"] = time.perf_counter() - t0
    res["machine"] = f"{platform.machine()}, {platform.python_implementation()} {platform.python_version()}"
    for k, v in res.items():
        print(f"{k:48s} {v:.4g}" if isinstance(v, float) else f"{k:48s} {v}")
    if write_docs:
        _write_docs(res)
    return res


def _write_docs(res: dict) -> None:
    if not DOC.is_file():
        return
    rows = [
        ("CCPs (seed 004 case, whole part)", f"{res['ccps']:,}"),
        ("RCSE path generation", f"{res['rcse_s']:.3f} s ({res['rcse_ccps_per_s'] / 1e6:.1f} M CCPs/s); paper 1,791 s (MATLAB)"),
        ("conventional: modelling (grid %d x %d, 5 um)" % tuple(res["conventional_grid"]),
         f"{res['conventional_modelling_s']:.2f} s; paper 4,734 s"),
        ("conventional: CCPs by interpolation (linear, on rows)",
         f"{res['conventional_toolpath_s']:.3f} s; paper 9,809 s"),
        ("conventional: cubic B-spline at the exact spiral point (prefilter counted as modelling)", f"{res['conventional_cubic_exact_xy_toolpath_s']:.3f} s"),
        ("profile error max: RCSE / conventional linear / conventional cubic",
         f"{res['rcse_profile_error_max_nm']:.2g} / {res['conventional_profile_error_max_nm']:.1f} / "
         f"{res['conventional_cubic_exact_xy_profile_error_max_nm']:.1f} nm"),
        ("max X velocity: RCSE / conventional",
         f"{res['rcse_x_velocity_max_mm_s']:.4g} / {res['conventional_x_velocity_max_mm_s']:.3g} mm/s"),
        ("max X acceleration: RCSE / conventional",
         f"{res['rcse_x_acceleration_max_mm_s2']:.2g} / {res['conventional_x_acceleration_max_mm_s2']:.3g} mm/s^2"),
        ("X reversals: RCSE / conventional", f"{res['rcse_x_reversals']} / {res['conventional_x_reversals']:,}"),
        ("kinematics of 1.37 M points", f"{res['kinematics_s']:.2f} s"),
    ]
    if "nc_write_s" in res:
        rows.append(("write toolpath.nc / toolpath.csv",
                     f"{res['nc_write_s']:.1f} s ({res['nc_mb']:.0f} MB) / {res['csv_write_s']:.1f} s"))
    table = "| figure | value |\n|---|---|\n" + "\n".join(f"| {a} | {b} |" for a, b in rows)
    block = (f"{BEGIN}\nMeasured by `benchmarks/bench_rcse.py` on {time.strftime('%Y-%m-%d')} "
             f"({res['machine']}, 2 shared cores):\n\n{table}\n{END}")
    text = DOC.read_text()
    if BEGIN in text and END in text:
        text = text[:text.index(BEGIN)] + block + text[text.index(END) + len(END):]
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    from render_inspect.io import atomic_write_text

    atomic_write_text(DOC, text)


if __name__ == "__main__":
    out = main(write_docs="--no-docs" not in sys.argv)
    print(json.dumps(out, default=str))
