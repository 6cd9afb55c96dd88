"""Figures of the virtual instrument's characterisation (``render-inspect characterise``):
its transfer function, step response, slope limit and noise; and the one-screen
summaries of ``measure`` and ``analyze``."""

from __future__ import annotations

import numpy as np

from ..core.units import MM_TO_UM
from ._figures import line_panels, map_panels
from ._profile_figs import period_text, profile_summary
from ._format import fmt_number, fmt_quantity

__all__ = ["analysis_summary", "characterise_figures", "measurement_summary"]


def characterise_figures(m: dict, curves: dict) -> dict:
    """The PNGs of an instrument characterisation (``itf.png``, ``step.png``, ``slope.png``,
    ``flat_noise.png``) from its metrics and curves (name -> bytes)."""
    profiles, diff = curves["step_profiles"], curves["flat_difference"]
    itf = m["itf"]
    t = itf["table"]
    f = [r["frequency_per_mm"] for r in t]
    inst = [(r["frequency_per_mm"], r["itf_instrument"]) for r in t if r["itf_instrument"] is not None]
    alias = [(r["frequency_per_mm"], r["aliased_instrument"]) for r in t
             if r.get("aliased_instrument") is not None]
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
                    "label": "measured, at the camera pixel (up to its Nyquist frequency)",
                    "style": "points"}]
        + ([{"x": [a for a, _ in alias], "y": [b for _, b in alias],
             "label": "above the camera's Nyquist: aliased pattern (not a transfer value)",
             "style": "points"}] if alias else []),
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
    # the camera's pixel spans the map: axes in mm on the part, not pixel indices
    px = m.get("pixel_mm") or (m.get("objective") or {}).get("pixel")
    ny, nx = np.shape(diff)
    figs["flat_noise.png"] = map_panels(
        [("flat: two measurements subtracted", diff)],
        extent=None if px is None else (0.0, nx * px, 0.0, ny * px),
        label="height difference (nm)", cmap="RdBu_r", symmetric=True)
    return figs


def measurement_summary(metrics: dict) -> list[tuple[str, str]]:
    """The headline numbers of ``measure``'s ``metrics.json`` for a one-screen summary:
    (quantity, text) rows."""
    m = metrics.get("measure", {})
    noise = m.get("noise") or {}
    h = m.get("height") or {}
    shape = m.get("shape") or [0, 0]
    rows = [("mode, algorithm", f"{str(m.get('mode', '')).upper()}, {m.get('algorithm')} "
                                f"(lambda_eff {fmt_quantity(m.get('effective_wavelength_nm'), 'nm')})"),
            ("camera", f"{shape[1]} x {shape[0]} pixels of "
                       f"{fmt_quantity((m.get('pixel_mm') or 0) * MM_TO_UM, 'um')}"),
            ("measured pixels", _percent(m.get("valid_fraction"))),
            ("fringes above the noise", _percent(m.get("light_fraction"))
             + (f" (frame noise {fmt_number(noise['frame_noise'])} of full scale, threshold "
                f"{fmt_number(noise.get('threshold_sigmas'))} sigma)"
                if noise.get("frame_noise") is not None else "")),
            ("regions, saturated pixels", f"{m.get('regions')}, {m.get('saturated_pixels')}")]
    if h:
        rows.append((f"height, {h.get('form_removed', 'plane')} removed",
                     f"Sq {fmt_quantity(h.get('Sq_nm'), 'nm')}, Sa {fmt_quantity(h.get('Sa_nm'), 'nm')}, "
                     f"Sz {fmt_quantity(h.get('Sz_nm'), 'nm')}"))
    return rows


def analysis_summary(metrics: dict) -> list[tuple[str, str]]:
    """The headline numbers of ``analyze``'s ``metrics.json`` for a one-screen summary:
    (quantity, text) rows (a profile's: :func:`profile_summary`)."""
    if metrics.get("kind") == "profile":
        return _input_rows(metrics.get("input") or {}) + profile_summary(metrics)
    a = metrics.get("areal", {})
    f = metrics.get("filter", {})
    shape = metrics.get("shape") or [0, 0]
    px = metrics.get("pixel_mm") or [0, 0]
    filt = ", ".join(f"{k[0]} {v:g} mm" for k, v in (("S_mm", f.get("S_mm")),
                                                     ("L_mm", f.get("L_mm"))) if v)
    out = metrics.get("outliers", {})
    rows = _input_rows(metrics.get("input") or {})
    valid = metrics.get("valid_fraction")
    n_bad = (metrics.get("input") or {}).get("n_invalid")
    invalid = (f"{n_bad:,} invalid ({_percent(1.0 - float(valid))})"
               if isinstance(n_bad, int) and valid is not None
               else f"{_percent(valid)} valid")
    # (four significant figures: the pixel as the file gives it, non-square ones told apart)
    rows += [("map", f"{shape[1]} x {shape[0]} points, pixel {px[0] * MM_TO_UM:.4g} x "
                     f"{px[1] * MM_TO_UM:.4g} um, field {px[0] * shape[1]:.4g} x "
                     f"{px[1] * shape[0]:.4g} mm (x by y); {invalid}"),
            ("form removed, filter", f"{(metrics.get('form') or {}).get('method')}, "
                                     f"{filt or 'none'}"),
            ("Sa, Sq", f"{fmt_quantity(a.get('Sa_nm'), 'nm')}, {fmt_quantity(a.get('Sq_nm'), 'nm')}"),
            ("Sp, Sv, Sz", f"{fmt_quantity(a.get('Sp_nm'), 'nm')}, {fmt_quantity(a.get('Sv_nm'), 'nm')}, "
                           f"{fmt_quantity(a.get('Sz_nm'), 'nm')}"),
            ("Ssk, Sku, Sdq", f"{fmt_number(a.get('Ssk'))}, {fmt_number(a.get('Sku'))}, "
                              f"{fmt_number(a.get('Sdq'))}"),
            ("outliers (3-sigma rule)", f"{out.get('count')} "
                                        + ("left out" if out.get("left_out") else "kept"))]
    dom = (metrics.get("periods") or {}).get("dominant")
    if dom and (dom.get("period_mm") or dom.get("note")):
        rows.append(("dominant period", period_text(dom)))
    return rows


def _input_rows(inp: dict) -> list[tuple[str, str]]:
    """The file (its format, the reader, the units it declares) and the instrument its
    header names (with the acquisition date), from ``metrics["input"]``."""
    if not inp:
        return []
    units = inp.get("units_in_file") or {}
    fmt = inp.get("format_name") or inp.get("format") or "?"
    if "position" in units:  # a profile: positions and heights, said or given
        where = ("in the file" if inp.get("units_from") == "file" else
                 f"units from {inp.get('units_in_file_from') or inp.get('units_from')}")
        said = f"; {where}: positions {units.get('position')}, heights {units.get('height')}"
    else:
        said = (f"; in the file: lateral {units.get('lateral')}, heights "
                f"{units.get('vertical')}" if units else "")
    date = inp.get("date")
    return [("file", f"{fmt}, read by {inp.get('reader') or '?'}{said}"),
            ("instrument", f"{inp.get('instrument') or 'not stated in the file'}"
                           + (f"; acquired {date}" if date else ""))]


def _percent(v: float | None) -> str:
    return "n/a" if v is None else f"{100 * float(v):.1f} %"
