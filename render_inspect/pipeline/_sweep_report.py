"""What a sweep says besides its points' own metrics: the ``results.csv`` column names of
the scene keys (with their units), each point's machining time, the point to machine
(``[select]``), and the size of a sweep before it runs (points, a rough time, the
``--yes`` gate for a large one)."""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from typing import Any

from ..batch import SweepFile, machining_time, missing_metrics, select_lines, select_point
from ..core.errors import InputError
from ..core.grid import grid_shape
from ..core.units import MIN_TO_S
from ..processes import process_of
from ..scene import Scene

__all__ = ["column_names", "add_machining_times", "selection", "point_seconds",
           "sweep_estimate", "estimate_text", "check_sweep_size", "CONFIRM_POINTS", "first_record_check",
           "check_select_names"]

#: a sweep with more points than this to run is refused without ``--yes`` (``yes=True``)
CONFIRM_POINTS = 500
#: the rough estimate of a point's own time before it runs: a fixed part (planning the
#: spiral over a small region, the metrics, the files; 0.16 - 0.4 s measured per point of
#: a 0.1 x 0.1 mm region at 1 um on two shared cores) plus its samples at the process's
#: cut rate; and the start of each worker (importing the package, loading the compiled
#: kernels: 9 s measured for the first point of a worker)
POINT_FIXED_S = 0.5
WORKER_START_S = 10.0
#: units of the scene keys whose names do not say it, as their descriptions begin
_UNITS = ("mm", "um", "nm", "rad", "deg", "s", "Hz", "%", "1/mm", "mm/s", "mm/min", "N", "GPa",
          "MPa", "K")
#: key names that already end in their unit
_UNIT_SUFFIX = re.compile(r"_(mm|um|nm|deg|rad|s|hz|rpm|gb|percent|per_min|per_rev|"
                          r"mm_per_min|mm_s|nm_rms)$", re.IGNORECASE)


def _unit_of(scene: Scene, key: str) -> str:
    """The unit of a scene key whose name does not say it ("" when it has none or its
    name ends in it): the first word of its description when that is a unit."""
    parts = key.split(".")
    if _UNIT_SUFFIX.search(parts[-1]):
        return ""
    node: Any = scene
    for part in parts[:-1]:
        node = getattr(node, part, None)
        if node is None:
            return ""
    fields = getattr(type(node), "model_fields", {})
    f = fields.get(parts[-1])
    desc = (getattr(f, "description", None) or "").strip()
    first = re.split(r"[,;( ]", desc, maxsplit=1)[0] if desc else ""
    return first if first in _UNITS else ""


def column_names(scene: Scene | None, keys: list[str]) -> dict:
    """``results.csv`` column of each scene key: the key with its unit added when its
    name does not say it (``tool.nose_radius`` -> ``tool.nose_radius_mm``; a key whose
    name ends in its unit, such as ``process.feed_mm_per_min``, and a key without a
    unit keep their name)."""
    out = {}
    for k in keys:
        unit = _unit_of(scene, k) if scene is not None else ""
        suffix = {"%": "percent", "1/mm": "per_mm", "mm/s": "mm_per_s",
                  "mm/min": "mm_per_min"}.get(unit, unit)
        out[k] = f"{k}_{suffix}" if suffix else k
    return out


def add_machining_times(tasks: list[dict], records: list[dict]) -> None:
    """Give every finished record of ``tasks`` the metric ``machining`` (``time_s``,
    ``time_min``, ``of``: :func:`render_inspect.batch.machining_time`), in place."""
    scenes = {t["id"]: t["scene"] for t in tasks}
    for r in records:
        m = r.get("metrics")
        if r.get("status") != "done" or not isinstance(m, dict) or r.get("id") not in scenes:
            continue
        mt = machining_time(scenes[r["id"]], m)
        if mt is not None:
            m["machining"] = mt
        else:
            m.pop("machining", None)


def selection(spec: SweepFile, keys: list[str], records: list[dict]) -> tuple[list[str], dict | None]:
    """The summary's lines on the point to machine (``[select]``) and the result for
    ``sweep.json`` (None without ``[select]``)."""
    if spec.select is None:
        return [], None
    result = select_point(records, spec.select)
    return select_lines(result, keys, spec.select), result


def check_select_names(spec: SweepFile, tasks: list[dict], records: list[dict], *,
                       source: Any = "", when: str = "nothing was run") -> None:
    """Refuse ``[select]`` metric names that the finished ``records`` (of ``tasks``) do not
    have: one line naming each with the nearest name a point has (nothing to check
    without ``[select]`` or before a point has finished)."""
    if spec.select is None:
        return
    copies = [{**r, "metrics": dict(r.get("metrics") or {})} for r in records]
    add_machining_times(tasks, copies)
    text = missing_metrics(spec.select, copies)
    if text:
        raise InputError(f"sweep file {str(source or spec.name)!r}: {text}; {when}")


def first_record_check(spec: SweepFile, source: Any = "") -> Callable[[dict, dict], None] | None:
    """A check for the first finished point of a run (:func:`check_select_names`): the
    sweep stops there, the point kept, rather than after its last point; None without
    ``[select]``."""
    if spec.select is None:
        return None

    def check(record: dict, task: dict) -> None:
        check_select_names(spec, [task], [record], source=source,
                           when="the sweep stopped after its first point (kept): correct "
                                "the name and run the same command again")
    return check


def point_seconds(scene: Scene) -> float:
    """A rough estimate of the seconds one point takes on a worker that has started
    (:data:`POINT_FIXED_S` and the samples at the process's cut rate)."""
    process = process_of(scene)
    rate = getattr(process.traits(process.inputs_of(scene)), "cut_rate", 0) or 0
    sim = scene.simulation
    ny, nx = grid_shape(tuple(sim.region), float(sim.pixel))
    return POINT_FIXED_S + (ny * nx / rate if rate > 0 else 0.0)


def sweep_estimate(todo: list[dict], workers: int | None, done: list[dict] | None = None) -> dict:
    """The points to run and a rough time: their estimates (or the median time of the
    points this folder has finished, when there are some) shared by the workers, plus the
    workers' start."""
    n = len(todo)
    nw = max(1, min(workers or os.cpu_count() or 1, n or 1))
    secs = sorted(float(r["seconds"]) for r in (done or [])
                  if r.get("status") == "done" and isinstance(r.get("seconds"), (int, float)))
    if secs:
        per = [secs[len(secs) // 2]] * n
        basis = f"the median of the {len(secs)} points finished here"
    else:
        per = [float(t.get("estimate_s") or POINT_FIXED_S) for t in todo]
        basis = "the points' samples at the process's cut rate"
    total = (sum(per) / nw + WORKER_START_S) if n else 0.0
    return {"points": n, "workers": nw, "seconds": total, "basis": basis}


def _duration(seconds: float) -> str:
    if seconds < 2 * MIN_TO_S:
        return f"{seconds:.0f} s"
    if seconds < 2 * MIN_TO_S * MIN_TO_S:
        return f"{seconds / MIN_TO_S:.0f} min"
    return f"{seconds / (MIN_TO_S * MIN_TO_S):.1f} h"


def estimate_text(est: dict) -> str:
    """``about 3 min on 2 workers (rough: ...)``."""
    return (f"about {_duration(est['seconds'])} on {est['workers']} worker"
            f"{'s' if est['workers'] != 1 else ''} (rough estimate from {est['basis']})")


def check_sweep_size(sweep_path: Any, est: dict, total: int, *, yes: bool) -> None:
    """Refuse a sweep with more than :data:`CONFIRM_POINTS` points to run unless ``yes``:
    one line with the points, those finished before and the estimated time."""
    n = est["points"]
    if n <= CONFIRM_POINTS or yes:
        return
    before = total - n
    raise InputError(f"sweep file {str(sweep_path)!r}: {n:,} points to run"
                     + (f" ({before:,} of {total:,} finished before)" if before else "")
                     + f", {estimate_text(est)}; more than {CONFIRM_POINTS} points run only "
                       f"with --yes (or make the grid smaller)")
