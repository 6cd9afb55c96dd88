"""The measured cutting edge of a turned part: its deviation along the edge angle and the
form error it imprints (:func:`plot_tool_edge`, figure kind ``"tool_edge"``), and the edge
worn along the cut (:func:`plot_tool_wear`, figure kind ``"tool_wear"``); both registered
with :func:`~render_inspect.report.register_figure`."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._figure_kinds import register_figure
from ._savefig import save_png

__all__ = ["plot_tool_edge", "plot_tool_wear"]


@register_figure("tool_edge")
def plot_tool_edge(spec: dict, png_path: str | Path) -> Path:
    """Two panels: the edge's radius deviation (nm) against the angle along the edge, the
    cutting arc and the contact angles the region needs marked; the form error along one
    radial section of the simulated surface against the imprint the edge predicts on a
    path planned for the circular nose."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    ang = np.asarray(spec["angle_deg"])
    h = float(spec["half_angle_deg"])
    keep = np.abs(ang) <= h * 1.2 + 1
    a1.plot(ang[keep], np.asarray(spec["delta_nm"])[keep], color="k", lw=1)
    a1.axvspan(-h, h, color="0.9", label="cutting arc")
    c0, c1 = spec["contact_deg"]
    a1.axvspan(c0, c1, color="tab:orange", alpha=0.3, label="contact angles of the region")
    a1.set_xlabel("angle along the edge (deg)")
    a1.set_ylabel("radius deviation (nm)")
    a1.legend(loc="best", fontsize=8)
    r = np.asarray(spec["r_mm"])
    a2.plot(r, spec["imprint_nm"], color="tab:red", lw=1,
            label="imprint predicted without edge compensation")
    a2.plot(r, spec["error_nm"], color="tab:blue", lw=0.8,
            label=f"simulated form error (compensation {spec['compensation']})")
    a2.set_xlabel("distance from the spindle axis (mm)")
    a2.set_ylabel("height, mean removed (nm)")
    a2.legend(loc="best", fontsize=8)
    fig.suptitle(spec.get("title", ""), fontsize=10)
    return save_png(fig, png_path, tight_layout=True)


@register_figure("tool_wear")
def plot_tool_wear(spec: dict, png_path: str | Path) -> Path:
    """Two panels: the edge radius and the flank wear land over the whole part against the
    radius (the cut runs from the outside in); the simulated roughness (Sa of machined -
    design in rings of the region) against the radius."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    r = np.asarray(spec["r_mm"])
    a1.plot(r, spec["edge_radius_nm"], color="k", lw=1, label="edge radius (nm)")
    a1.set_xlabel("distance from the spindle axis (mm); the cut runs from the outside in")
    a1.set_ylabel("edge radius (nm)")
    b1 = a1.twinx()
    b1.plot(r, spec["flank_um"], color="tab:red", lw=1, label="flank wear land (um)")
    b1.set_ylabel("flank wear land VB (um)", color="tab:red")
    a1.invert_xaxis()
    a2.plot(spec["ring_r_mm"], spec["ring_sa_nm"], "o-", color="tab:blue", ms=3)
    a2.set_xlabel("distance from the spindle axis (mm)")
    a2.set_ylabel("Sa of machined - design in rings (nm)")
    a2.set_ylim(bottom=0)
    fig.suptitle(spec.get("title", ""), fontsize=10)
    return save_png(fig, png_path, tight_layout=True)
