"""``render`` and ``compare``: images of a scene's surface through the registered
instruments, and two variants of a scene side by side."""

from __future__ import annotations

import argparse
from typing import Any

from ..core.lazy import freeze_lasting, passive_omp_wait
from ._args import _add_scene_args, _Registered, _render_kinds, scene_of


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("render", help="virtual interferometer and diffuse-light images (Mitsuba 3)")
    _add_scene_args(p)
    p.add_argument("--surface", choices=["design", "machined"], default="machined")
    p.add_argument("--kind", choices=_Registered(_render_kinds), default="all", metavar="KIND",
                   help="a registered instrument, diffuse or all: %(choices)s (default all)")

    p = sub.add_parser("compare", help="two variants of the scene (the process's own pair, e.g. "
                                       "compensated vs uncompensated, or --vary): images, metrics, "
                                       "report.html")
    _add_scene_args(p)
    p.add_argument("--measured", default=None, help="measured height map (X3P, EXR, ...) to compare, "
                                                    "or a profile (text export, Dektak .opdx, X3P PRF)")
    p.add_argument("--vary", default=None, metavar="KEY=A,B",
                   help="compare KEY = A against KEY = B instead of the process's own pair, e.g. "
                        "--vary process.compensation=normal,z (TOML values)")
    p.add_argument("--force", action="store_true",
                   help="compare the measured map even when it does not match the design "
                        "(overlap or residual checks fail)")
    p.add_argument("--line", default=None, metavar="X0,Y0,X1,Y1",
                   help="with --measured PROFILE: the line on the part, mm (default for a turned "
                        "part: a diameter through the spindle axis)")
    p.add_argument("--units", default=None, metavar="U",
                   help="with --measured PROFILE: a text file's units when it does not state "
                        "them: um, mm, nm or POSITION,HEIGHT (e.g. um,nm)")
    p.add_argument("--filter", default=None, metavar="S,L",
                   help="with --measured PROFILE: ISO 16610-21 Gaussian cut-offs lambda_s,lambda_c "
                        "in mm (default: ISO 21920-3's choice for the measured profile)")
    p.add_argument("--repeat", type=int, default=1, metavar="N",
                   help="measure each variant N times (1..100), each with fresh camera noise, "
                        "and report the difference's repeatability (default 1)")


def _render(args: argparse.Namespace, overwrite: bool) -> dict:
    # the scene is checked first; the pipeline (numba, SciPy, the renderers) is imported
    # after it, not at the top of the module, so that `render-inspect --help` and a
    # mistake in the scene or a key are answered at once
    scene = scene_of(args)
    # (imported once the input is checked)
    from .. import pipeline

    # the objects made so far (the modules, the scene's schema) live as long as the
    # process: the collector leaves them out of its later passes (a few tenths of a
    # CPU-second over the libraries the render loads next)
    freeze_lasting()
    # the threads of numba's parallel passes wait asleep between them instead of spinning
    # (no step before this one starts them): a spinning thread holds the second core that
    # the render's own threads (the truth, the FFTs' second worker) need meanwhile
    passive_omp_wait()
    return pipeline.run_render(scene, args.out, surface=args.surface, kind=args.kind,
                               overwrite=overwrite)


def _compare(args: argparse.Namespace, overwrite: bool) -> dict:
    # (the scene first, the pipeline after it, as above)
    scene = scene_of(args)
    # (imported once the input is checked)
    from .. import pipeline
    # (the scene package is loaded by scene_of already; kept local like the pipeline)
    from ..scene import find_scene

    # (a measured profile is compared along a line: pipeline.run_compare_profile)
    return pipeline.run_compare_command(scene, args.out, measured=args.measured,
                                        vary=args.vary, force=args.force, line=args.line,
                                        units=args.units, filter_spec=args.filter,
                                        repeat=args.repeat, overwrite=overwrite,
                                        scene_file=find_scene(args.scene))


#: command -> what runs it, ``(args, overwrite) -> result``
RUN = {"render": _render, "compare": _compare}
#: commands whose process ends as soon as their files are written (``_main.EXIT_AT_ONCE``)
EXIT_AT_ONCE = ("render",)
