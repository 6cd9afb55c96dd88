"""Sweep figures: a metric against one key with a curve per value of another (seed 000
Fig. 15 a-c as curves), and a metric over two keys as a heat map."""

from __future__ import annotations

import io

import numpy as np

from ._results import flatten
from ._sweepfile import PlotConfig

__all__ = ["curves_png", "heatmap_png", "default_plots", "plot_png"]


def _figure(figsize=(6.0, 4.4)):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()


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


#: Units of sweep keys whose names do not carry one (lengths are mm).
_UNITS = {"tool.nose_radius": "mm", "process.workpiece_radius": "mm", "simulation.pixel": "mm",
          "process.depth_of_cut": "mm", "process.arc_length": "mm"}


def _label(key: str) -> str:
    unit = _UNITS.get(key)
    return f"{key} ({unit})" if unit else key


def curves_png(records, *, x: str, y: str = "residual.Sq_nm", series: str | None = None,
               study: str | None = None, title: str = "", log: bool = False) -> bytes:
    """``y`` (a metric, dotted path into metrics.json) against the sweep key ``x``, one curve
    per value of the key ``series`` (points with other values of further keys are drawn
    as separate curves too, labelled by them).  Returns PNG bytes."""
    keys = [x] + ([series] if series else [])
    rows = _rows(records, keys, y, study)
    fig = _figure()
    ax = fig.add_subplot(111)
    groups: dict = {}
    for row in rows:
        groups.setdefault(row[1] if series else None, []).append((row[0], row[-1]))
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    for i, (s, pts) in enumerate(sorted(groups.items(), key=lambda t: (t[0] is None, t[0]))):
        pts = sorted(pts)
        col = cmap(i / max(len(groups) - 1, 1))
        ax.plot([p[0] for p in pts], [p[1] for p in pts], "o-", color=col, ms=4,
                label=None if s is None else f"{series} = {s:g}")
    ax.set_xlabel(_label(x))
    ax.set_ylabel(_label(y))
    if log:
        ax.set_yscale("log")
    ax.grid(True, alpha=0.3)
    if series and groups:
        ax.legend(fontsize=8)
    ax.set_title(title or f"{y} vs {x}" + (f" (study {study})" if study else ""), fontsize=10)
    if not rows:
        ax.text(0.5, 0.5, "no finished points", ha="center", va="center", transform=ax.transAxes)
    fig.tight_layout()
    return _png(fig)


def heatmap_png(records, *, x: str, y: str, value: str = "residual.Sq_nm",
                study: str | None = None, title: str = "", log: bool = False) -> bytes:
    """``value`` (a metric) over the plane of the sweep keys ``x`` and ``y``: cells on the
    grid of the values met, each annotated with its value (the mean where several points
    share a cell).  Returns PNG bytes."""
    from matplotlib.colors import LogNorm

    rows = _rows(records, [x, y], value, study)
    fig = _figure((6.2, 4.8))
    ax = fig.add_subplot(111)
    if rows:
        xs = sorted({r[0] for r in rows})
        ys = sorted({r[1] for r in rows})
        grid = np.full((len(ys), len(xs)), np.nan)
        acc: dict = {}
        for a, b, v in rows:
            acc.setdefault((ys.index(b), xs.index(a)), []).append(v)
        for (i, j), vs in acc.items():
            grid[i, j] = float(np.mean(vs))
        finite = grid[np.isfinite(grid)]
        norm = LogNorm(vmin=finite[finite > 0].min(), vmax=finite.max()) \
            if log and (finite > 0).any() else None
        im = ax.imshow(grid, origin="lower", aspect="auto", cmap="viridis", norm=norm,
                       interpolation="nearest")
        ax.set_xticks(range(len(xs)), [f"{v:g}" for v in xs])
        ax.set_yticks(range(len(ys)), [f"{v:g}" for v in ys])
        if grid.size <= 400:
            for (i, j), vs in acc.items():
                shade = im.norm(np.mean(vs))  # light text on the dark end of viridis
                ax.text(j, i, f"{np.mean(vs):.3g}", ha="center", va="center", fontsize=7,
                        color="w" if np.ma.filled(shade, 0.0) < 0.6 else "k")
        cb = fig.colorbar(im, ax=ax)
        cb.set_label(value)
    else:
        ax.text(0.5, 0.5, "no finished points", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel(_label(x))
    ax.set_ylabel(_label(y))
    ax.set_title(title or f"{value} over {x} and {y}" + (f" (study {study})" if study else ""),
                 fontsize=10)
    fig.tight_layout()
    return _png(fig)


def plot_png(records, plot: PlotConfig) -> bytes:
    """The PNG of one ``[[plot]]`` entry."""
    if plot.kind == "curves":
        return curves_png(records, x=plot.x, y=plot.y, series=plot.series, study=plot.study,
                          title=plot.title, log=plot.log)
    return heatmap_png(records, x=plot.x, y=plot.y, value=plot.value, study=plot.study,
                       title=plot.title, log=plot.log)


def default_plots(spec) -> list[PlotConfig]:
    """Plots for a sweep file without ``[[plot]]``: per study, ``residual.Sq_nm`` against
    each varied key (a curve per value of the next key) and a heat map for every pair of
    varied keys."""
    out = []
    for st in spec.studies():
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
