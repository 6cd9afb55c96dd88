"""What the sweep's figures show: the rows of (sweep key values..., metric) of the finished
points (:func:`plot_rows`), and the plots a sweep file without ``[[plot]]`` gets
(:func:`default_plots`); :func:`render_inspect.report.sweep_plot_png` draws them."""

from __future__ import annotations

from collections.abc import Iterable

from ._morris import MORRIS_STUDY
from ._results import flatten
from ._sweepfile import PlotConfig, SweepFile

__all__ = ["plot_rows", "default_plots"]


def _rows(records, keys, metric, study=None):
    """(values of keys..., metric) for every finished record with all of them numeric."""
    rows = []
    for r in records:
        if r.get("status") != "done":
            continue
        if study is not None and study not in (r.get("studies") or []):
            continue
        p = r.get("params") or {}
        m = flatten(r.get("metrics") or {}).get(metric)
        vals = [p.get(k) for k in keys]
        if m is None or any(not isinstance(v, (int, float)) or isinstance(v, bool) for v in vals):
            continue
        rows.append((*[float(v) for v in vals], float(m)))
    return rows


def plot_rows(records: Iterable[dict], plot: PlotConfig) -> list[tuple]:
    """The rows one ``[[plot]]`` entry draws: (x, metric) or (x, series, metric) for
    ``curves``, (x, y, value) for ``heatmap``."""
    if plot.kind == "curves":
        return _rows(records, [plot.x] + ([plot.series] if plot.series else []), plot.y, plot.study)
    return _rows(records, [plot.x, plot.y], plot.value, plot.study)


def default_plots(spec: SweepFile) -> list[PlotConfig]:
    """Plots for a sweep file without ``[[plot]]``: per study, ``residual.Sq_nm`` against
    each varied key (a curve per value of the next key) and a heat map for every pair of
    varied keys (a ``[morris]`` design gets its indices' plots instead)."""
    out = []
    for st in spec.studies():
        if st.name == MORRIS_STUDY and spec.morris is not None:
            continue  # drawn as the Morris indices (report.morris_png)
        keys = [*st.grid, *st.zip]
        keys += [k for p in st.points for k in p if k not in keys]
        study = st.name if len(spec.studies()) > 1 else None
        tag = f"{st.name}_" if st.name else ""
        for i, k in enumerate(keys):
            series = keys[(i + 1) % len(keys)] if len(keys) > 1 else None
            out.append(PlotConfig(kind="curves", x=k, series=series, study=study,
                                  name=f"{tag}Sq_vs_{k.split('.')[-1]}"))
        for i in range(len(keys)):
            for j in range(i + 1, len(keys)):
                out.append(PlotConfig(kind="heatmap", x=keys[i], y=keys[j], study=study,
                                      name=f"{tag}Sq_{keys[i].split('.')[-1]}_"
                                           f"{keys[j].split('.')[-1]}"))
    return out
