"""``render-inspect`` command line.  Heavy engines are imported lazily inside commands,
so ``render-inspect --help`` stays fast."""

from __future__ import annotations

import argparse
import sys
import time

from . import __version__


def _add_scene_args(p: argparse.ArgumentParser, *, out=True):
    p.add_argument("scene", help="scene file (TOML)")
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

    p = sub.add_parser("toolpath", help="tool path only: toolpath.npz (or csv / nc)")
    _add_scene_args(p)
    p.add_argument("--format", choices=["npz", "csv", "nc"], default="npz")

    p = sub.add_parser("render", help="synthetic interferometer and diffuse-light images (Mitsuba 3)")
    _add_scene_args(p)
    p.add_argument("--surface", choices=["design", "machined"], default="machined")
    p.add_argument("--kind", choices=["interferometer", "diffuse", "all"], default="all")

    p = sub.add_parser("compare", help="compensated vs uncompensated (or vs --measured): images, metrics, report.html")
    _add_scene_args(p)
    p.add_argument("--measured", default=None, help="measured height map (X3P, EXR, ...) to compare")

    p = sub.add_parser("demo", help="set-up check plus the main job on the built-in seed-000 grid scene")
    p.add_argument("--out", required=True)
    p.add_argument("--quick", action="store_true", help="smaller images (for tests)")
    return ap


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    from .errors import RenderInspectError

    t0 = time.perf_counter()
    try:
        if args.command == "demo":
            from .pipeline import run_demo

            run_demo(args.out, quick=args.quick)
        else:
            from .scene import load_scene

            scene = load_scene(args.scene, args.overrides)
            if args.command == "simulate":
                from .pipeline import run_simulate

                run_simulate(scene, args.out)
            elif args.command == "toolpath":
                from .pipeline import run_toolpath

                run_toolpath(scene, args.out, fmt=args.format)
            elif args.command == "render":
                from .render import run_render

                run_render(scene, args.out, surface=args.surface, kind=args.kind)
            elif args.command == "compare":
                from .report import run_compare

                run_compare(scene, args.out, measured=args.measured)
    except RenderInspectError as err:
        print(f"render-inspect {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted; no partial output was left", file=sys.stderr)
        return 130
    print(f"render-inspect {args.command}: done in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
