"""The comparison page (report.html) from the compare metrics and figures."""

from __future__ import annotations

import json
import math

from .. import __version__
from ._html import HtmlReport

__all__ = ["build_page"]


def _get(d, path, default=None):
    for k in path.split("."):
        if not isinstance(d, dict) or k not in d:
            return default
        d = d[k]
    return d


_SUMMARY_ROWS = [
    ("residual Sa (nm)", "residual.Sa_nm"),
    ("residual Sq (nm)", "residual.Sq_nm"),
    ("residual Sz (nm)", "residual.Sz_nm"),
    ("residual min, signed (nm; < 0 = overcut)", "residual.min_nm"),
    ("filtered residual Sq (nm)", "filtered.Sq_nm"),
    ("filtered residual Sz (nm)", "filtered.Sz_nm"),
    ("instrument: residual Sq reported (nm)", "measured.instrument_residual_Sq_nm"),
    ("instrument: residual Sq true, same pixels (nm)", "measured.true_residual_Sq_nm"),
    ("instrument: height error rms (nm)", "measured.rms_nm"),
    ("instrument: height error PV (nm)", "measured.pv_nm"),
    ("instrument: measured pixels (fraction)", "measured.valid_fraction"),
    ("tool path points", "toolpath.points"),
    ("tool path revolutions", "toolpath.revolutions"),
]


def _fmt(v, scale=1.0, digits=4):
    if v is None:
        return None
    try:
        return f"{float(v) * scale:.{digits}g}"
    except (TypeError, ValueError):
        return str(v)


def _measured_section(rep, mf: dict, keys) -> None:
    """The measured file: checks, coverage, registration with its uncertainty, outliers,
    warnings, parameters, source (lengths in mm or um, heights in nm, angles in deg)."""
    rep.section("Measured file")
    src = mf.get("source") or {}
    px = mf.get("pixel_mm") or [None, None]
    shape = mf.get("shape") or [None, None]
    units = src.get("units_in_file") or {}
    rep.text(f"{src.get('path', '')}: read by {src.get('reader', '?')}; {shape[0]} x {shape[1]} "
             f"points, pixel {_fmt(px[0], 1e3)} x {_fmt(px[1], 1e3)} um (x by y); units declared "
             f"in the file: lateral {units.get('lateral', '?')}, vertical "
             f"{units.get('vertical', '?')}; read as mm.  Heights below in nm, shifts in um, "
             f"angles in degrees.")
    warns = list(mf.get("warnings") or [])
    for w in warns:
        rep.text(w, cls="note")
    checks = mf.get("checks") or {}
    reg = mf.get("registration") or {}
    unc = (reg.get("uncertainty") or {}).get("sigma", {})
    out = mf.get("outliers") or {}
    ov = checks.get("overlap") or {}
    rows = [["coverage of the simulated region (fraction of its area)", _fmt(mf.get("coverage"))],
            ["overlap after registration (fraction of the smaller area)", _fmt(ov.get("fraction"))],
            ["registration residual RMS (nm)", _fmt(checks.get("residual_rms_mm"), 1e6)],
            ["residual limit (nm)", _fmt(checks.get("residual_limit_mm"), 1e6)],
            ["checks", "passed" if checks.get("ok") else
             ("refused, compared with --force" if checks else "not run")],
            ["outliers (second difference, k = " + _fmt(out.get("sigma"), 1, 3) + ")",
             f"{out.get('count')} ({_fmt(100 * (out.get('fraction') or 0), 1, 3)} %), left out "
             f"of {' and '.join(out.get('left_out_of', []))}"]]
    rep.table(rows, header=["measured file", "value"])
    if reg:
        rrows = []
        for key, label, scale in (("tx_mm", "shift x (um)", 1e3), ("ty_mm", "shift y (um)", 1e3),
                                  ("tz_mm", "piston z (um)", 1e3),
                                  ("alpha_rad", "tilt about x (deg)", 180 / math.pi),
                                  ("beta_rad", "tilt about y (deg)", 180 / math.pi),
                                  ("gamma_rad", "rotation about z (deg)", 180 / math.pi)):
            sig = unc.get(key)
            rrows.append([label, _fmt(reg.get(key), scale),
                          "not fitted" if sig is None else _fmt(sig, scale, 3)])
        rep.table(rrows, header=["registration (design -> measured)", "value",
                                 "standard uncertainty"])
        meth = (reg.get("uncertainty") or {}).get("method")
        if meth:
            rep.text(f"Registration by {reg.get('method')} over {reg.get('n_points')} points; "
                     f"uncertainty: {meth}.")
    meas = mf.get("measured") or {}
    sim = mf.get("simulated") or {}
    dif = mf.get("difference") or {}
    rep.table([[k, meas.get(k), sim.get(k), dif.get(k)] for k in keys],
              header=["parameter", "measured - design", "simulated (same chain)",
                      "measured - simulated"])
    rep.table([[k, json.dumps(v) if isinstance(v, (dict, list)) else v] for k, v in src.items()],
              header=["source", "value"])


def build_page(scene, metrics: dict, figs: dict, *, notes=()) -> str:
    """HTML text of report.html.

    Parameters
    ----------
    scene : Scene
    metrics : dict
        What ``metrics.json`` holds (``compensated``, ``uncompensated``, optional
        ``measured_file``, ``lenslets``, provenance).
    figs : dict name -> PNG bytes
        The figures of :func:`render_inspect.report._compare._figures`.
    notes : list of str
        Render-size caps and other remarks to show.
    """
    c, u = metrics["compensated"], metrics["uncompensated"]
    mf = metrics.get("measured_file")
    rep = HtmlReport(f"render_inspect comparison: {scene.name}",
                     f"{scene.description or scene.design.type} | compensated "
                     f"({c['compensation']}) vs uncompensated ({u['compensation']}) | seed "
                     f"{metrics['seed']} | Mitsuba {metrics['mitsuba_variant']} | render_inspect "
                     f"{metrics['software_version']}")

    rep.section("Summary")
    dmin = c["residual"]["min_nm"], u["residual"]["min_nm"]
    rep.text(f"Signed minimum of machined - design: {dmin[0]:.1f} nm compensated, "
             f"{dmin[1]:.1f} nm uncompensated (negative = the tool cut below the design, "
             f"overcut). Residual Sq {c['residual']['Sq_nm']:.1f} nm vs "
             f"{u['residual']['Sq_nm']:.1f} nm.")
    header = ["quantity", "compensated", "uncompensated"] + (["measured file"] if mf else [])
    rows = []
    for label, key in _SUMMARY_ROWS:
        row = [label, _get(c, key), _get(u, key)]
        if mf:
            mkey = {"residual.Sa_nm": "measured.Sa_nm", "residual.Sq_nm": "measured.Sq_nm",
                    "residual.Sz_nm": "measured.Sz_nm"}.get(key)
            row.append(_get(mf, mkey) if mkey else None)
        rows.append(row)
    rep.table(rows, header=header)
    rep.text("Instrument rows: the height is retrieved from the rendered frames (phase "
             "shifting with 2-D unwrapping, or the coherence envelope peak) and aligned to the "
             "true height by its mean over the measured pixels (an interferometer measures "
             "relative height). 'Reported' is what the instrument would give as the residual; "
             "'true' is the ray-traced height on the same pixels: their difference is the "
             "instrument's share.")
    for n in notes:
        rep.text(n, cls="note")

    rep.section("Interferograms")
    rep.figure(figs["interferogram_side_by_side"],
               "Zero-phase-shift frame of the virtual interference microscope, same camera and "
               "seed for both variants (row 0 = smallest y at the bottom).")
    rep.figure(figs["interferogram_difference"], "Intensity difference, compensated - uncompensated.")

    rep.section("Diffuse light")
    rep.figure(figs["diffuse_micro_side_by_side"],
               "Microscope view straight down (orthographic), aluminium under the diffuse "
               "light; heights exaggerated as stated.")
    rep.figure(figs["diffuse_difference"], "Luminance difference (linear), compensated - uncompensated.")
    rep.figure(figs["diffuse_macro_side_by_side"], "Whole part, perspective view.")

    rep.section("Residual and filtered maps")
    cap = "machined - design (nm), one colour scale for all panels"
    if mf:
        cap += "; third panel: the measured file after registration to the design"
    rep.figure(figs["residual_side_by_side"], cap + ".")
    rep.figure(figs["residual_difference"], "Machined height, compensated - uncompensated (nm).")
    f = c["filtered"]
    desc = [f"form removal {f.get('form_removal')}"]
    if f.get("s_filter_mm"):
        desc.append(f"S-filter {f['s_filter_mm'] * 1e3:g} um")
    if f.get("l_filter_mm"):
        desc.append(f"L-filter {f['l_filter_mm'] * 1e3:g} um")
    extra = (" (default waviness filter: 2.5 feeds per revolution, removes the turning marks; "
             "set metrology.s_filter / l_filter to choose)") if f.get("default_waviness_filter") else ""
    rep.figure(figs["filtered_side_by_side"],
               "Filtered residual: " + ", ".join(desc) + extra + ".")
    keys = ["Sa_nm", "Sq_nm", "Sp_nm", "Sv_nm", "Sz_nm", "Ssk", "Sku", "Sdq", "Sdr_percent"]
    rep.table([[k, c["filtered"].get(k), u["filtered"].get(k)] for k in keys],
              header=["filtered parameter", "compensated", "uncompensated"])

    rep.section("Radial profiles")
    rep.figure(figs["radial_profiles"],
               "Radial sections through the spindle axis at several angles (after seed 000 "
               "Fig. 16 b, c): design (dashed) and machined heights, and machined - design. "
               "Without compensation the overcut waviness changes with the section angle.")

    rep.section("Phase retrieval (what the instrument reports)")
    rep.figure(figs["measured_residual_side_by_side"],
               "Measured height - design on the camera grid: the residual as the instrument "
               "sees it (camera noise, pixel averaging, slope drop-outs included).")
    rep.figure(figs["measurement_error_side_by_side"],
               "Measured - true height (nm), piston aligned by the mean over measured pixels.")
    mkeys = ["mode", "algorithm", "wavelength_nm", "rms_nm", "pv_nm", "piston_nm",
             "valid_fraction", "light_fraction", "regions"]
    rep.table([[k, c["measured"].get(k), u["measured"].get(k)] for k in mkeys],
              header=["phase retrieval", "compensated", "uncompensated"])
    ik = ["mode", "objective", "numerical_aperture", "wavelength_nm", "bandwidth_nm",
          "pixel_mm", "shape", "frames", "subsamples", "noise", "valid_fraction"]
    rep.table([[k, c["interferometer"].get(k), u["interferometer"].get(k)] for k in ik],
              header=["interferometer", "compensated", "uncompensated"])

    lens = metrics.get("lenslets")
    if lens:
        rep.section("Lenslets")
        cols = ["row", "col", "x_mm", "y_mm", "dx_um", "dy_um", "Sa_um", "Sq_um", "PV_um"]
        rep.table([[str(e.get("row"))] + [e.get(k) for k in cols[1:]] for e in lens], header=cols)
        ul = u.get("lenslets") or []
        if ul:
            rep.heading("Uncompensated")
            rep.table([[str(e.get("row"))] + [e.get(k) for k in cols[1:]] for e in ul], header=cols)

    if mf:
        _measured_section(rep, mf, keys)

    rep.section("Parameters")
    sd = scene.to_dict()
    for sec in ("design", "tool", "process", "simulation", "metrology"):
        val = sd.get(sec, {})
        rows = [[k, json.dumps(x) if isinstance(x, (dict, list)) else x] for k, x in val.items()]
        if sec == "process":
            rows = [r if r[0] != "compensation" else
                    ["compensation", f"{c['compensation']} | {u['compensation']}"] for r in rows]
        rep.table(rows, header=[f"[{sec}]", "value"])
    rs = metrics.get("render_settings", {})
    for sec in ("interferometer", "diffuse"):
        val = rs.get(sec, {})
        rep.table([[k, json.dumps(x) if isinstance(x, (dict, list)) else x] for k, x in val.items()],
                  header=[f"[render.{sec}] as rendered", "value"])

    rep.section("Scene and provenance")
    prov = [["software_version", metrics.get("software_version", __version__)],
            ["seed", metrics.get("seed")], ["mitsuba_variant", metrics.get("mitsuba_variant")],
            ["compare total (s)", _get(metrics, "timing_s.total")]]
    for name, v in (("compensated", c), ("uncompensated", u)):
        for k, t in (v.get("timing_s") or {}).items():
            prov.append([f"{name} {k} (s)", t])
    rep.table(prov, header=["provenance", "value"])
    rep.pre(json.dumps(sd, indent=2, sort_keys=True))
    return rep.render()
