"""``render-inspect`` command line: argparse -> :mod:`render_inspect.pipeline`.

Exit codes: 0 done, 1 an error in the input or the run (one line on stderr naming the
parameter, the allowed range and the value received; anything unexpected is reported
the same way, with a hint how to see the traceback), 2 a usage error (argparse),
130 interrupted (Ctrl-C), 143 terminated (SIGTERM).  After an error or an interruption
the output folder is as it was before the run.  Long steps run in blocks and stop
within about a block (a fraction of a second to a second or two) of the signal
(:mod:`render_inspect.core.cancel`).

Output: progress bars with an ETA on stderr for every step that runs longer than a
second (rich; plain log lines when stderr is not a terminal), messages through the
``render_inspect`` logger (``-v``: more, ``-q``: warnings and errors only), and for
``compare`` and ``demo`` a one-screen summary on stdout with the headline numbers and
the path of ``report.html``.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import signal
import sys
import threading
import time
import traceback
from pathlib import Path

from . import __version__
from .core import cancel
from .core.cancel import Terminated
from .core.errors import RenderInspectError
from .core.progress import set_reporter

log = logging.getLogger("render_inspect")

#: steps shorter than this are not shown
SHOW_AFTER_S = 1.0


class _Registered:
    """argparse ``choices`` read from a registry the first time they are needed (checking
    a value, or ``render-inspect render --help``), so that building the parser imports
    nothing heavy."""

    def __init__(self, load):
        self._load = load
        self._values = None

    def _get(self) -> tuple:
        if self._values is None:
            self._values = tuple(self._load())
        return self._values

    def __contains__(self, value) -> bool:
        return value in self._get()

    def __iter__(self):
        return iter(self._get())

    def __len__(self) -> int:
        return len(self._get())


def _render_kinds() -> tuple:
    # the registered instruments (the pipeline and its registries are imported lazily:
    # `render-inspect --help` must answer at once)
    from .pipeline import render_kinds

    return render_kinds()


def _program_formats() -> list:
    # the formats the io registry writes machine programs in (imported lazily, as above)
    from .pipeline import program_formats

    return program_formats()


def _add_verbosity(p: argparse.ArgumentParser, *, top: bool = False):
    default = 0 if top else argparse.SUPPRESS
    g = p.add_mutually_exclusive_group()
    g.add_argument("-q", "--quiet", dest="quiet", action="store_true",
                   default=False if top else argparse.SUPPRESS,
                   help="only warnings and errors; no progress bars or summary")
    g.add_argument("-v", "--verbose", dest="verbose", action="count", default=default,
                   help="more messages (every step and its duration)")


def _add_scene_args(p: argparse.ArgumentParser, *, out=True):
    p.add_argument("scene", help="scene file (TOML) or the name of a shipped scene, "
                                 "e.g. sts_sinusoidal_grid")
    if out:
        _add_out_args(p)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key, e.g. --set process.spindle_rpm=100 (TOML value syntax)")
    _add_verbosity(p)


def _add_out_args(p: argparse.ArgumentParser):
    p.add_argument("--out", required=True,
                   help="output folder: written whole when the run succeeds, untouched otherwise")
    p.add_argument("--overwrite", action="store_true",
                   help="replace --out even if it holds files render-inspect did not write")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="render-inspect",
        description="Simulate, render and inspect diamond-machined freeform optics before they are cut.")
    ap.add_argument("--version", action="version", version=f"render-inspect {__version__}")
    _add_verbosity(ap, top=True)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = sub.add_parser("simulate", help="tool path + machined surface: heightmap.exr, metrics.json, preview")
    _add_scene_args(p)
    p.add_argument("--tiled", action="store_true",
                   help="compute the map tile by tile into heightmap.zarr (automatic when it does not fit "
                        "the memory budget: simulation.max_memory_gb, by default 80%% of the free memory)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="run the tiles on a local Dask cluster of N worker processes (implies --tiled)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the tiles on the Dask cluster at ADDRESS, e.g. tcp://host:8786 (implies --tiled)")
    p.add_argument("--tile", type=int, default=1024, metavar="PIXELS",
                   help="tile side in pixels, a multiple of 64 in [64, 16384] (default 1024)")

    p = sub.add_parser("toolpath", help="the machine program only: toolpath.npz (or csv / nc / "
                                        "any registered format)")
    _add_scene_args(p)
    p.add_argument("--format", choices=_Registered(_program_formats), default="npz",
                   metavar="FORMAT", help="a registered program format: %(choices)s (default npz)")

    p = sub.add_parser("render", help="virtual interferometer and diffuse-light images (Mitsuba 3)")
    _add_scene_args(p)
    p.add_argument("--surface", choices=["design", "machined"], default="machined")
    p.add_argument("--kind", choices=_Registered(_render_kinds), default="all", metavar="KIND",
                   help="a registered instrument, diffuse or all: %(choices)s (default all)")

    p = sub.add_parser("compare", help="two variants of the scene (the process's own pair, e.g. "
                                       "compensated vs uncompensated, or --vary): images, metrics, "
                                       "report.html")
    _add_scene_args(p)
    p.add_argument("--measured", default=None, help="measured height map (X3P, EXR, ...) to compare")
    p.add_argument("--vary", default=None, metavar="KEY=A,B",
                   help="compare KEY = A against KEY = B instead of the process's own pair, e.g. "
                        "--vary process.compensation=normal,z (TOML values)")
    p.add_argument("--force", action="store_true",
                   help="compare the measured map even when it does not match the design "
                        "(overlap or residual checks fail)")

    p = sub.add_parser("analyze", help="ISO 25178-2 parameters of one height map file (measured "
                                       "or simulated): metrics.json, height.png, --x3p")
    p.add_argument("file", help="height map: X3P, SUR, PLU, DAT (MetroPro), DATX, OPD, TMD, NMS, "
                                "heightmap.exr, ...")
    _add_out_args(p)
    p.add_argument("--form", choices=["none", "plane", "poly2", "sphere"], default="plane",
                   help="form removed first (none: the mean only)")
    p.add_argument("--filter", default=None, metavar="S,L",
                   help="ISO 16610-61 Gaussian nesting indices in mm, e.g. 0.0025,0.8 or ,0.8")
    p.add_argument("--outliers", choices=["none", "sigma"], default="none",
                   help="sigma: leave out the 3-sigma second-difference outliers (counted either way)")
    p.add_argument("--slope", choices=["forward", "central"], default="forward",
                   help="derivative estimator of Sdq/Sdr (forward: as SurfaceTopography and surfalize)")
    p.add_argument("--x3p", action="store_true", help="also write the evaluated surface as height.x3p")
    _add_verbosity(p)

    p = sub.add_parser("measure", help="height from interferometer frames alone: height.exr, metrics.json")
    p.add_argument("frames", help="interferogram.exr (frames + settings), or a TIFF / PNG stack "
                                  "or a folder of frames with a settings JSON")
    _add_out_args(p)
    p.add_argument("--algorithm", default="auto",
                   choices=["auto", "4step", "5step", "hariharan", "lsq", "envelope",
                            "envelope+phase"],
                   help="PSI: 4step, 5step (= hariharan), lsq; CSI: envelope, envelope+phase; "
                        "auto: by mode and frame count")
    p.add_argument("--settings", default=None,
                   help="settings JSON of a TIFF / PNG stack (default: beside it)")
    p.add_argument("--min-modulation", type=float, default=0.05, dest="min_modulation",
                   help="pixels with lower fringe contrast are not measured (default 0.05)")
    _add_verbosity(p)

    p = sub.add_parser("characterise", help="the virtual instrument's transfer function, step "
                                            "response, slope limit and noise (ISO 25178-600 style)")
    p.add_argument("--objective", default="20x", help="objective preset (2.5x, 5x, 10x, 20x, 50x, 100x)")
    _add_out_args(p)
    p.add_argument("--mode", choices=["psi", "csi"], default="psi")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override an instrument key of [render.interferometer], e.g. "
                        "--set numerical_aperture=0.5 (TOML value syntax)")
    p.add_argument("--seed", type=int, default=0, help="seed of the camera noise")
    p.add_argument("--quick", action="store_true", help="fewer points, smaller fields (for tests)")
    _add_verbosity(p)

    _add_fit_parser(sub)

    p = sub.add_parser("sweep", help="parameter sweep on Dask: results.jsonl, results.csv, summary, plots "
                                     "(resumable)")
    p.add_argument("sweep", help="sweep file (TOML) or the name of a shipped sweep, e.g. fig15_small")
    p.add_argument("--out", required=True, help="the sweep's folder; finished points there are not run again")
    p.add_argument("--overwrite", action="store_true",
                   help="write the sweep into a non-empty folder that is not a sweep's (its files "
                        "are left in place)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--scheduler", metavar="ADDRESS", default=None,
                       help="address of a running Dask scheduler, e.g. tcp://10.0.0.5:8786 "
                            "(default: a LocalCluster on this machine)")
    where.add_argument("--workers", metavar="N", type=int, default=None,
                       help="process workers of the LocalCluster (default: the CPU count)")
    p.add_argument("--retry-failed", action="store_true", help="run the points recorded as failed again")
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
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a key in every case (what-if checks; not with --update)")
    _add_verbosity(p)

    p = sub.add_parser("demo", help="set-up check plus the main job on the shipped sinusoidal grid "
                                        "(Li et al. 2018)")
    _add_out_args(p)
    p.add_argument("--quick", action="store_true", help="smaller images (for tests)")
    _add_verbosity(p)
    return ap


def _add_fit_parser(sub) -> None:
    """``fit``: the scene's tool, feed, machine and material keys fitted to a measured
    surface (its own block: the pipeline's ``run_fit`` does the work)."""
    p = sub.add_parser("fit", help="fit free scene keys (tool, feed, machine, material) to a "
                                   "measured surface through the virtual instrument; predict "
                                   "the next cut: fit.json, fit.html")
    p.add_argument("measured", help="measured height map: anything analyze reads (instrument "
                                    "file, X3P, the height.exr that measure writes)")
    p.add_argument("--scene", required=True, help="scene file (TOML) or shipped scene name "
                                                  "describing the cut")
    p.add_argument("--free", required=True, action="append", metavar="KEY[,KEY...]",
                   help="numeric scene keys to fit, e.g. tool.nose_radius,process.feed_mm_per_min"
                        " (array entries by index: machine.errors.axial_sync.0.1)")
    _add_out_args(p)
    p.add_argument("--bounds", action="extend", nargs="+", default=[], metavar="KEY=A,B",
                   help="bounds of a free key (default: the schema's range; must lie inside it)")
    p.add_argument("--objective", default=None,
                   help="virtual instrument objective when the file names none (default: the "
                        "scene's render.interferometer.objective)")
    p.add_argument("--at", default=None, metavar="X,Y|register",
                   help="where the measured field lies: its centre at X,Y mm, or 'register' "
                        "(found on the design); default: the file's origin")
    p.add_argument("--window", type=float, default=0.2, metavar="MM",
                   help="side of the fitted square, mm (default 0.2: each evaluation simulates "
                        "and images this much)")
    p.add_argument("--form", choices=["none", "plane", "poly2", "sphere"], default="plane",
                   help="form removed from measured and predicted maps before comparing")
    p.add_argument("--weights", action="append", default=[], metavar="TERM=W",
                   help="misfit term weights: map, psd, harmonics (default 1 each)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int, default=None, metavar="N",
                       help="run the evaluations on a local Dask cluster of N processes")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run the evaluations on the Dask cluster at ADDRESS")
    p.add_argument("--predict", action="extend", nargs="+", default=[], metavar="KEY=VALUE",
                   help="after the fit, simulate the fitted scene with KEY=VALUE (TOML value) "
                        "into DIR/predict, e.g. --predict process.feed_mm_per_min=0.4")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key before fitting (TOML value syntax)")
    p.add_argument("--seed", type=int, default=0, help="seed of the virtual camera's noise and "
                                                       "of the global search")
    p.add_argument("--global", dest="global_points", type=int, default=8, metavar="N",
                   help="points of a seeded Sobol design over the search box (the bounds "
                        "narrowed to half and twice the start) before the local fit "
                        "(default 8; 0: the scene's and the measurement's starts only)")
    p.add_argument("--max-evaluations", dest="max_evaluations", type=int, default=150,
                   metavar="N", help="largest number of evaluations (default 150)")
    p.add_argument("--profile-points", dest="profile_points", type=int, default=3, metavar="N",
                   help="points either side of the solution along each parameter (misfit.png)")
    p.add_argument("--cache", default=None, metavar="DIR",
                   help="cached evaluations (default: OUT.cache beside --out); a fit run again "
                        "resumes from them")
    _add_verbosity(p)


def _run(args):
    # the pipeline imports numba, scipy and pydantic: imported here, not at the top of the
    # module, so that `render-inspect --help` answers at once
    from . import pipeline

    # (the scene schema imports pydantic and the registries: same reason)
    from .scene import instrument_config, load_scene, unit_warnings

    ow = bool(getattr(args, "overwrite", False))
    if args.command == "demo":
        return pipeline.run_demo(args.out, quick=args.quick, overwrite=ow)
    if args.command == "analyze":
        return pipeline.run_analyze(args.file, args.out, form=args.form, filter_spec=args.filter,
                                    outliers=args.outliers, slope=args.slope, x3p=args.x3p,
                                    overwrite=ow)
    if args.command == "measure":
        return pipeline.run_measure(args.frames, args.out, algorithm=args.algorithm,
                                    settings=args.settings, min_modulation=args.min_modulation,
                                    overwrite=ow)
    if args.command == "characterise":
        return pipeline.run_characterise(
            instrument_config(args.objective, args.mode, args.overrides), args.out,
            quick=args.quick, seed=args.seed, overwrite=ow)
    if args.command == "sweep":
        info = pipeline.run_sweep(pipeline.find_sweep(args.sweep), args.out,
                                  scheduler=args.scheduler, workers=args.workers,
                                  retry_failed=args.retry_failed, overwrite=ow)
        failure = pipeline.sweep_failure(info, args.out)
        if failure:
            raise RenderInspectError(failure)
        return info
    if args.command == "regress":
        return pipeline.run_regress(update=args.update, only=args.only, out=args.out,
                                    overrides=args.overrides, overwrite=ow)
    if args.command == "fit":
        return pipeline.run_fit(
            args.measured, load_scene(args.scene, args.overrides), args.free, args.out,
            bounds=args.bounds, objective=args.objective, at=args.at, window_mm=args.window,
            form=args.form, weights=args.weights, workers=args.workers,
            scheduler=args.scheduler, predict=args.predict, seed=args.seed,
            global_points=args.global_points, max_evaluations=args.max_evaluations,
            profile_points=args.profile_points, cache=args.cache, overwrite=ow)
    scene = load_scene(args.scene, args.overrides)
    # values that are probably unit mistakes (a feed per revolution typed per minute, a
    # pixel that aliases the feed marks): said before the run, which goes on
    for text in unit_warnings(scene, sampling=args.command in ("simulate", "compare", "render")):
        log.warning("warning: %s", text)
    if args.command == "simulate":
        return pipeline.run_simulate(scene, args.out, tiled=True if args.tiled else None,
                                     workers=args.workers, scheduler=args.scheduler,
                                     tile=args.tile, overwrite=ow)
    if args.command == "toolpath":
        return pipeline.run_toolpath(scene, args.out, fmt=args.format, overwrite=ow)
    if args.command == "render":
        return pipeline.run_render(scene, args.out, surface=args.surface, kind=args.kind,
                                   overwrite=ow)
    if args.command == "compare":
        return pipeline.run_compare(scene, args.out, measured=args.measured, vary=args.vary,
                                    force=args.force, overwrite=ow)
    return None


# ---------------------------------------------------------------------------- progress
class RichReporter:
    """Progress bars (rich) on stderr: one row per running step, shown once the step has
    run for :data:`SHOW_AFTER_S`, with its bar, elapsed time and ETA."""

    def __init__(self, console):
        from rich.progress import (
            BarColumn,
            Progress,
            SpinnerColumn,
            TaskProgressColumn,
            TextColumn,
            TimeElapsedColumn,
            TimeRemainingColumn,
        )

        self._progress = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(),
                                  TaskProgressColumn(), TimeElapsedColumn(), TextColumn("ETA"),
                                  TimeRemainingColumn(), console=console, transient=True)
        self._lock = threading.Lock()
        self._tasks = {}  # id -> dict(start, total, timed, shown)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._tick, daemon=True)

    def __enter__(self):
        self._progress.start()
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(timeout=1.0)
        self._progress.stop()
        return False

    def start(self, description, total, timed=False):
        with self._lock:
            tid = self._progress.add_task(description, total=total, visible=False)
            self._tasks[tid] = {"start": time.monotonic(), "total": total, "timed": timed}
        return tid

    def advance(self, handle, amount):
        with self._lock:
            if handle in self._tasks and not self._tasks[handle]["timed"]:
                self._progress.advance(handle, amount)

    def update(self, handle, description):
        with self._lock:
            if handle in self._tasks:
                self._progress.update(handle, description=description)

    def progress(self, handle, completed):
        """A step estimated by time reports its measured progress: shown from now on by
        it (the bar and the ETA start again from this point)."""
        with self._lock:
            info = self._tasks.get(handle)
            if info is not None and info["timed"]:
                info["timed"] = False
                self._progress.reset(handle, total=info["total"], completed=completed,
                                     visible=time.monotonic() - info["start"] >= SHOW_AFTER_S)
            elif info is not None:
                self._progress.update(handle, completed=completed)

    def finish(self, handle):
        with self._lock:
            info = self._tasks.pop(handle, None)
            if info is not None:
                self._progress.remove_task(handle)

    def _tick(self):
        while not self._stop.wait(0.2):
            now = time.monotonic()
            with self._lock:
                for tid, info in self._tasks.items():
                    el = now - info["start"]
                    if el >= SHOW_AFTER_S:
                        upd = {"visible": True}
                        if info["timed"] and info["total"]:
                            upd["completed"] = timed_fill(el, info["total"])
                        self._progress.update(tid, **upd)


def timed_fill(elapsed: float, expected: float) -> float:
    """How far to fill the bar of a step known only by its expected duration: the elapsed
    time up to 80 % of the expectation, then ever more slowly towards (never reaching) the
    end, so that a step that takes longer than expected keeps moving instead of sitting
    at 99 %.  A step that reports its real progress leaves this estimate."""
    x = elapsed / expected
    frac = x if x < 0.8 else 1.0 - 0.2 * math.exp(-(x - 0.8) / 0.2)
    return frac * expected


class LogReporter:
    """Without a terminal: one log line per step that took longer than
    :data:`SHOW_AFTER_S` (its duration)."""

    def __init__(self):
        self._t = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False

    def start(self, description, total, timed=False):
        h = object()
        self._t[h] = (description, time.monotonic())
        return h

    def advance(self, handle, amount):
        pass

    def update(self, handle, description):
        # a step of a multi-step task ended: log it, time the next one
        if handle in self._t:
            self._log(*self._t[handle])
            self._t[handle] = (description, time.monotonic())

    def finish(self, handle):
        if handle in self._t:
            self._log(*self._t.pop(handle))

    @staticmethod
    def _log(desc, t0):
        dt = time.monotonic() - t0
        if dt >= SHOW_AFTER_S:
            log.info("%s: %.1f s", desc, dt)


class _NullContext:
    def __enter__(self):
        return None

    def __exit__(self, *exc):
        return False


def _reporter(args):
    if getattr(args, "quiet", False):
        return _NullContext()
    if sys.stderr.isatty():
        from rich.console import Console

        return RichReporter(Console(file=sys.stderr))
    return LogReporter()


class _RichLogHandler(logging.Handler):
    """Log records printed through the progress display's console (above the bars,
    which would otherwise be torn by direct writes to stderr)."""

    def __init__(self, console):
        super().__init__()
        self.console = console

    def emit(self, record):
        try:
            self.console.print(self.format(record), markup=False, highlight=False,
                               soft_wrap=True)
        except Exception:  # logging must never raise into the run
            self.handleError(record)


# ----------------------------------------------------------------------------- summary
def _print_compare_summary(metrics: dict, out: str, seconds: float) -> None:
    from rich.console import Console
    from rich.table import Table

    # the pipeline is imported lazily (see _run)
    from .pipeline import compare_summary

    con = Console(file=sys.stdout, highlight=False)
    rows, diff = compare_summary(metrics)
    va, vb = (v["name"] for v in metrics["variants"])
    scene = metrics.get("scene", {}).get("name", "")
    t = Table(title=f"render-inspect compare: {scene} ({seconds:.0f} s)", title_justify="left",
              show_edge=False)
    t.add_column("")
    t.add_column(va, justify="right")
    t.add_column(vb, justify="right")
    for r in rows:
        t.add_row(*r)
    con.print(t)
    # lines are not wrapped: a path must stay one piece to be copied
    if metrics.get("pair", {}).get("identical"):
        con.print(f"The two variants are identical ({metrics['pair']['key']} has no effect here).",
                  soft_wrap=True)
    else:
        for k, v in diff:
            con.print(f"{k}: {v}", soft_wrap=True)
    con.print(f"report: {metrics.get('report') or (out.rstrip('/') + '/report.html')}",
              soft_wrap=True, markup=False)


def _print_summary(command: str, metrics: dict, out: str, seconds: float) -> None:
    """``measure`` and ``analyze``: their headline numbers and where the files are."""
    from rich.console import Console
    from rich.table import Table

    # the pipeline is imported lazily (see _run)
    from .pipeline import analyze_summary, measure_summary

    rows = measure_summary(metrics) if command == "measure" else analyze_summary(metrics)
    src = metrics.get("source") if command == "measure" else metrics.get("input", {}).get("path")
    con = Console(file=sys.stdout, highlight=False)
    t = Table(title=f"render-inspect {command}: {Path(str(src)).name} ({seconds:.0f} s)",
              title_justify="left",
              show_edge=False, show_header=False)
    t.add_column("")
    t.add_column("")
    for r in rows:
        t.add_row(*r)
    con.print(t)
    con.print(f"output: {str(Path(out).resolve())}", soft_wrap=True, markup=False)


def _on_interrupt(signum, frame):
    # Ctrl-C: the main thread stops here, and every long computation running in blocks
    # (kernels, tiles, worker threads) at its next check (core.cancel); inside native code
    # that cannot unwind an exception (importing Mitsuba, loading a scene), at the end of
    # that block (cancel.deferred)
    cancel.request(signum)
    if not cancel.deferring():
        raise KeyboardInterrupt


def _on_terminate(signum, frame):
    cancel.request(signum)
    if not cancel.deferring():
        raise Terminated(signum)


def _interrupt_in(err: BaseException) -> KeyboardInterrupt | None:
    """The interruption behind ``err``: Ctrl-C during a compiled (numba) kernel surfaces
    as a SystemError whose cause or context is the KeyboardInterrupt."""
    seen = set()
    e = err
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


def _traceback_hint(parser) -> str:
    opts = getattr(parser, "_option_string_actions", {})
    if "-v" in opts or "--verbose" in opts:
        return "run with -v for the traceback"
    return "set RENDER_INSPECT_TRACEBACK=1 for the traceback"


def _one_line(text: str) -> str:
    return " ".join(str(text).split()) if "\n" not in str(text) else str(text).rstrip()


def _setup_logging(args) -> None:
    level = logging.INFO
    if getattr(args, "quiet", False):
        level = logging.WARNING
    elif getattr(args, "verbose", 0):
        level = logging.DEBUG
    if not any(isinstance(h, _StderrHandler) for h in log.handlers):
        handler = _StderrHandler()
        handler.setFormatter(logging.Formatter("%(message)s"))
        log.addHandler(handler)
    log.setLevel(level)


class _StderrHandler(logging.StreamHandler):
    """Log records on the *current* ``sys.stderr``: a handler holding the stream it was
    made with writes into a closed file once ``sys.stderr`` has been replaced (a second
    ``main()`` in one process under a captured or redirected stderr), which logging
    reports as "--- Logging error ---" instead of the message."""

    def __init__(self):
        super().__init__(sys.stderr)

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):  # StreamHandler.__init__ / setStream set it: always stderr
        pass


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _setup_logging(args)
    show_tb = bool(getattr(args, "verbose", 0)) or os.environ.get("RENDER_INSPECT_TRACEBACK", "") \
        not in ("", "0")
    old_signals = {}
    cancel.clear()
    for sig, handler in ((signal.SIGINT, _on_interrupt), (signal.SIGTERM, _on_terminate),
                         (signal.SIGHUP, _on_terminate)):
        try:
            old_signals[sig] = signal.signal(sig, handler)
        except (ValueError, OSError):  # not the main thread: leave the handlers alone
            pass
    prefix = f"render-inspect {args.command}"
    t0 = time.perf_counter()
    reporter = _reporter(args)
    handlers = list(log.handlers)
    if isinstance(reporter, RichReporter):
        rich_handler = _RichLogHandler(reporter._progress.console)
        rich_handler.setFormatter(logging.Formatter("%(message)s"))
        log.handlers = [rich_handler]
    t_start = time.monotonic()
    try:
        with reporter as rep:
            old = set_reporter(rep)
            try:
                result = _run(args)
                # a signal whose exception was swallowed (raised inside a __del__ or a
                # callback that ignores exceptions) still ends the run as an interruption
                cancel.check()
            except BaseException as err:
                if isinstance(err, (SystemExit, GeneratorExit)):
                    raise
                stop = _interrupt_in(err)
                if stop is None:
                    raise
                raise stop from None
            finally:
                set_reporter(old)
                log.handlers = handlers
    except RenderInspectError as err:
        if show_tb:
            traceback.print_exc()
        print(f"{prefix}: error: {_one_line(err)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as stop:
        what = "terminated" if isinstance(stop, Terminated) else "interrupted"
        # the folder an interruption arriving after the swap leaves complete (the
        # exception's attribute, or a folder swapped in since this run started; nothing
        # was written when the pipeline was never imported)
        done = getattr(stop, "render_inspect_output_complete", None)
        if done is None and f"{__package__}.pipeline" in sys.modules:
            # (the pipeline is imported lazily, see _run; here only when it was)
            from .pipeline import completed_outputs

            done = next(iter(completed_outputs(since=t_start)), None)
        if args.command == "sweep":
            state = (f"the finished points are kept in {args.out}/results.jsonl: run the same "
                     f"command again to go on")
        elif done:
            state = f"the output folder {done} had been written completely"
        else:
            state = "the output folder was left as it was"
        kept = getattr(stop, "render_inspect_kept", None)  # (fit: its evaluations)
        if kept:
            state += f"; {kept}"
        print(f"{prefix}: {what}; {state}", file=sys.stderr)
        return 143 if isinstance(stop, Terminated) else 130
    except MemoryError:
        if show_tb:
            traceback.print_exc()
        print(f"{prefix}: error: ran out of memory; set simulation.max_memory_gb lower than "
              f"the machine's free memory so that render-inspect refuses such runs at the start, "
              f"or reduce the sizes (simulation.region / simulation.pixel, image resolution)",
              file=sys.stderr)
        return 1
    except OSError as err:
        if show_tb:
            traceback.print_exc()
        where = f": {err.filename}" if getattr(err, "filename", None) else ""
        print(f"{prefix}: error: {err.strerror or err}{where} ({_traceback_hint(parser)})",
              file=sys.stderr)
        return 1
    except Exception as err:  # a bug: one line, the traceback on request
        if show_tb:
            traceback.print_exc()
        print(f"{prefix}: internal error: {type(err).__name__}: {_one_line(err)[:300]} "
              f"({_traceback_hint(parser)})", file=sys.stderr)
        return 1
    finally:
        for sig, handler in old_signals.items():
            signal.signal(sig, handler)
        cancel.clear()
    dt = time.perf_counter() - t0
    if args.command in ("compare", "demo") and isinstance(result, dict) and "variants" in result \
            and not getattr(args, "quiet", False):
        _print_compare_summary(result, args.out, dt)
    elif args.command in ("measure", "analyze") and isinstance(result, dict) \
            and not getattr(args, "quiet", False):
        _print_summary(args.command, result, args.out, dt)
    log.info("%s: done in %.1f s", prefix, dt)
    return 0


if __name__ == "__main__":
    sys.exit(main())
