"""Which point of a sweep to machine: the machining time of each point (the whole part's
program, from the scene and the feed the simulation planned) and the point that meets the
sweep file's ``[select]`` constraints at the smallest value of a metric (by default the
machining time).

A sweep file's ``[select]`` table::

    [select]
    minimize = "machining.time_min"       # the default
    [select.at_most]
    "residual.Sq_nm" = 2.0                # residual Sq <= 2 nm
    "residual.Sz_nm" = 15.0
    [select.at_least]
    "residual.valid_fraction" = 0.99
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Sequence
from typing import Any

from pydantic import Field, field_validator

from ..core.section import Section
from ..core.units import MIN_TO_S
from ._results import flatten

__all__ = ["SelectConfig", "machining_time", "select_point", "select_lines",
           "missing_metrics", "MACHINING_TIME"]

#: the metric each finished point gets from the sweep: the whole part's machining time
MACHINING_TIME = "machining.time_min"


def _metric_name(v: str) -> str:
    if not isinstance(v, str) or "." not in v.strip(".") or not all(v.split(".")):
        raise ValueError(f"must be a dotted metric name such as 'residual.Sq_nm' or "
                         f"{MACHINING_TIME!r}, received {v!r}")
    return v


class SelectConfig(Section):
    """``[select]``: the point to machine is the finished point that meets every bound of
    ``at_most`` and ``at_least`` (metric name -> limit, in the metric's own unit) with the
    smallest ``minimize``."""
    minimize: str = Field(MACHINING_TIME, description="the metric to make smallest among the "
                                                      "points that meet the bounds")
    at_most: dict[str, float] = Field(default_factory=dict,
                                      description="metric -> upper bound (metric <= bound)")
    at_least: dict[str, float] = Field(default_factory=dict,
                                       description="metric -> lower bound (metric >= bound)")

    @field_validator("minimize")
    @classmethod
    def _minimize(cls, v):
        return _metric_name(v)

    @field_validator("at_most", "at_least")
    @classmethod
    def _bounds(cls, v):
        for k in v:
            _metric_name(k)
        return v

    def metrics(self) -> list[str]:
        """Every metric the selection reads (the minimised one first)."""
        return list(dict.fromkeys([self.minimize, *self.at_most, *self.at_least]))

    def text(self) -> str:
        """The bounds in words: ``residual.Sq_nm <= 2, residual.Sz_nm <= 15``."""
        parts = [f"{k} <= {v:g}" for k, v in self.at_most.items()]
        parts += [f"{k} >= {v:g}" for k, v in self.at_least.items()]
        return ", ".join(parts)


def _number(v: Any) -> float | None:
    return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None


def machining_time(scene: dict, metrics: dict) -> dict | None:
    """The time the whole part's program cuts for, from a point's scene (as a dict) and
    its ``metrics.json``: ``{"time_s", "time_min", "of"}`` (``of``: what was counted), or
    None when it is not known before the program is written (a program read from a file).

    * A spiral (``process.kind`` sts, fts, hts, rcse): ``(Rw - Ri) / f`` revolutions at
      ``process.spindle_rpm``, from ``process.workpiece_radius`` Rw to
      ``process.inner_radius`` Ri at the feed per revolution f the simulation planned
      (``toolpath.feed_per_rev_mm``: ``process.feed_mm_per_min / process.spindle_rpm``,
      or the feed ``process.scallop_bound_nm`` chose).
    * Sculpturing: one target line per column of the lenslet array, each ``design.rows x
      design.pitch_y`` long, at the cutting speed ``process.feed_mm_per_min``.

    The approach, plunge and retract moves are not counted (seconds against the minutes or
    hours of the cut)."""
    proc = scene.get("process") or {}
    if proc.get("program"):
        return None
    kind = proc.get("kind")
    feed = proc.get("feed_mm_per_min")
    if not isinstance(feed, (int, float)) or feed <= 0:
        return None
    if kind == "sculpt":
        d = scene.get("design") or {}
        rows, cols, py = _number(d.get("rows")), _number(d.get("cols")), _number(d.get("pitch_y"))
        if rows is None or cols is None or py is None:
            return None
        t = cols * rows * py / (feed / MIN_TO_S)
        of = (f"{cols:g} target lines of {rows:g} x {py:g} mm at {feed:g} mm/min (the whole "
              f"lenslet array; moves between the lines not counted)")
    else:
        rpm, rw = _number(proc.get("spindle_rpm")), _number(proc.get("workpiece_radius"))
        ri = _number(proc.get("inner_radius")) or 0.0
        if rpm is None or rw is None or rpm <= 0:
            return None
        f = _number((metrics.get("toolpath") or {}).get("feed_per_rev_mm")) or feed / rpm
        revs = (rw - ri) / f
        t = revs / rpm * MIN_TO_S
        of = (f"the spiral from r = {rw:g} to {ri:g} mm: {revs:,.0f} revolutions of "
              f"{f:.4g} mm at {rpm:g} rpm (approach, plunge and retract not counted)")
    return {"time_s": t, "time_min": t / MIN_TO_S, "of": of}


def _known(records: Iterable[dict]) -> set[str]:
    return {k for r in records if r.get("status") == "done"
            for k in flatten(r.get("metrics") or {})}


def missing_metrics(select: SelectConfig, records: Iterable[dict]) -> str | None:
    """One line naming the ``[select]`` metrics that no finished point has (with the
    nearest name a point has), or None when every one is there or nothing is finished."""
    known = _known(records)
    if not known:
        return None
    bad = []
    for name in select.metrics():
        if name not in known:
            close = difflib.get_close_matches(name, sorted(known), n=1)
            bad.append(f"{name!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    if not bad:
        return None
    return (f"[select] names {'a metric' if len(bad) == 1 else 'metrics'} that the points do not "
            f"have: {', '.join(bad)}; metric names are dotted paths into a point's metrics.json, "
            f"such as 'residual.Sq_nm', or {MACHINING_TIME!r}")


def _value(flat: dict, name: str) -> float | None:
    v = flat.get(name)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        return None
    return float(v)


def select_point(records: Iterable[dict], select: SelectConfig) -> dict:
    """The point to machine among the finished ``records``.

    Returns
    -------
    dict
        ``constraints`` (the bounds in words), ``minimize``, ``finished`` (points done),
        ``meeting`` (how many meet every bound), ``best`` (the record id, ``params``,
        ``metrics``: the selection's metrics of the point that meets them with the smallest
        ``minimize``; None when none does), ``closest`` (when none does: the point whose
        worst bound is exceeded least, as a fraction of the bound, with ``excess``), and
        ``error`` (the metrics no point has; then nothing is selected).
    """
    done = [r for r in records if r.get("status") == "done"]
    out: dict[str, Any] = {"constraints": select.text(), "minimize": select.minimize,
                           "finished": len(done), "meeting": 0, "best": None, "closest": None,
                           "error": missing_metrics(select, done)}
    if out["error"]:
        return out
    meeting, scored = [], []
    for r in done:
        flat = flatten(r.get("metrics") or {})
        vals = {k: _value(flat, k) for k in select.metrics()}
        excess = 0.0
        for k, lim in select.at_most.items():
            v = vals[k]
            excess = max(excess, math.inf if v is None else (v - lim) / (abs(lim) or 1.0))
        for k, lim in select.at_least.items():
            v = vals[k]
            excess = max(excess, math.inf if v is None else (lim - v) / (abs(lim) or 1.0))
        entry = {"id": r.get("id"), "params": r.get("params") or {}, "metrics": vals,
                 "index": r.get("index", 0)}
        if excess <= 0 and vals[select.minimize] is not None:
            meeting.append(entry)
        elif math.isfinite(excess):
            scored.append((excess, entry))
    out["meeting"] = len(meeting)
    if meeting:
        out["best"] = min(meeting, key=lambda e: (e["metrics"][select.minimize], e["index"]))
    elif scored:
        excess, entry = min(scored, key=lambda t: (t[0], t[1]["index"]))
        out["closest"] = {**entry, "excess": excess}
    return out


def _num(v: Any) -> str:
    return f"{v:g}" if isinstance(v, float) else str(v)


def _point_text(entry: dict, keys: Sequence[str], select: SelectConfig) -> str:
    params = entry["params"]
    where = ", ".join(f"{k} = {_num(params.get(k))}" for k in keys) or "the base scene"
    vals = entry["metrics"]
    shown = ", ".join(f"{k} {vals[k]:.4g}" if vals.get(k) is not None else f"{k} -"
                      for k in select.metrics())
    return f"{where} (point {entry['id']}): {shown}"


def select_lines(result: dict, keys: Sequence[str], select: SelectConfig) -> list[str]:
    """The summary's lines (plain text) for a :func:`select_point` result."""
    if result["error"]:
        return [f"No point selected: {result['error']}."]
    bounds = result["constraints"] or "no bounds"
    head = f"meeting {bounds}" if result["constraints"] else "(no bounds given)"
    if result["best"] is not None:
        return [f"Best point {head}, smallest {select.minimize}: "
                f"{_point_text(result['best'], keys, select)}.  {result['meeting']} of "
                f"{result['finished']} finished points meet the bounds."]
    if not result["finished"]:
        return [f"No point selected ({bounds}): no point has finished."]
    text = f"No point meets {bounds} ({result['finished']} finished points)"
    if result["closest"] is not None:
        c = result["closest"]
        text += (f"; the closest exceeds its tightest bound by {c['excess']:.0%}: "
                 f"{_point_text(c, keys, select)}")
    return [text + "."]
