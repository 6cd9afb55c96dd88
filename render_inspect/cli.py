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

    p = sub.add_parser("demo", help="set-up check plus the main job on the shipped seed-000 grid scene")
    p.add_argument("--out", required=True)
    p.add_argument("--quick", action="store_true", help="smaller images (for tests)")
    return ap


def _run(args) -> None:
    # the pipeline imports numba, scipy and pydantic: imported here, not at the top of the
    # module, so that `render-inspect --help` answers at once
    from . import pipeline

    # (the scene schema imports pydantic and the registries: same reason)
    from .scene import load_scene

    if args.command == "demo":
        pipeline.run_demo(args.out, quick=args.quick)
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
        pipeline.run_compare(scene, args.out, measured=args.measured)


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
        print("interrupted; no partial output was left", file=sys.stderr)
        return 130
    print(f"render-inspect {args.command}: done in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
