"""``toolpath``: the machine program of a scene (in any format the io registry writes for
it) and its facts; every NC program written is read back and verified against the part,
the design and the machine before the folder is put in place."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import logging
import math
from pathlib import Path

from ..core.errors import InputError
from ..design import Surface, make_surface
from ..fit import scene_hash
from ..io import (file_record, atomic_output_dir, atomic_write_text, check_nc_style, cut_points,
                  export_program, program_axes, program_blocks, program_formats, read_nc_blocks)
from ..processes import Plan, Process, check_budget, findings_summary, process_of
from ..report import draw_figure
from ..toolpath import Tool, compare_with_plan, edge_notes, plan_memory, verify_blocks
from ._metrics import toolpath_metrics, write_metrics

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["plan_program", "run_toolpath", "program_formats", "verify_program_file",
           "check_links", "write_program_report", "log_program_summary", "nc_memory",
           "NC_BYTES_PER_POINT", "check_tool_edge", "edge_warnings"]

log = logging.getLogger("render_inspect")


def plan_program(scene: Scene, *, surface: Surface | None = None) -> Plan:
    """The :class:`~render_inspect.processes.Plan` of the scene's whole program (or of
    the region its process plans for the ``toolpath`` command)."""
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = surface if surface is not None else make_surface(scene.design)
    region = process.program_region(cfg)
    process.precheck(cfg, region)
    return process.plan(cfg, surface, region=region)


def verify_program_file(path: Path, process: Process, cfg: Any, surface: Surface, plan: Plan,
                        links: Any, *, part: Any = None) -> dict | None:
    """Read the NC program ``path`` back and check every block of it against the part,
    the design and the machine (:func:`~render_inspect.toolpath.verify_blocks`); returns
    the check's facts, None for a process that states no part to check against.  The
    cutting points must be the planned program's (``plan``) to the written places.  A
    failure is an :class:`InputError` naming the block number.  ``part``: the process's
    :meth:`~render_inspect.processes.Process.program_part`, when the caller has it."""
    if part is None:
        part = process.program_part(cfg, surface, plan)
    if part is None or links is None:
        log.warning("%s: the program is not verified (its process states no part to check "
                    "it against)", Path(path).name)
        return None
    blocks = read_nc_blocks(path)
    what = Path(path).name
    facts = verify_blocks(blocks, part, process.program_limits(cfg), links, what=what)
    facts["as_planned"] = compare_with_plan(blocks, cut_points(blocks, path),
                                            program_axes(plan.program), what=what)
    return facts


def links_and_part(process: Any, cfg: Any, surface: Surface, plan: Plan) -> tuple | None:
    """The links of the planned program and the part they are checked against
    (:meth:`~render_inspect.processes.Process.program_links_part`: the part made once),
    or None.  A process that states its links by overriding ``program_links`` alone has
    those, with its ``program_part``."""
    own = getattr(type(process), "program_links", None)
    if own is not None and own is not Process.program_links:
        links = process.program_links(cfg, surface, plan)
        return None if links is None else (links, process.program_part(cfg, surface, plan))
    return process.program_links_part(cfg, surface, plan)


def check_links(process: Any, cfg: Any, surface: Surface, plan: Plan) -> dict | None:
    """The moves between the cuts of the planned program (approach, links, exit: the
    blocks :func:`~render_inspect.io.program_blocks` gives) checked against the part and
    the machine: the rapids stay in the clearance plane, plunges and retracts are
    vertical, no link touches the part.  Returns the facts (``metrics.json``
    ``toolpath.links``), None for a process without a part to check against."""
    both = links_and_part(process, cfg, surface, plan)
    if both is None:
        return None
    links, part = both
    blocks = program_blocks(plan.program, links)
    return verify_blocks(blocks, part, process.program_limits(cfg), links,
                         what="the planned program", check_cuts=False)


#: Bytes per point of writing an NC program, reading it back and verifying it block by
#: block, beyond the planned path (:func:`~render_inspect.toolpath.plan_memory`):
#: measured as the peak resident set of ``toolpath --format nc`` of the turned
#: sinusoidal grid at 0.36 and 1.44 million points, 267 bytes per point in all
#: (tests/test_memory_estimate.py)
NC_BYTES_PER_POINT = 170


def nc_memory(scene: Scene, points: int) -> int:
    """Check the memory of writing, reading back and verifying an NC program of
    ``points`` points (with the planned path held) against the scene's budget; returns
    the bytes."""
    n = int(points)
    need = int(plan_memory(n) + n * NC_BYTES_PER_POINT)
    return check_budget(scene.simulation, need,
                        what=f"the NC program ({n:,} points written, read back and verified)",
                        drivers=[], hint="plan fewer points (process.points_per_rev, "
                                         "process.arc_length, process.workpiece_radius)")


def _program_source(scene: Scene, scene_file: str | Path | None = None) -> dict:
    """The NC header's record of where a program comes from: ``scene_file`` (its name),
    ``scene_file_sha256`` (of the file as read) and ``scene_sha256_as_run`` (the scene
    after its ``--set`` overrides: the SHA-256 of its canonical JSON, the value
    ``metrics.json`` ``inputs.scene.sha256_as_run`` records)."""
    head: dict[str, Any] = {}
    if scene_file is not None:
        rec = file_record(scene_file, "scene")
        head["scene_file"] = Path(scene_file).name
        head["scene_file_sha256"] = rec["sha256"] or rec.get("note", "not read")
    head["scene_sha256_as_run"] = scene_hash(scene.to_dict())
    return head


def _nc_style(fmt: str, comments: str | None, block_numbers: int | None) -> dict:
    """The writer's ``comments`` and ``block_numbers`` of an NC program, checked (one line
    naming the option); the options belong to ``--format nc`` alone."""
    if fmt != "nc":
        given = [n for n, v in (("--nc-comments", comments), ("--nc-block-numbers", block_numbers))
                 if v is not None]
        if given:
            raise InputError(f"{' and '.join(given)} set how an NC program is written: they need "
                             f"--format nc, received --format {fmt}")
        return {}
    style = {"comments": "semicolon" if comments is None else comments,
             "block_numbers": 1 if block_numbers is None else block_numbers}
    check_nc_style(style["comments"], style["block_numbers"])
    return style


def run_toolpath(scene: Scene, out: str | Path, *, fmt: str = "npz",
                 overwrite: bool = False, scene_file: str | Path | None = None,
                 nc_comments: str | None = None, nc_block_numbers: int | None = None) -> Any:
    """``render-inspect toolpath``: the program as ``toolpath.<fmt>`` (npz, csv, nc or any
    format a module of :mod:`render_inspect.io` registers) and ``toolpath.json`` (its
    facts: points, revolutions or lines, kinematics, accessibility; for an NC program
    ``program_check``, what its verification found).  Returns the program.  ``out`` is
    checked and locked first and replaced as a whole when complete (``overwrite``: see
    :func:`~render_inspect.io.atomic_output_dir`).

    An NC program is written with its links (approach, the moves between cuts, exit
    through the clearance plane) and read back and verified block by block before the
    folder is put in place: a program that fails is not written (the error names the
    block).  ``scene_file``: the scene file the scene was read from, named with its SHA-256
    in the program's header (:func:`_program_source`).  ``nc_comments`` (``"semicolon"``,
    the default, or ``"parenthesis"`` for a Fanuc-type control) and ``nc_block_numbers``
    (the increment of the block numbers, default 1; 0 writes none) set how the NC program
    writes its comment lines and block numbers (:func:`~render_inspect.io.write_nc`); its
    content is the same.

    A program whose blocks come faster than ``process.block_rate_limit_per_s`` is written,
    with a warning (``toolpath.block_rate``); where the scene sets no limit, faster than 1000
    a second (one block per millisecond) is said as a note."""
    formats = program_formats()
    if fmt not in formats:
        raise InputError(f"--format must be one of {formats}, received {fmt!r}")
    style = _nc_style(fmt, nc_comments, nc_block_numbers)
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    with atomic_output_dir(out, overwrite=overwrite, command="toolpath", scene=scene) as tmp:
        surface = make_surface(scene.design)
        plan = plan_program(scene, surface=surface)
        both = links_and_part(process, cfg, surface, plan)
        links, part = (None, None) if both is None else both
        if fmt == "nc":  # before the program is written, read back and verified
            nc_memory(scene, plan.program.points)
        header = {**process.program_header(cfg), **_program_source(scene, scene_file)}
        written = export_program(plan.program, Path(tmp), fmt=fmt, header=header, links=links,
                                 **style)
        facts = process.program_facts(cfg, plan)
        if fmt == "nc" and "program" not in facts:
            check = verify_program_file(written, process, cfg, surface, plan, links, part=part)
            if check is not None:
                facts["program_check"] = check
        if "program" in facts:  # a program read from a file: its figures and table too
            write_program_report(Path(tmp), plan, facts)
        write_metrics(tmp, toolpath_metrics(scene.name, facts), name="toolpath.json")
    log.info("%s program: %s points -> %s", process.traits(cfg).name,
             f"{facts['toolpath']['points']:,}", out)
    if "program" in facts:
        log_program_summary(facts["program"])
    rate = facts["toolpath"].get("block_rate") or {}
    if rate.get("warning"):
        # over the scene's own limit: a warning; over the default (the control unknown): a
        # note, since ultra-precision controls take more than one block per millisecond
        if rate.get("limit_from_scene"):
            log.warning("%s", rate["warning"])
        else:
            log.info("note: %s", rate["warning"])
    return plan.program


def write_program_report(folder: Path, plan: Plan, facts: dict) -> None:
    """The figures of a program read from a file (``feed_per_rev.png``,
    ``kinematics.png``) and its feed per revolution by radius as ``feed_per_rev.csv``."""
    for name, spec in plan.plots.items():
        draw_figure(spec, folder / name)
    rows = facts["program"].get("feed_per_rev", {}).get("by_radius", [])
    if rows:
        cols = ("r_from_mm", "r_to_mm", "points", "mean_um", "min_um", "max_um")
        text = ",".join(cols) + "\n" + "".join(
            ",".join(repr(r[c]) for c in cols) + "\n" for r in rows)
        atomic_write_text(folder / "feed_per_rev.csv", text)


def log_program_summary(info: dict, facts_file: str = "toolpath.json") -> None:
    """What was read and inferred, and the findings, one line each (findings as a
    warning); ``facts_file``: the file of the command that holds ``program``."""
    log.info("program %s (%s): %s", info.get("file"), info.get("dialect"),
             "; ".join(info.get("inferred", {}).values()))
    f = info.get("feed_per_rev")
    if f:
        log.info("feed per revolution %.4g um (median), %.4g .. %.4g um over the radius "
                 "(feed_per_rev.png, %s program.feed_per_rev)", f["median_um"],
                 f["min_um"], f["max_um"], facts_file)
    text = findings_summary(info)
    (log.warning if info.get("findings") else log.info)("program findings: %s", text)


def check_tool_edge(scene: Scene) -> Tool | None:
    """The scene's tool with its measured cutting edge (``tool.edge_profile``,
    ``tool.waviness``) read and checked as the cut will take it, before any work: an edge
    the cut cannot take (a deviation beyond 1 % of the nose radius, an edge that folds
    back) is an :class:`InputError` in one line.  None for a circular nose."""
    tool = getattr(scene, "tool", None)
    if tool is None or not (getattr(tool, "edge_profile", None) or getattr(tool, "waviness", None)):
        return None
    t = Tool.from_config(tool)
    return t if t.edge is not None else None


def edge_warnings(scene: Scene) -> list[str]:
    """What the nose arc (``tool.included_angle_deg``) takes from beyond a measured cutting
    edge (the deviation held at the table's end values), and a fitted radius the cut does
    not use: one line each, said before a run.  An edge the cut cannot take is refused
    (:func:`check_tool_edge`)."""
    t = check_tool_edge(scene)
    if t is None or t.edge is None:
        return []
    return edge_notes(t.edge, t.nose_radius, (-t.half_angle, t.half_angle),
                      f"the nose arc of tool.included_angle_deg = {math.degrees(2 * t.half_angle):g}")
