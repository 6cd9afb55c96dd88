"""What a report needs so that its run can be repeated and its warnings are not lost:
the command line it was made with (``render-inspect`` only), the input files (scene file,
machine program, measured file, a height-map design, a measured tool edge) each with its
SHA-256, the scene as run (after ``--set``), the software version and the seed; and every
warning the command said while it ran."""

from __future__ import annotations

import functools
import platform
from collections.abc import Callable, Iterable
from contextvars import ContextVar
from pathlib import Path
from typing import Any, ParamSpec, TypeVar

from .. import __version__
from ..core.invocation import command_line, working_directory
from ..fit import scene_hash
from ..io import file_record
from ._blender_warnings import note, scene_warnings, warnings_into

__all__ = ["run_inputs", "keeps_warnings", "said_warnings",
           "difference_warnings"]

_P = ParamSpec("_P")
_R = TypeVar("_R")

#: the warnings of the command now running (:func:`keeps_warnings`), None outside one
_SAID: ContextVar[list[str] | None] = ContextVar("render_inspect_said_warnings", default=None)

def _scene_inputs(d: dict) -> list[tuple[str, str]]:
    """(role, path) of the files a scene dictionary reads."""
    found: list[tuple[str, str]] = []

    def design(node: Any, role: str) -> None:
        if isinstance(node, dict):
            if isinstance(node.get("path"), str) and node["path"]:
                found.append((role, node["path"]))
            for part in ("base", "feature"):
                design(node.get(part), f"design {part} height map")

    design(d.get("design"), "design height map")
    for section, key, role in (("tool", "edge_profile", "measured tool edge"),
                               ("process", "program", "machine program")):
        sec = d.get(section)
        value = sec.get(key) if isinstance(sec, dict) else None
        if isinstance(value, str) and value:
            found.append((role, value))
    return found


def run_inputs(scene_dict: dict, *, scene_file: str | Path | None = None,
               measured: str | Path | None = None, seed: int | None = None,
               variants: Iterable[tuple[str, dict]] = ()) -> dict:
    """The provenance of a run: ``scene`` (``name``, ``file``: the scene file's record or
    None, ``sha256_as_run``: :func:`~render_inspect.fit.scene_hash` of the scene after its
    overrides, as ``fit.json``'s ``scene_sha256``), ``files`` (a
    :func:`~render_inspect.io.file_record` of each file the run read: the measured file, each
    variant's program, height-map design and measured tool edge; a variant's name in its
    role where the variants read different files), ``software_version``, ``python``,
    ``seed``, ``command`` (the ``render-inspect`` command line as typed, program name
    first, paths as given: :func:`render_inspect.core.invocation.command_line`; None for
    a run called from Python) and ``working_directory`` (where that command ran: what its
    relative paths are relative to; None with it)."""
    files: list[dict] = []
    seen: set[tuple[str, str]] = set()

    def add(path: str | Path, role: str) -> None:
        key = (role.split(" (")[0], str(Path(path).resolve()))
        if key not in seen:
            seen.add(key)
            files.append(file_record(path, role))

    if measured is not None:
        add(measured, "measured file")
    each = [(name, _scene_inputs(d)) for name, d in variants] or [("", _scene_inputs(scene_dict))]
    differ = len({tuple(x) for _, x in each}) > 1
    for name, found in each:
        for role, path in found:
            add(path, f"{role} ({name})" if differ and name else role)
    return {"scene": {"name": scene_dict.get("name"),
                      "file": None if scene_file is None else file_record(scene_file, "scene file"),
                      "sha256_as_run": scene_hash(scene_dict)},
            "files": files, "software_version": __version__,
            "python": platform.python_version(), "seed": seed,
            "command": command_line(), "working_directory": working_directory()}


def keeps_warnings(fn: Callable[_P, _R]) -> Callable[_P, _R]:
    """Run ``fn`` (a command's pipeline function, scene first) keeping every warning it
    logs, and those the command line says of the scene before a run (unit mistakes, a
    measured tool edge's range), for :func:`said_warnings`: what its report lists at
    the top."""

    @functools.wraps(fn)
    def run(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        outer = _SAID.get()
        found: list[str] = [] if outer is None else outer
        if args:
            scene_warnings(args[0], found)
        token = _SAID.set(found)
        try:
            with warnings_into(found):
                return fn(*args, **kwargs)
        finally:
            _SAID.reset(token)

    return run


def said_warnings(extra: Iterable[str] = ()) -> list[str]:
    """The warnings said so far by the command now running (:func:`keeps_warnings`), each
    once, with ``extra`` lines added."""
    found = list(_SAID.get() or [])
    for text in extra:
        if text.split(": ", 1)[-1] not in found:  # a measured file's warning already said
            note(found, text)
    return found


def difference_warnings(metrics: dict) -> list[str]:
    """``compare``'s warnings found in its own numbers: a measured difference that failed
    or is not resolved above the measurements' noise, a variant measured on few pixels,
    and the measured file's warnings and refusals (compared with ``--force``)."""
    out: list[str] = []
    names = [v["name"] for v in metrics.get("variants", [])]
    pair = " - ".join(names)
    mw = ((metrics.get("difference") or {}).get("window") or {}).get("measured") or {}
    res = mw.get("resolution") or {}
    if mw.get("status") == "failed":
        why = "; ".join((mw.get("fringe_order") or {}).get("reasons") or []) or "fringe-order failure"
        out.append(f"the measured difference {pair} FAILED ({why}): its map and profile show what "
                   f"the unwrapping gave, not a measurement")
    elif res.get("resolved") is False:
        out.append(f"the measured difference {pair} is not resolved: {mw.get('rms_nm', 0):.3g} nm "
                   f"rms against a noise floor of {(mw.get('noise') or {}).get('floor_nm', 0):.3g} "
                   f"nm ({res.get('rule', '')})")
    for name in names:
        frac = ((metrics.get(name) or {}).get("measured") or {}).get("valid_fraction")
        if isinstance(frac, (int, float)) and frac < 0.9:
            out.append(f"{name}: the virtual interferometer measured {100 * frac:.3g} % of its "
                       f"pixels (slopes beyond the objective's aperture, or no fringes above the "
                       f"noise): its instrument rows cover those pixels only")
    mf = metrics.get("measured_file") or {}
    for w in mf.get("warnings") or []:
        out.append(f"measured file: {w}")
    checks = mf.get("checks") or {}
    if checks and not checks.get("ok"):
        out.append("measured file: refused by its checks and compared with --force: "
                   + "; ".join(str(r) for r in checks.get("refusals") or []))
    return out
