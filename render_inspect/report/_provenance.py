"""The two parts every report page shares: the warnings the command said, at the top, and
where the run's inputs came from (the command line, files with their SHA-256, the scene as
run, software version, seed), at the end, so that the run can be repeated and checked."""

from __future__ import annotations

import shlex
from collections.abc import Iterable, Sequence

from ._format import fmt_number
from ._html import HtmlReport

__all__ = ["warnings_section", "provenance_section"]


def warnings_section(rep: HtmlReport, warnings: Sequence[str] | None) -> None:
    """A "Warnings" section: every warning the command printed (program findings, a failed
    virtual measurement, an unreliable registration, a tool edge used beyond its measured
    range, values that look like unit mistakes), or a line saying there were none."""
    rep.section("Warnings")
    if warnings:
        rep.text(f"{len(warnings)} warning{'s' if len(warnings) != 1 else ''} said by the "
                 f"command while it ran (also printed on the terminal):")
        rep.list(warnings, cls="warn")
    else:
        rep.text("None: the command said no warning while it ran.")


def provenance_section(rep: HtmlReport, metrics: dict, *, title: str = "Provenance",
                       extra: Iterable[Sequence[object]] = (),
                       seed_text: str = "seed (simulation; the camera noise seeds derive "
                                        "from it)") -> None:
    """A section with what repeats the run: the command line it was made with (and the
    directory it ran in), or that it was made from Python; the software version, the
    seed (``seed_text`` says what it seeds), the scene (its file and SHA-256, and the
    SHA-256 of the scene as run, after ``--set``), each input file with its role, path,
    size and SHA-256; ``extra`` rows after them."""
    inp = metrics.get("inputs") or {}
    sc = inp.get("scene") or {}
    named = metrics.get("scene")
    name = sc.get("name") or (named.get("name") if isinstance(named, dict) else named) or ""
    rep.section(title)
    cmd = inp.get("command")
    rows: list[list[object]] = [
        ["command", shlex.join(cmd) if cmd else
         "not recorded: the run was made from Python (the render_inspect API), not the "
         "render-inspect command line" if "command" in inp else "not recorded"],
    ]
    if cmd and inp.get("working_directory"):
        rows.append(["run in (relative paths start here)", inp["working_directory"]])
    rows += [
        ["software", f"render_inspect {metrics.get('software_version') or inp.get('software_version')}"
                     + (f", Python {inp['python']}" if inp.get("python") else "")],
        [seed_text, str(metrics.get("seed"))],
        ["scene", str(name)],
    ]
    f = sc.get("file")
    rows.append(["scene file", f["path"] if f else "not recorded (the scene was given as data)"])
    if f:
        rows.append(["scene file SHA-256", f.get("sha256") or f.get("note", "not hashed")])
    if sc.get("sha256_as_run"):
        rows.append(["scene as run (after --set) SHA-256", sc["sha256_as_run"]])
    rows += [list(r) for r in extra]
    rep.table(rows, header=["provenance", "value"])
    files = inp.get("files") or []
    if files:
        rep.table([[r.get("role", ""), r.get("path", ""),
                    "not read" if r.get("bytes") is None else f"{fmt_number(r['bytes'])} bytes",
                    r.get("sha256") or r.get("note", "not hashed")] for r in files],
                  header=["input file", "path", "size", "SHA-256"])
    else:
        rep.text("Input files: none besides the scene (the design, the tool and the tool path "
                 "are all given by the scene's keys).")
