"""``sweep``, ``regress`` and ``demo``: many runs at once (a parameter sweep on Dask, the
image regression of the shipped cases) and the set-up check with the main job."""

from __future__ import annotations

import argparse
from typing import Any

from ..core.errors import RenderInspectError
from ._args import _add_cluster_args, _add_out_args, _add_set_arg, _add_verbosity


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("sweep", help="parameter sweep on Dask: results.jsonl, results.csv, summary, plots "
                                     "(resumable)")
    p.add_argument("sweep", help="sweep file (TOML) or the name of a shipped sweep, e.g. fig15_small")
    p.add_argument("--out", required=True, help="the sweep's folder; finished points there are not run again")
    p.add_argument("--overwrite", action="store_true",
                   help="write the sweep into a non-empty folder that is not a sweep's (its files "
                        "are left in place)")
    _add_cluster_args(p, workers="process workers of the LocalCluster (default: the CPU count)",
                      scheduler="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                                "(default: a LocalCluster on this machine)", scheduler_first=True)
    p.add_argument("--retry-failed", action="store_true", help="run the points recorded as failed again")
    p.add_argument("--yes", action="store_true",
                   help="run a sweep with more than 500 points still to run (refused without it, "
                        "with its size and a rough time)")
    _add_verbosity(p)

    p = sub.add_parser("regress", help="image regression: render scenes/regression/ and compare with "
                                       "the references")
    p.add_argument("--update", action="store_true",
                   help="make the references anew (records the software version and Mitsuba variant)")
    p.add_argument("--only", metavar="NAME", default=None,
                   help="case names or glob patterns, comma-separated")
    p.add_argument("--out", default="out/regress",
                   help="summary.html and the images that differ (default: out/regress); written "
                        "whole when the run ends, untouched otherwise")
    p.add_argument("--overwrite", action="store_true",
                   help="replace --out even if it holds files render-inspect did not write")
    _add_set_arg(p, help="override a key in every case (what-if checks; not with --update)")
    _add_verbosity(p)

    p = sub.add_parser("demo", help="set-up check plus the main job on the shipped sinusoidal grid "
                                        "(Li et al. 2018)")
    _add_out_args(p)
    p.add_argument("--quick", action="store_true", help="smaller images (for tests)")
    _add_set_arg(p, help="override a key of the demo's scene, e.g. --set render.diffuse.spp=4 "
                         "(applied after --quick's window)")
    _add_verbosity(p)


def _sweep(args: argparse.Namespace, overwrite: bool) -> dict:
    # the pipeline imports numba, scipy and pydantic: imported here, not at the top of the
    # module, so that `render-inspect --help` answers at once
    from .. import pipeline

    info = pipeline.run_sweep(pipeline.find_sweep(args.sweep), args.out,
                              scheduler=args.scheduler, workers=args.workers,
                              retry_failed=args.retry_failed, overwrite=overwrite,
                              yes=args.yes)
    failure = pipeline.sweep_failure(info, args.out)
    if failure:
        raise RenderInspectError(failure)
    return info


def _regress(args: argparse.Namespace, overwrite: bool) -> dict:
    # (the pipeline is imported lazily, as above)
    from .. import pipeline

    return pipeline.run_regress(update=args.update, only=args.only, out=args.out,
                                overrides=args.overrides, overwrite=overwrite)


def _demo(args: argparse.Namespace, overwrite: bool) -> dict:
    # (the pipeline is imported lazily, as above)
    from .. import pipeline

    return pipeline.run_demo(args.out, quick=args.quick, overwrite=overwrite,
                             overrides=args.overrides)


#: command -> what runs it, ``(args, overwrite) -> result``
RUN = {"sweep": _sweep, "regress": _regress, "demo": _demo}
