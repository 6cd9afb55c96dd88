"""The Morris screening plot of a sweep (``morris_<output>.png``): each factor's mean
absolute elementary effect mu* against the spread sigma of its effects (Campolongo,
Cariboni & Saltelli 2007), next to the factors ranked by mu*."""

from __future__ import annotations


import numpy as np

from ._savefig import figure_png

__all__ = ["morris_png"]


def _short(key: str) -> str:
    parts = key.split(".")
    return ".".join(parts[-2:]) if len(parts) > 2 else key


def morris_png(morris: dict, output: str, *, title: str = "") -> bytes:
    """PNG bytes of the indices of ``output`` in ``morris`` (what
    :func:`render_inspect.batch.morris_indices` returns): left mu* against sigma, one labelled
    point per factor on logarithmic axes (the line sigma = mu* parts effects that depend on
    the other factors from nearly linear ones; values below 1e-4 of the largest sit on
    the axes), right mu* as bars with +-sigma, largest first."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    ind = morris.get("indices", {}).get(output, {})
    rows = sorted(((k, v["mu_star"], v["sigma"] or 0.0) for k, v in ind.items()
                   if v["mu_star"] is not None), key=lambda r: -r[1])
    fig = Figure(figsize=(11.0, 4.6), dpi=100)
    FigureCanvasAgg(fig)
    ax, bx = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    if rows:
        mu = np.array([r[1] for r in rows])
        sd = np.array([r[2] for r in rows])
        top0 = max(float(mu.max()), float(sd.max()), 1e-12) * 1.5 * 1e-4
        ax.scatter(np.maximum(mu, top0), np.maximum(sd, top0), s=22, color="C0", zorder=3)
        for (k, m, s) in rows:
            ax.annotate(_short(k), (max(m, top0), max(s, top0)), fontsize=7, xytext=(3, 2),
                        textcoords="offset points")
        top = max(float(mu.max()), float(sd.max()), 1e-12) * 1.5
        # the factors span decades: logarithmic axes, the smallest kept a decade below
        floor = top * 1e-4
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.scatter(np.maximum(mu, floor), np.maximum(sd, floor), s=0)  # the autoscale
        ax.plot([floor, top], [floor, top], ":", color="0.5", lw=1, label="sigma = mu*")
        ax.set_xlim(floor, top)
        ax.set_ylim(floor, top)
        ax.legend(fontsize=8, loc="upper left")
        y = np.arange(len(rows))[::-1]
        bx.barh(y, mu, xerr=sd, color="C0", alpha=0.8, error_kw={"lw": 0.8, "capsize": 2})
        bx.set_yticks(y, [_short(r[0]) for r in rows], fontsize=7)
    else:
        for a in (ax, bx):
            a.text(0.5, 0.5, "no complete trajectory", ha="center", va="center",
                   transform=a.transAxes)
    ax.set_xlabel(f"mu* (change of {output} over the factor's range)")
    ax.set_ylabel("sigma of the elementary effects")
    ax.grid(True, alpha=0.3)
    bx.set_xlabel(f"mu* +- sigma of {output}")
    bx.grid(True, axis="x", alpha=0.3)
    n = morris.get("complete", 0)
    fig.suptitle((title or f"Morris elementary effects: {output}")
                 + f"  ({n} trajectories, {morris.get('levels')} levels)", fontsize=10)
    return figure_png(fig, tight_layout=True, close=False)
