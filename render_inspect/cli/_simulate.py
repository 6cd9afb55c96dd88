"""``simulate`` and ``toolpath``: a scene's machined surface, or its machine program only."""

from __future__ import annotations

import argparse
from typing import Any

from .. import _early_signals
from ..core.lazy import freeze_lasting
from ._args import _add_cluster_args, _add_scene_args, _program_formats, _Registered, scene_of


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("simulate", help="tool path + machined surface: heightmap.exr, metrics.json, preview")
    _add_scene_args(p)
    p.add_argument("--tiled", action="store_true",
                   help="compute the map tile by tile into heightmap.zarr (automatic when it does not fit "
                        "the memory budget: simulation.max_memory_gb, by default 80%% of the free memory)")
    _add_cluster_args(p, workers="run the tiles on a local Dask cluster of N worker processes (implies --tiled)",
                      scheduler="run the tiles on the Dask cluster at ADDRESS, e.g. tcp://host:8786 "
                                "(implies --tiled)", exclusive=False)
    p.add_argument("--tile", type=int, default=1024, metavar="PIXELS",
                   help="tile side in pixels, a power of two from 64 to 16384 (default 1024)")

    p = sub.add_parser("toolpath", help="the machine program only: toolpath.npz (or csv / nc / "
                                        "any registered format)")
    _add_scene_args(p)
    p.add_argument("--format", choices=_Registered(_program_formats), default="npz",
                   metavar="FORMAT", help="a registered program format: %(choices)s (default npz)")
    p.add_argument("--nc-comments", dest="nc_comments", choices=("semicolon", "parenthesis"),
                   default=None, help="--format nc: the comment lines as '; text' (default; "
                                      "RS274NGC / LinuxCNC, Siemens 840D) or '(text)' (Fanuc-type "
                                      "controls, where ';' ends a block)")
    p.add_argument("--nc-block-numbers", dest="nc_block_numbers", type=_block_numbers,
                   default=None, metavar="STEP|off",
                   help="--format nc: the increment of the block numbers (default 1: N1, N2, "
                        "...; 10: N10, N20, ...; at most 1000) or 'off' for none")


def _block_numbers(text: str) -> int | str:
    """``--nc-block-numbers``: 'off' (0) or the increment as a whole number (its range is
    checked with the scene, one line naming the option)."""
    t = text.strip().lower()
    if t in ("off", "none", "0"):
        return 0
    try:
        return int(t)
    except ValueError:
        return text  # (refused by the check, naming the option and the value)


def _simulate(args: argparse.Namespace, overwrite: bool) -> dict:
    # the scene is checked first; the pipeline (numba, SciPy, the writers) is imported
    # after it, not at the top of the module, so that `render-inspect --help` and a
    # mistake in the scene or a key are answered at once
    scene = scene_of(args)
    # (imported once the input is checked)
    from .. import pipeline

    # the objects made so far (the modules, the scene's schema) live as long as the
    # process: the collector leaves them out of its passes over what numba loads next
    freeze_lasting()
    # the figures are drawn by a second process beside the computation when this process
    # is the program's own (not a program that called main())
    return pipeline.run_simulate(scene, args.out, tiled=True if args.tiled else None,
                                 workers=args.workers, scheduler=args.scheduler,
                                 tile=args.tile, overwrite=overwrite,
                                 figure_process=_early_signals.is_program())


def _toolpath(args: argparse.Namespace, overwrite: bool) -> object:
    # (the scene first, the pipeline after it, as above)
    scene = scene_of(args)
    # (imported once the input is checked)
    from .. import pipeline

    # (the scene package is loaded by scene_of already; kept local like the pipeline)
    from ..scene import find_scene

    return pipeline.run_toolpath(scene, args.out, fmt=args.format, overwrite=overwrite,
                                 scene_file=find_scene(args.scene), nc_comments=args.nc_comments,
                                 nc_block_numbers=args.nc_block_numbers)


#: command -> what runs it, ``(args, overwrite) -> result``
RUN = {"simulate": _simulate, "toolpath": _toolpath}
#: commands whose process ends as soon as their files are written (``_main.EXIT_AT_ONCE``:
#: the interpreter's teardown of numba's compiler and the libraries loaded is skipped)
EXIT_AT_ONCE = ("simulate", "toolpath")
