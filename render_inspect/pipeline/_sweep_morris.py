"""The Morris indices of a sweep's ``[morris]`` design (``morris.json``) and their table
(``summary.md``)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import cast

from ..batch import MorrisConfig, SweepFile, flatten, morris_indices, point_key

__all__ = ["sweep_morris", "morris_table"]


def sweep_morris(spec: SweepFile, records: Iterable[dict]) -> dict:
    """The Morris indices of a sweep's ``[morris]`` design from its finished records
    (:func:`~render_inspect.batch.morris_indices`; ``morris.json``)."""
    morris = cast(MorrisConfig, spec.morris)  # (a sweep with a [morris] design)
    keys = [f.key for f in morris.factor]
    found = {}
    for r in records:
        if r.get("status") != "done":
            continue
        p = r.get("params") or {}
        if any(p.get(k) is None for k in keys):
            continue
        found[point_key({k: p[k] for k in keys})] = flatten(r.get("metrics") or {})
    return morris_indices(morris, lambda point: found.get(point_key(point)))


def morris_table(morris: dict) -> list[str]:
    """Markdown lines of the Morris indices (``summary.md``)."""
    lines = [f"## Morris elementary effects ({morris['complete']} of {morris['trajectories']} "
             f"trajectories complete, {morris['levels']} levels)", ""]
    for name, ind in morris["indices"].items():
        lines += [f"### {name}", "", "| factor | mu* | mu | sigma |", "|---|---|---|---|"]
        fmt = (lambda v: "-" if v is None else f"{v:.4g}")
        for key, v in sorted(ind.items(), key=lambda kv: -(kv[1]["mu_star"] or 0.0)):
            lines.append(f"| {key} | {fmt(v['mu_star'])} | {fmt(v['mu'])} | {fmt(v['sigma'])} |")
        lines.append("")
    return lines
