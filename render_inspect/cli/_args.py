"""Shared pieces of the command line: argparse ``choices`` read from a registry, the
options several commands take (the scene, ``--out``, ``-q`` / ``-v``), and the scene a
scene command runs on."""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path
from typing import TYPE_CHECKING

from ..core.lazy import collector_paused

if TYPE_CHECKING:
    from ..scene import Scene

log = logging.getLogger("render_inspect")


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
    from ..pipeline import render_kinds

    return render_kinds()


def _objective_names() -> list:
    # the registered objective presets, which render.interferometer.objective takes (the
    # scene is imported lazily, as above)
    from ..scene import objective_names

    return objective_names()


def _program_formats() -> list:
    # the formats the io registry writes machine programs in (imported lazily, as above)
    from ..pipeline import program_formats

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
    _add_set_arg(p)
    _add_program_arg(p)
    _add_verbosity(p)


def _add_set_arg(p: argparse.ArgumentParser, *,
                 help: str = "override a scene key, e.g. --set process.spindle_rpm=100 (TOML value "
                             "syntax)"):
    """``--set KEY=VALUE`` (repeatable, into ``args.overrides``); ``help`` says what the
    command's keys are."""
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=help)


def _add_cluster_args(p: argparse.ArgumentParser, *, workers: str, scheduler: str,
                      exclusive: bool = True, scheduler_first: bool = False):
    """``--workers N`` (a local Dask cluster) and ``--scheduler ADDRESS`` (a running one),
    each with the command's ``help``; ``exclusive``: at most one of them."""
    g = p.add_mutually_exclusive_group() if exclusive else p
    for flag in (("--scheduler", "--workers") if scheduler_first else ("--workers", "--scheduler")):
        if flag == "--workers":
            g.add_argument(flag, type=int, default=None, metavar="N", help=workers)
        else:
            g.add_argument(flag, default=None, metavar="ADDRESS", help=scheduler)


def _add_program_arg(p: argparse.ArgumentParser):
    p.add_argument("--program", default=None, metavar="FILE",
                   help="a machine program (NC / G-code / C X Z point list) simulated in place "
                        "of the planned path (= --set process.program=FILE; docs/programs.md)")


def scene_overrides(args: argparse.Namespace) -> list:
    """The ``--set`` overrides with ``--program FILE`` as ``process.program`` (an absolute
    path) last."""
    out = list(getattr(args, "overrides", None) or [])
    prog = getattr(args, "program", None)
    if prog:
        out.append(f"process.program={json.dumps(str(Path(prog).resolve()))}")
    return out


def _add_out_args(p: argparse.ArgumentParser):
    p.add_argument("--out", required=True,
                   help="output folder: written whole when the run succeeds, untouched otherwise")
    p.add_argument("--overwrite", action="store_true",
                   help="replace --out even if it holds files render-inspect did not write")


def refuse_scene_in_out(args: argparse.Namespace) -> None:
    """Refuse an output folder that holds the scene file (it would be deleted with the
    folder; the files the scene reads are checked when the folder is opened)."""
    if getattr(args, "out", None):
        # (imported once the scene is read: a mistake in it is answered first)
        from .. import pipeline
        # (the schema, imported on first use as in scene_of)
        from ..scene import find_scene

        pipeline.refuse_inputs_inside(args.out, [find_scene(args.scene)])


def scene_of(args: argparse.Namespace) -> Scene:
    """The scene a scene command runs on (``args.scene`` with the ``--set`` overrides)."""
    # (the collector is paused meanwhile: the schema's modules and classes live as long as
    # the process)
    with collector_paused():
        # (the scene schema imports pydantic and the registries: imported here, not at the
        # top of the module, so that `render-inspect --help` answers at once)
        from ..scene import load_scene, unit_warnings

        scene = load_scene(args.scene, scene_overrides(args))
        refuse_scene_in_out(args)
    # values that are probably unit mistakes (a feed per revolution typed per minute, a
    # pixel that aliases the feed marks): said before the run, which goes on
    for text in unit_warnings(scene, sampling=args.command in ("simulate", "compare", "render")):
        log.warning("warning: %s", text)
    say_tool_edge(scene)
    return scene


def say_tool_edge(scene: Scene) -> None:
    """A measured cutting edge the cut cannot take refused, and what the nose arc takes
    from beyond it said, before the run."""
    tool = getattr(scene, "tool", None)
    if tool is not None and (getattr(tool, "edge_profile", None) or getattr(tool, "waviness", None)):
        # (imported here: the pipeline's tool-path stage and its kernels load only for a
        # scene with an edge)
        from ..pipeline import edge_warnings

        for text in edge_warnings(scene):
            log.warning("warning: %s", text)
