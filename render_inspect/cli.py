"""``render-inspect`` command line: argparse -> :mod:`render_inspect.pipeline`.

Exit codes: 0 done, 1 an error in the input or the run (one line on stderr naming the
parameter, the allowed range and the value received), 2 a usage error (argparse),
130 interrupted.
"""

from __future__ import annotations

import argparse
import logging
import sys
import time

from . import __version__
from .core.errors import RenderInspectError

log = logging.getLogger("render_inspect")


def _add_scene_args(p: argparse.ArgumentParser, *, out=True):
    p.add_argument("scene", help="scene file (TOML) or the name of a shipped scene, "
                                 "e.g. sts_sinusoidal_grid")
    if out:
        p.add_argument("--out", required=True, help="output folder (written atomically)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key, e.g. --set process.spindle_rpm=100 (TOML value syntax)")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="render-inspect",
        description="Simulate, render and inspect diamond-machined freeform optics before they are cut.")
    ap.add_argument("--version", action="version", version=f"render-inspect {__version__}")
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("simulate", help="tool path + machined surface: heightmap.exr, metrics.json, preview")
    _add_scene_args(p)
    p.add_argument("--tiled", action="store_true",
                   help="compute the map tile by tile into heightmap.zarr (automatic when it does not fit "
                        "simulation.max_memory_gb)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="run the tiles on a local Dask cluster of N worker processes (implies --tiled)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the tiles on the Dask cluster at ADDRESS, e.g. tcp://host:8786 (implies --tiled)")
    p.add_argument("--tile", type=int, default=1024, metavar="PIXELS",
                   help="tile side in pixels, a multiple of 64 (default 1024)")

    p = sub.add_parser("toolpath", help="the machine program only: toolpath.npz (or csv / nc)")
    _add_scene_args(p)
    p.add_argument("--format", choices=["npz", "csv", "nc"], default="npz")

    p = sub.add_parser("render", help="virtual interferometer and diffuse-light images (Mitsuba 3)")
    _add_scene_args(p)
    p.add_argument("--surface", choices=["design", "machined"], default="machined")
    p.add_argument("--kind", choices=["interferometer", "diffuse", "all"], default="all")

    p = sub.add_parser("compare", help="compensated vs uncompensated (or vs --measured): images, metrics, report.html")
    _add_scene_args(p)
    p.add_argument("--measured", default=None, help="measured height map (X3P, EXR, ...) to compare")
    p.add_argument("--force", action="store_true",
                   help="compare the measured map even when it does not match the design "
                        "(overlap or residual checks fail)")

    p = sub.add_parser("analyze", help="ISO 25178-2 parameters of one height map file (measured "
                                       "or simulated): metrics.json, height.png, --x3p")
    p.add_argument("file", help="height map: X3P, SUR, PLU, DAT (MetroPro), DATX, OPD, TMD, NMS, "
                                "heightmap.exr, ...")
    p.add_argument("--out", required=True, help="output folder (written atomically)")
    p.add_argument("--form", choices=["none", "plane", "poly2", "sphere"], default="plane",
                   help="form removed first (none: the mean only)")
    p.add_argument("--filter", default=None, metavar="S,L",
                   help="ISO 16610-61 Gaussian nesting indices in mm, e.g. 0.0025,0.8 or ,0.8")
    p.add_argument("--outliers", choices=["none", "sigma"], default="none",
                   help="sigma: leave out the 3-sigma second-difference outliers (counted either way)")
    p.add_argument("--slope", choices=["forward", "central"], default="forward",
                   help="derivative estimator of Sdq/Sdr (forward: as SurfaceTopography and surfalize)")
    p.add_argument("--x3p", action="store_true", help="also write the evaluated surface as height.x3p")

    p = sub.add_parser("measure", help="height from interferometer frames alone: height.exr, metrics.json")
    p.add_argument("frames", help="interferogram.exr (frames + settings), or a TIFF / PNG stack "
                                  "or a folder of frames with a settings JSON")
    p.add_argument("--out", required=True, help="output folder (written atomically)")
    p.add_argument("--algorithm", default="auto",
                   choices=["auto", "4step", "5step", "hariharan", "lsq", "envelope",
                            "envelope+phase"],
                   help="PSI: 4step, 5step (= hariharan), lsq; CSI: envelope, envelope+phase; "
                        "auto: by mode and frame count")
    p.add_argument("--settings", default=None,
                   help="settings JSON of a TIFF / PNG stack (default: beside it)")
    p.add_argument("--min-modulation", type=float, default=0.05, dest="min_modulation",
                   help="pixels with lower fringe contrast are not measured (default 0.05)")

    p = sub.add_parser("characterise", help="the virtual instrument's transfer function, step "
                                            "response, slope limit and noise (ISO 25178-600 style)")
    p.add_argument("--objective", default="20x", help="objective preset (2.5x, 5x, 10x, 20x, 50x, 100x)")
    p.add_argument("--out", required=True, help="output folder (written atomically)")
    p.add_argument("--mode", choices=["psi", "csi"], default="psi")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override an instrument key of [render.interferometer], e.g. "
                        "--set numerical_aperture=0.5 (TOML value syntax)")
    p.add_argument("--seed", type=int, default=0, help="seed of the camera noise")
    p.add_argument("--quick", action="store_true", help="fewer points, smaller fields (for tests)")

    p = sub.add_parser("sweep", help="parameter sweep on Dask: results.jsonl, results.csv, summary, plots "
                                     "(resumable)")
    p.add_argument("sweep", help="sweep file (TOML) or the name of a shipped sweep, e.g. fig15_small")
    p.add_argument("--out", required=True, help="the sweep's folder; finished points there are not run again")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", default=None,
                       help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                            "(default: a LocalCluster on this machine)")
    where.add_argument("--workers", metavar="N", type=int, default=None,
                       help="process workers of the LocalCluster (default: the CPU count)")
    p.add_argument("--retry-failed", action="store_true", help="run the points recorded as failed again")

    p = sub.add_parser("regress", help="image regression: render scenes/regression/ and compare with "
                                       "the references")
    p.add_argument("--update", action="store_true",
                   help="make the references anew (records the software version and Mitsuba variant)")
    p.add_argument("--only", metavar="NAME", default=None,
                   help="case names or glob patterns, comma-separated")
    p.add_argument("--out", default="out/regress",
                   help="summary.html and the images that differ (default: out/regress)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key in every case (what-if checks; not with --update)")

    p = sub.add_parser("demo", help="set-up check plus the main job on the shipped seed-000 grid scene")
    p.add_argument("--out", required=True)
    p.add_argument("--quick", action="store_true", help="smaller images (for tests)")
    return ap


def _run(args) -> None:
    # the pipeline imports numba, scipy and pydantic: imported here, not at the top of the
    # module, so that `render-inspect --help` answers at once
    from . import pipeline

    # (the scene schema imports pydantic and the registries: same reason)
    from .scene import instrument_config, load_scene

    if args.command == "demo":
        pipeline.run_demo(args.out, quick=args.quick)
        return
    if args.command == "analyze":
        pipeline.run_analyze(args.file, args.out, form=args.form, filter_spec=args.filter,
                             outliers=args.outliers, slope=args.slope, x3p=args.x3p)
        return
    if args.command == "measure":
        pipeline.run_measure(args.frames, args.out, algorithm=args.algorithm,
                             settings=args.settings, min_modulation=args.min_modulation)
        return
    if args.command == "characterise":
        pipeline.run_characterise(instrument_config(args.objective, args.mode, args.overrides),
                                  args.out, quick=args.quick, seed=args.seed)
        return
    if args.command == "sweep":
        info = pipeline.run_sweep(pipeline.find_sweep(args.sweep), args.out,
                                  scheduler=args.scheduler, workers=args.workers,
                                  retry_failed=args.retry_failed)
        if info["failed"]:
            raise RenderInspectError(
                f"{info['failed']} of {info['points']} points failed (their errors are in "
                f"{args.out}/summary.md and results.csv); the other points are done; rerun "
                f"with --retry-failed to try the failed ones again")
        return
    if args.command == "regress":
        pipeline.run_regress(update=args.update, only=args.only, out=args.out,
                             overrides=args.overrides)
        return
    scene = load_scene(args.scene, args.overrides)
    if args.command == "simulate":
        pipeline.run_simulate(scene, args.out, tiled=True if args.tiled else None, workers=args.workers,
                              scheduler=args.scheduler, tile=args.tile)
    elif args.command == "toolpath":
        pipeline.run_toolpath(scene, args.out, fmt=args.format)
    elif args.command == "render":
        pipeline.run_render(scene, args.out, surface=args.surface, kind=args.kind)
    elif args.command == "compare":
        pipeline.run_compare(scene, args.out, measured=args.measured, force=args.force)


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    if not log.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(message)s"))
        log.addHandler(handler)
        log.setLevel(logging.INFO)
    t0 = time.perf_counter()
    try:
        _run(args)
    except RenderInspectError as err:
        print(f"render-inspect {args.command}: error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        if args.command == "sweep":
            print(f"interrupted; the finished points are kept in {args.out}/results.jsonl: run the "
                  f"same command again to go on", file=sys.stderr)
        else:
            print("interrupted; no partial output was left", file=sys.stderr)
        return 130
    print(f"render-inspect {args.command}: done in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
