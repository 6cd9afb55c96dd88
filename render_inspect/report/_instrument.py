"""Figures of the virtual instrument's characterisation (``render-inspect characterise``):
its transfer function, step response, slope limit and noise."""

from __future__ import annotations

from ._figures import line_panels, map_panels

__all__ = ["characterise_figures"]


def characterise_figures(m, curves) -> dict:
    """The PNGs of an instrument characterisation (``itf.png``, ``step.png``, ``slope.png``,
    ``flat_noise.png``) from its metrics and curves (name -> bytes)."""
    profiles, diff = curves["step_profiles"], curves["flat_difference"]
    itf = m["itf"]
    t = itf["table"]
    f = [r["frequency_per_mm"] for r in t]
    inst = [(r["frequency_per_mm"], r["itf_instrument"]) for r in t if r["itf_instrument"] is not None]
    obj = m["objective"]
    figs = {"itf.png": line_panels([{
        "title": f"Instrument transfer function, {obj['name']} NA {obj['numerical_aperture']:g}",
        "xlabel": "spatial frequency (1/mm)", "ylabel": "measured / true amplitude",
        "series": [{"x": f, "y": [r["itf_textbook"] for r in t], "label": "pupil overlap (textbook)",
                    "style": "dashed"},
                   {"x": f, "y": [r["itf_model"] for r in t], "label": "model, linear theory"},
                   {"x": f, "y": [r["itf_optics"] for r in t], "label": "measured, optics (fine pixel)",
                    "style": "points"},
                   {"x": [a for a, _ in inst], "y": [b for _, b in inst],
                    "label": "measured, at the camera pixel", "style": "points"}],
        "vlines": [(itf["cutoff_per_mm"], "cut-off"), (itf["camera_nyquist_per_mm"], "camera Nyquist")],
        "ylim": (-0.05, 1.15)}])}
    psi = m["step"]["psi_profile"]
    figs["step.png"] = line_panels([
        {"title": "PSI, 20 nm step (step response)", "xlabel": "x from the edge (um)",
         "ylabel": "measured height (nm)", "series": [{"x": psi["x_um"], "y": psi["height_nm"]}]},
        {"title": "CSI: measured - true across a step (batwing)", "xlabel": "x from the edge (um)",
         "ylabel": "error (nm)",
         "series": [{"x": xv, "y": ev, "label": k} for k, (xv, ev) in profiles.items()]}])
    panels = []
    for key, sl in m["slope"].items():
        rows = sl["table"]
        panels.append({"title": f"sphere, {key} ({sl['pixel_um']:.3g} um pixel)",
                       "xlabel": "surface slope (deg)", "ylabel": "fraction",
                       "series": [{"x": [r["slope_deg"] for r in rows],
                                   "y": [r["valid_fraction"] for r in rows], "label": "valid pixels"},
                                  {"x": [r["slope_deg"] for r in rows],
                                   "y": [r["contrast"] for r in rows], "label": "fringe contrast"}],
                       "vlines": [(sl["slope_limit_deg"], "asin(NA)")], "ylim": (-0.05, 1.05)})
    figs["slope.png"] = line_panels(panels)
    figs["flat_noise.png"] = map_panels([("flat: difference of two measurements", diff)],
                                        label="nm", cmap="RdBu_r", symmetric=True)
    return figs
