"""``toolpath``: the machine program of a scene (in any format the io registry writes for
it) and its facts."""

from __future__ import annotations

import logging
from pathlib import Path

from ..core.errors import InputError
from ..design import make_surface
from ..io import atomic_output_dir, export_program, program_formats
from ..processes import process_of
from ._metrics import toolpath_metrics, write_metrics

__all__ = ["plan_program", "run_toolpath", "program_formats"]

log = logging.getLogger("render_inspect")


def plan_program(scene, *, surface=None):
    """The :class:`~render_inspect.processes.Plan` of the scene's whole program (or of
    the region its process plans for the ``toolpath`` command)."""
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = surface if surface is not None else make_surface(scene.design)
    region = process.program_region(cfg)
    process.precheck(cfg, region)
    return process.plan(cfg, surface, region=region)


def run_toolpath(scene, out, *, fmt: str = "npz", overwrite: bool = False):
    """``render-inspect toolpath``: the program as ``toolpath.<fmt>`` (npz, csv, nc or any
    format a module of :mod:`render_inspect.io` registers) and ``toolpath.json`` (its
    facts: points, revolutions or lines, kinematics, accessibility).  Returns the
    program.  ``out`` is checked and locked first and replaced as a whole when complete
    (``overwrite``: see :func:`~render_inspect.io.atomic_output_dir`)."""
    formats = program_formats()
    if fmt not in formats:
        raise InputError(f"--format must be one of {formats}, received {fmt!r}")
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    with atomic_output_dir(out, overwrite=overwrite, command="toolpath", scene=scene) as tmp:
        plan = plan_program(scene)
        export_program(plan.program, Path(tmp), fmt=fmt, header=process.program_header(cfg))
        facts = process.program_facts(cfg, plan)
        write_metrics(tmp, toolpath_metrics(scene.name, facts), name="toolpath.json")
    log.info("%s program: %s points -> %s", process.traits(cfg).name,
             f"{facts['toolpath']['points']:,}", out)
    return plan.program
