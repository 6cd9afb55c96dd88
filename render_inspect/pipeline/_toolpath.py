"""``toolpath``: the machine program of a scene (npz, csv or nc) and its facts."""

from __future__ import annotations

import logging
from pathlib import Path

from .. import __version__
from ..core.errors import InputError
from ..core.toolpath import LinearProgram
from ..design import make_surface
from ..io import atomic_output_dir, export_program, write_json
from ..processes import process_of

__all__ = ["plan_program", "run_toolpath"]

log = logging.getLogger("render_inspect")


def plan_program(scene, *, surface=None):
    """The :class:`~render_inspect.processes.Plan` of the scene's whole program (or of
    the region its process plans for the ``toolpath`` command)."""
    kind = process_of(scene)
    surface = surface if surface is not None else make_surface(scene.design)
    region = kind.program_region(scene)
    kind.precheck(scene, region)
    return kind.plan(scene, surface, region=region)


def run_toolpath(scene, out, *, fmt: str = "npz", overwrite: bool = False):
    """``render-inspect toolpath``: the program as ``toolpath.npz`` / ``.csv`` / ``.nc`` and
    ``toolpath.json`` (its facts: points, revolutions or lines, kinematics,
    accessibility).  Returns the program.  ``out`` is checked and locked first and
    replaced as a whole when complete (``overwrite``: see
    :func:`~render_inspect.io.atomic_output_dir`)."""
    if fmt not in ("npz", "csv", "nc"):
        raise InputError(f"--format must be one of ['csv', 'nc', 'npz'], received {fmt!r}")
    kind = process_of(scene)
    with atomic_output_dir(out, overwrite=overwrite, command="toolpath", scene=scene) as tmp:
        plan = plan_program(scene)
        prog = plan.program
        header = kind.program_header(scene)
        tmp = Path(tmp)
        export_program(prog, tmp, fmt=fmt, header=header)
        facts = dict(plan.facts)
        tp = facts.setdefault("toolpath", {})
        meta = {k: v for k, v in getattr(prog, "meta", {}).items() if k != "accessibility"}
        if isinstance(prog, LinearProgram):
            tp.setdefault("points", prog.points)
            tp.setdefault("lines", prog.lines)
            tp.setdefault("kind", "sculpt")
            tp.setdefault("cut_time_s", prog.duration_s)
        else:
            tp.setdefault("points", prog.points)
            tp.setdefault("revolutions", prog.revolutions)
            tp.setdefault("feed_per_rev_mm", scene.process.feed_per_rev)
            for k, v in meta.items():
                tp.setdefault(k, v)
            if "accessibility" in prog.meta:
                facts["accessibility"] = prog.meta["accessibility"]
        info = {"software_version": __version__, "scene_name": scene.name, **facts}
        write_json(tmp / "toolpath.json", info)
    if isinstance(prog, LinearProgram):
        log.info("sculpturing program: %s points -> %s", f"{prog.points:,}", out)
    else:
        log.info("tool path: %s points, %.1f revolutions -> %s", f"{prog.points:,}",
                 prog.revolutions, out)
    return prog
