"""The work behind the operators: each task is one call of :mod:`render_inspect.pipeline`
on JSON-able parameters, returning its JSON-able result.

Tasks run in a worker process while Blender's UI stays responsive (``_jobs.Job``), or in
Blender's own process in background mode and from scripts.  They write files only (each
output folder atomically: a cancelled or failed run leaves nothing behind); the operators
turn the results into Blender data on the main thread.

This module is imported both as part of the add-on and, in the worker, as a top-level
module: render_inspect only inside the tasks, through :func:`_pipeline`.
"""

from __future__ import annotations

import importlib


def _pipeline():
    """``render_inspect.pipeline``: the add-on's (``_lib``: the copy inside the extension)
    when this module is part of the add-on, else (the worker) the one on ``sys.path``."""
    if __package__:
        from . import _lib

        return _lib.module("pipeline")
    return importlib.import_module("render_inspect.pipeline")


def _nothing(fraction: float, message: str) -> None:
    """Default progress callback."""


def simulate(p: dict, progress=_nothing) -> dict:
    pipeline = _pipeline()

    return pipeline.simulate_variants(p["scene_path"], overrides=p.get("overrides", ()),
                                      out=p["out"], surface=p.get("surface", "machined"),
                                      exaggeration=p.get("exaggeration"), progress=progress)


def render(p: dict, progress=_nothing) -> dict:
    pipeline = _pipeline()

    return pipeline.render_variant(p["heightmap"], variant=p["variant"], surface=p["surface"],
                                   exaggeration=p["exaggeration"], view=p["view"],
                                   resolution=p["resolution"], samples=p["samples"],
                                   seed=p["seed"], out=p["out"],
                                   interferogram=p.get("interferogram", True), progress=progress)


def compare(p: dict, progress=_nothing) -> dict:
    pipeline = _pipeline()

    return pipeline.compare_scene(p["scene_path"], overrides=p.get("overrides", ()),
                                  out=p["out"], measured=p.get("measured"),
                                  units=p.get("units"), line=p.get("line"), progress=progress)


def export(p: dict, progress=_nothing) -> dict:
    pipeline = _pipeline()

    return pipeline.export_variant(p["heightmap"], variant=p["variant"], surface=p["surface"],
                                   exaggeration=p["exaggeration"], formats=p["formats"],
                                   out=p["out"], progress=progress)


TASKS = {"simulate": simulate, "render": render, "compare": compare, "export": export}


def run(task: str, params: dict, progress=_nothing) -> dict:
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; one of {sorted(TASKS)}")
    return TASKS[task](params, progress)
