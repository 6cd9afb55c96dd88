"""The comparison page (report.html) from the compare metrics and figures.

The first figure is the difference between the two variants; every number is written
with its unit and no more digits than the computation resolves; tables show the values
as rendered (presets resolved), never a placeholder for a value a figure states.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from typing import Any, Protocol

from ..core.units import MM_TO_UM
from .. import __version__
from ._format import fmt_number, fmt_quantity
from ._comparison import resolution_text
from ._html import HtmlReport
from ._page_text import (_diffuse_value, _g, _get, _lowpass_caption, _macro_light_words,
                         _micro_light_words, _overcut_sentences, _process_facts, _q, _res, _scaled,
                         _value_text)
from ._params import SECTION_ORDER, meaning, section_rows, settings_rows, value_text
from ._program_page import program_section
from ._provenance import provenance_section, warnings_section

__all__ = ["build_page", "ReportedScene"]


class _DesignType(Protocol):
    @property
    def type(self) -> str:
        ...


class ReportedScene(Protocol):
    """What the comparison page reads of a validated scene (the scene's ``Scene``, which a
    type checker confirms satisfies this where the pipeline passes one): its name, its
    description, the design's type, the ``[render]`` section, each section by name and the
    whole scene as a dictionary."""

    @property
    def name(self) -> str:
        ...

    @property
    def description(self) -> str:
        ...

    @property
    def design(self) -> _DesignType:
        ...

    @property
    def render(self) -> object:
        ...

    def to_dict(self) -> dict:
        ...


#: (label, key, unit) of the summary table
_SUMMARY_ROWS = [
    ("residual Sa", "residual.Sa_nm", "nm"),
    ("residual Sq", "residual.Sq_nm", "nm"),
    ("residual Sz", "residual.Sz_nm", "nm"),
    ("residual min, signed (< 0 = overcut)", "residual.min_nm", "nm"),
    ("waviness (filtered residual) Sq", "filtered.Sq_nm", "nm"),
    ("waviness (filtered residual) Sz", "filtered.Sz_nm", "nm"),
    ("instrument: residual Sq reported", "measured.instrument_residual_Sq_nm", "nm"),
    ("instrument: residual Sq true, same pixels", "measured.true_residual_Sq_nm", "nm"),
    ("instrument: height error rms", "measured.rms_nm", "nm"),
    ("instrument: height error PV", "measured.pv_nm", "nm"),
    ("instrument: measured pixels", "measured.valid_fraction", "fraction"),
]

#: what each summary row is of, and how it is filtered (the ``{filters}`` of the waviness)
_SUMMARY_OF = {
    "residual": ("ISO 25178-2, of the simulated cut (the truth): machined - design over the "
                 "simulated region at the simulation's pixel, heights about their mean; no S- "
                 "or L-filter"),
    "residual.min_nm": ("the lowest point of the simulated cut's machined - design (not "
                        "levelled): how far the cut goes below the design"),
    "filtered": "ISO 25178-2, of the simulated cut's waviness: {filters}",
    "measured.instrument_residual_Sq_nm": (
        "ISO 25178-2 Sq, as measured by the virtual interferometer: measured - design on the "
        "camera grid over the common window, piston and tilt removed; no S- or L-filter"),
    "measured.true_residual_Sq_nm": (
        "ISO 25178-2 Sq of the simulated cut on the same camera pixels, the same piston and "
        "tilt removed"),
    "measured.rms_nm": "virtual interferometer: measured - true height over its measured pixels",
    "measured.pv_nm": "virtual interferometer: measured - true height over its measured pixels",
    "measured.valid_fraction": "virtual interferometer: share of the camera's pixels measured",
}


def _summary_of(key: str, filters: str) -> str:
    """What a summary row's number is of, with its filters and standard."""
    text = _SUMMARY_OF.get(key) or _SUMMARY_OF.get(key.split(".")[0], "")
    return text.format(filters=filters)


def _filters_words(f: dict) -> str:
    """The waviness filters in words: S- and L-filter nesting indices, form removed."""
    s_mm, l_mm = f.get("s_filter_mm"), f.get("l_filter_mm")
    return (f"ISO 16610-61 Gaussian S-filter "
            + (_q(s_mm * MM_TO_UM, "um") if s_mm else "none")
            + ", L-filter " + (_q(l_mm, "mm") if l_mm else "none")
            + f", form removed first: {f.get('form_removal') or 'none'}")


_FILTER_KEYS = [("Sa", "Sa_nm", "nm"), ("Sq", "Sq_nm", "nm"), ("Sp", "Sp_nm", "nm"),
                ("Sv", "Sv_nm", "nm"), ("Sz", "Sz_nm", "nm"), ("Ssk", "Ssk", ""),
                ("Sku", "Sku", ""), ("Sdq", "Sdq", ""), ("Sdr", "Sdr_percent", "%")]


def _chance_text(reg: dict) -> str:
    """The registration's score against chance in words."""
    if "reliable" not in reg:
        return "not checked"
    best = reg.get("null_score")
    return (f"{'reliable' if reg['reliable'] else 'NOT RELIABLE'}: explains "
            f"{fmt_number(reg.get('score'), resolution=1e-3)} of the variance against "
            f"{'n/a' if best is None else fmt_number(best, resolution=1e-3)} for the best of "
            f"{(reg.get('chance') or {}).get('surrogates', '?')} surrogates")


def _measured_section(rep: HtmlReport, mf: dict) -> None:
    """The measured file: checks, coverage, registration with its uncertainty, outliers,
    warnings, parameters, source (lengths in mm or um, heights in nm, angles in deg)."""
    rep.section("Measured file")
    src = mf.get("source") or {}
    px = mf.get("pixel_mm") or [None, None]
    shape = mf.get("shape") or [None, None]
    units = src.get("units_in_file") or {}
    rep.text(f"{src.get('path', '')}: read by {src.get('reader', '?')}; {shape[0]} x {shape[1]} "
             f"points, pixel {fmt_quantity(_scaled(px[0], 1e3), 'um')} x "
             f"{fmt_quantity(_scaled(px[1], 1e3), 'um')} (x by y); units declared in the file: "
             f"lateral {units.get('lateral', '?')}, vertical {units.get('vertical', '?')}; "
             f"read as mm. Instrument: {src.get('instrument') or 'not stated in the file'}"
             f"{', acquired ' + str(src['date']) if src.get('date') else ''}.")
    for w in mf.get("warnings") or []:
        rep.text(w, cls="note")
    checks = mf.get("checks") or {}
    reg = mf.get("registration") or {}
    unc = (reg.get("uncertainty") or {}).get("sigma", {})
    out = mf.get("outliers") or {}
    ov = checks.get("overlap") or {}
    rows = [["coverage of the simulated region (of its area)",
             _q(mf.get("coverage"), "fraction")],
            ["overlap after registration (of the smaller area)",
             _q(ov.get("fraction"), "fraction")],
            ["registration residual RMS", fmt_quantity(_scaled(checks.get("residual_rms_mm"), 1e6),
                                                       "nm")],
            ["residual limit", fmt_quantity(_scaled(checks.get("residual_limit_mm"), 1e6), "nm")],
            ["checks", "passed" if checks.get("ok") else
             ("refused, compared with --force" if checks else "not run")],
            ["registration against chance", _chance_text(reg)],
            [f"outliers (spikes, k = {fmt_number(out.get('sigma'))})",
             f"{fmt_number(out.get('count'))} ({_q(out.get('fraction') or 0.0, 'fraction')}), "
             f"left out of {' and '.join(out.get('left_out_of', [])) or 'nothing'}"]]
    rep.table(rows, header=["measured file", "value"])
    if reg:
        rrows = []
        for key, label, scale, res in (("tx_mm", "shift x (um)", 1e3, 1e-4),
                                       ("ty_mm", "shift y (um)", 1e3, 1e-4),
                                       ("tz_mm", "piston z (um)", 1e3, 1e-4),
                                       ("alpha_rad", "tilt about x (deg)", 180 / math.pi, 1e-6),
                                       ("beta_rad", "tilt about y (deg)", 180 / math.pi, 1e-6),
                                       ("gamma_rad", "rotation about z (deg)", 180 / math.pi,
                                        1e-6)):
            sig = unc.get(key)
            rrows.append([label, fmt_number(_scaled(reg.get(key), scale), resolution=res),
                          "not fitted" if sig is None else
                          fmt_number(sig * scale, resolution=res)])
        rep.table(rrows, header=["registration (design -> measured)", "value",
                                 "standard uncertainty"])
        meth = (reg.get("uncertainty") or {}).get("method")
        if meth:
            rep.text(f"Registration by {reg.get('method')} over {fmt_number(reg.get('n_points'))} "
                     f"points; uncertainty: {meth}.")
    meas = mf.get("measured") or {}
    sim = mf.get("simulated") or {}
    dd = mf.get("difference") or {}
    flag = " (not reliable)" if reg.get("reliable") is False else ""
    rep.table([[label, _q(meas.get(k), unit), _q(sim.get(k), unit), _q(dd.get(k), unit)]
               for label, k, unit in _FILTER_KEYS],
              header=["parameter", "measured - design" + flag, "simulated (same chain)",
                      "measured - simulated" + flag])
    rep.table([[k, _value_text(k, v)] for k, v in src.items()], header=["source", "value"])


def build_page(scene: ReportedScene, metrics: dict, figs: dict, *, notes: Iterable[str] = ()) -> str:
    """HTML text of report.html.

    Parameters
    ----------
    scene : Scene
    metrics : dict
        What ``metrics.json`` holds (``variants``, one entry per variant name, ``pair``,
        ``difference``, ``filters``, ``windows``, optional ``measured_file``,
        ``lenslets``, provenance).
    figs : dict name -> PNG bytes
        The figures of the comparison (``difference`` first, or ``windows`` when the
        variants are identical).
    notes : list of str
        Render-size caps and other remarks to show.
    """
    va, vb = (v["name"] for v in metrics["variants"])
    la, lb = (v["label"] for v in metrics["variants"])
    c, u = metrics[va], metrics[vb]
    pair = metrics.get("pair", {})
    mf = metrics.get("measured_file")
    # (the scene's name, with the program's file where the cut is a program read from one)
    rep = HtmlReport(f"render_inspect comparison: {metrics.get('run_name') or scene.name}",
                     f"{scene.description or scene.design.type} | {va}: {la} vs {vb}: {lb} | seed "
                     f"{metrics['seed']} | Mitsuba {_variants_text(metrics)} | render_inspect "
                     f"{metrics['software_version']}")

    warnings_section(rep, metrics.get("warnings"))

    # ---- 1. the difference
    d = metrics["difference"]
    w = d.get("window", {})
    rep.section(f"What differs: {va} - {vb}")
    if pair.get("about"):
        rep.text(pair["about"])
    win = w.get("window_mm") or metrics["windows"]["common_mm"]
    win_txt = (f"x {fmt_number(win[0], sig=4)} .. {fmt_number(win[2], sig=4)} mm, "
               f"y {fmt_number(win[1], sig=4)} .. {fmt_number(win[3], sig=4)} mm")
    if pair.get("identical"):
        rep.text(f"The two variants are identical: {pair.get('key')} makes no difference to the "
                 f"machined surface of this scene, so no difference maps are shown.", cls="note")
        rep.figure(figs["windows"], f"Where the windows are: the simulated region and the common "
                                    f"window ({win_txt}), x and y in mm on the part, over the "
                                    f"design's height in grey (colour bar: nm or um as labelled).")
    else:
        tw, mw = w.get("true") or {}, w.get("measured") or {}
        same = w.get("true_same_form_removed") or {}
        removed = mw.get("form_removed", "piston and tilt")
        failed_note = (" The measured difference FAILED (fringe-order failures, said below): "
                       "its panel and profile show what the unwrapping gave, not a "
                       "measurement." if mw.get("status") == "failed" else "")
        rep.figure(figs["difference"],
                   f"Figure 1. {va} - {vb} over one common window ({win_txt}), placed where the "
                   f"two differ most. Left: where every window of this report lies (simulated "
                   f"region, interferometer field = common window, micro diffuse view; inset: "
                   f"the whole part), x and y in mm on the part, over the design's height in "
                   f"grey (its colour bar: nm or um as labelled). Middle: the true height difference of the simulated "
                   f"surfaces, and the difference of what the virtual interferometer measures, "
                   f"formed from the two measurements alone as instrument software does ({removed} "
                   f"removed; the fringe order of separate regions taken nearest the largest "
                   f"region's plane; pixels of unknown fringe order masked), on one colour scale. "
                   f"Right: the profile along the dashed line, through the largest difference."
                   + failed_note + _lowpass_caption(metrics))
        failed = mw.get("status") == "failed"
        floor = (mw.get("noise") or {}).get("floor_nm")
        rep.table([["measured by the virtual interferometer",
                    "FAILED" if failed else _q(mw.get("rms_nm"), "nm"),
                    "failed (no value)" if failed else _q(mw.get("pv_nm"), "nm"),
                    "failed (no value)" if failed else _q(mw.get("mean_nm"), "nm"),
                    f"the two measurements alone, {removed} removed; noise floor "
                    f"{_q(floor, 'nm')} (their own noise estimates, in quadrature)"],
                   ["true, like with like", _q(same.get("rms_nm"), "nm"),
                    _q(same.get("pv_nm"), "nm"), _q(same.get("mean_nm"), "nm"),
                    f"the simulated heights at the camera pixels both measured, the same "
                    f"{removed} removed: what the measured row should read"],
                   ["true, raw", _q(tw.get("rms_nm"), "nm"), _q(tw.get("pv_nm"), "nm"),
                    _q(tw.get("mean_nm"), "nm"),
                    "the simulated machined maps over the window at the simulation's pixel, "
                    "nothing removed"]],
                  header=[f"{va} - {vb} over the common window", "rms", "PV", "mean",
                          "how the number is formed"])
        verdict = resolution_text(mw)
        if verdict:
            rep.text(f"Is the measured difference resolved? {verdict}.",
                     cls="note" if failed or not (mw.get("resolution") or {}).get("resolved") else None)
        rep.text(f"Over the whole simulated region the true difference {va} - {vb} has an rms "
                 f"of {_q(d.get('machined_rms_nm'), 'nm')} and a PV of "
                 f"{_q(d.get('machined_pv_nm'), 'nm')}.")
    rep.table([[k, _q(_get(c, key), unit), _q(_get(u, key), unit)]
               for k, key, unit in [("residual Sq", "residual.Sq_nm", "nm"),
                                    ("residual min (< 0 = overcut)", "residual.min_nm", "nm"),
                                    ("waviness Sq", "filtered.Sq_nm", "nm")]],
              header=["headline", f"{va}: {la}", f"{vb}: {lb}"])
    for text in _overcut_sentences(metrics):
        rep.text(text)
    for n in notes:
        rep.text(n, cls="note")

    # ---- 2. summary
    rep.section("Summary")
    header = ["quantity", va, vb] + (["measured file"] if mf else []) + [
        "what it is of (standard, filters)"]
    fwords = _filters_words(metrics.get("filters") or {})
    rows = []
    for label, key, unit in _SUMMARY_ROWS:
        row = [label, _q(_get(c, key), unit), _q(_get(u, key), unit)]
        if mf:
            mkey = {"residual.Sa_nm": "measured.Sa_nm", "residual.Sq_nm": "measured.Sq_nm",
                    "residual.Sz_nm": "measured.Sz_nm"}.get(key)
            row.append(_q(_get(mf, mkey), unit) if mkey else "not measured")
        rows.append(row + [_summary_of(key, fwords)])
    tp_c, tp_u = c.get("toolpath") or {}, u.get("toolpath") or {}
    if tp_c.get("revolutions"):
        rows.append(["tool path points", fmt_number(tp_c.get("points")),
                     fmt_number(tp_u.get("points"))] + (["not measured"] if mf else []) + ["the tool path as simulated"])
        rows.append(["tool path revolutions", fmt_number(tp_c.get("revolutions")),
                     fmt_number(tp_u.get("revolutions"))] + (["not measured"] if mf else []) + ["the tool path as simulated"])
    elif tp_c.get("lines"):
        rows.append(["cutting lines", fmt_number(tp_c.get("lines")),
                     fmt_number(tp_u.get("lines"))] + (["not measured"] if mf else []) + ["the tool path as simulated"])
    rep.table(rows, header=header)
    if mf:
        rep.text("Measured file column: ISO 25178-2 parameters of the measured file minus the "
                 "design after its registration to the design (heights about their mean, "
                 "outliers as said under Measured file, no S- or L-filter).")
    rep.text("Instrument rows: the height is retrieved from the rendered frames (phase "
             "shifting with 2-D unwrapping, or the coherence envelope peak) and aligned to the "
             "true height by its mean over the measured pixels. 'Reported' is what the "
             "instrument would give as the residual; 'true' is the ray-traced height on the same "
             "pixels: their difference is the instrument's share.")

    # ---- 3. maps
    rep.section("Residual and waviness maps")
    cap = ("machined - design over the simulated region (nm), one colour scale for all panels; "
           "blue is below the design (an overcut): where each variant's deepest point comes "
           "from (the commanded geometry, the lathe, the material) is said under the headline "
           "numbers")
    if mf:
        cap += "; third panel: the measured file after registration to the design"
    rep.figure(figs["residual_side_by_side"], cap + ".")
    rep.figure(figs["residual_difference"],
               f"Machined height, {va} - {vb} (nm), over the simulated region; the dashed line is "
               f"the profile of Figure 1.")
    f = metrics.get("filters") or {}
    rep.heading("Waviness: the filters")
    desc = []
    if f.get("s_filter_mm"):
        desc.append(f"S-filter {_q(f['s_filter_mm'] * MM_TO_UM, 'um')}")
    if f.get("l_filter_mm"):
        desc.append(f"L-filter {_q(f['l_filter_mm'], 'mm')}")
    rep.text("ISO 16610-61 Gaussian filters, form removed first (" + (f.get("form_removal") or "none")
             + ")" + (": " + ", ".join(desc) if desc else "") + ". Chosen from the scene:")
    rep.list(f.get("reasons") or [])
    rep.figure(figs["filtered_side_by_side"],
               f"Waviness (filtered residual, nm): {va}, {vb} and their difference, one colour "
               f"scale; the border the filters cannot reach is "
               + ("cut (blank)." if f.get("edges") == "cut" else "filled by mirroring the map."))
    rep.table([[label, _q(c["filtered"].get(k), unit), _q(u["filtered"].get(k), unit)]
               for label, k, unit in _FILTER_KEYS],
              header=["waviness parameter", va, vb])
    rep.text(f"Waviness parameters: ISO 25178-2 (Sdq: root mean square gradient, no unit; Sdr: "
             f"developed interfacial area ratio) of the simulated cut's machined - design after "
             f"the filters above ({fwords}).")

    # ---- 4. interferometer
    ic = _get(metrics, "render_settings.interferometer") or {}
    rep.section("The virtual interferometer")
    rep.figure(figs["interferogram_side_by_side"],
               f"Zero-phase-shift frame over the common window, same camera for both, each "
               f"with its own noise "
               f"({ic.get('objective')}, NA {_g(ic.get('numerical_aperture'))}, "
               f"{_g(ic.get('wavelength_nm'))} nm, "
               f"{_q((ic.get('pixel') or 0) * MM_TO_UM, 'um')} pixels).")
    rep.figure(figs["interferogram_difference"], f"Intensity difference, {va} - {vb}.")
    rep.figure(figs["measured_residual_side_by_side"],
               "Measured height - design on the camera grid: the residual as the instrument "
               "sees it (camera noise, pixel averaging, slope drop-outs included), with its "
               "piston and tilt removed as instrument software does (an interferometer "
               "measures relative height; phase shifting knows heights only up to whole "
               "fringe orders of lambda_eff / 2 between regions that do not touch).")
    rep.figure(figs["measurement_error_side_by_side"],
               "Measured - true height (nm): the evaluation against the simulation's truth, "
               "each region's piston aligned to it by the mean over its measured pixels.")
    mrows = [("mode", "mode", ""), ("algorithm", "algorithm", ""),
             ("height error rms", "rms_nm", "nm"), ("height error PV", "pv_nm", "nm"),
             ("piston removed", "piston_nm", "nm"),
             ("measured pixels", "valid_fraction", "fraction"),
             ("pixels with fringes above the noise", "light_fraction", "fraction"),
             ("regions", "regions", "")]
    rep.table([[label, _q(c["measured"].get(k), unit), _q(u["measured"].get(k), unit)]
               for label, k, unit in mrows if k in c["measured"] or k in u["measured"]],
              header=["phase retrieval", va, vb])
    icls: Any = type(getattr(scene.render, "interferometer", None))
    ifields = icls.model_fields if hasattr(icls, "model_fields") else {}
    rep.table([[k, value_text(k, v, ifields.get(k)), meaning(k, ifields.get(k), v)]
               for k, v in ic.items()],
              header=["[render.interferometer] as rendered", "value", "meaning"])

    # ---- 5. diffuse light
    dif = _get(metrics, "render_settings.diffuse") or {}
    mic, mac = dif.get("micro") or {}, dif.get("macro") or {}
    rep.section("Diffuse light")
    rep.figure(figs["diffuse_micro_side_by_side"],
               f"Micro view of the common window, straight down (orthographic), aluminium "
               + _micro_light_words(mic)
               + f"; heights exaggerated {_g(mic.get('vertical_exaggeration'))}x "
               f"(written into every image).")
    rep.figure(figs["diffuse_difference"], f"Luminance difference (linear), {va} - {vb}.")
    rep.figure(figs["diffuse_macro_side_by_side"],
               f"The whole part, perspective view, heights exaggerated "
               f"{_g(mac.get('vertical_exaggeration'))}x; the design over the part with "
               f"the simulated residual inside the simulated region. "
               + _macro_light_words(mac))
    drows = []
    for k in ("resolution", "spp", "vertical_exaggeration", "mm_per_px", "light", "lamp",
              "material", "iridescence", "orders", "first_order_efficiency_550nm", "sigma_u",
              "sigma_v", "mitsuba_variant"):
        if k not in mic and k not in mac:
            continue
        drows.append([k, _diffuse_value(k, mic.get(k), mic), _diffuse_value(k, mac.get(k), mac)])
    rep.table(drows, header=["[render.diffuse] as rendered", "micro", "macro"])

    # ---- 6. sections and machine axes
    turning = bool(tp_c.get("revolutions"))
    rep.section("Radial sections" if turning else "Sections")
    rep.figure(figs["sections"],
               ("Radial sections through the spindle axis at several angles (after Li et al. "
                "2018, Fig. 16 b, c): design (dashed) and machined heights, machined - design, and the "
                "waviness. Without compensation the overcut waviness changes with the section "
                "angle.") if turning else
               ("Sections through the centre of the simulated region at several angles: design "
                "(dashed) and machined heights, machined - design, and the waviness."))
    if "kinematics" in figs:
        rep.section("Machine axes")
        rep.figure(figs["kinematics"],
                   "Position, velocity and acceleration of the axes that move (an axis at "
                   "constant speed, such as X of a constant-feed spiral, is named but not "
                   "plotted: its acceleration would be rounding noise).")

    # ---- a program read from a file: its findings and checks
    program_section(rep, metrics, (va, vb), figs)

    # ---- 7. process facts
    facts = _process_facts(c, u)
    if facts:
        rep.section("Process")
        rep.table(facts, header=["fact", va, vb])

    lens = metrics.get("lenslets")
    if lens:
        rep.section("Lenslets")
        cols = ["row", "col", "x_mm", "y_mm", "dx_um", "dy_um", "Sa_um", "Sq_um", "PV_um"]
        units = ["", "", "mm", "mm", "um", "um", "um", "um", "um"]
        head = ["row", "col", "x (mm)", "y (mm)", "dx (um)", "dy (um)", "Sa (um)", "Sq (um)",
                "PV (um)"]
        for name, tab in ((va, lens), (vb, u.get("lenslets") or [])):
            if not tab:
                continue
            rep.heading(name)
            rep.table([[str(e.get("row"))] + [fmt_number(e.get(k), resolution=_res(un))
                                              for k, un in zip(cols[1:], units[1:])]
                       for e in tab], header=head)

    if mf:
        _measured_section(rep, mf)

    # ---- 8. parameters and provenance
    rep.section("Parameters")
    _parameters(rep, scene, metrics)

    seeds = (((d.get("window") or {}).get("measured") or {}).get("noise") or {}).get("seeds") or {}
    prov: list[list[object]] = [["Mitsuba variant", _variants_text(metrics)]]
    prov += [[f"camera noise seed, {k}", str(s)] for k, s in seeds.items()]
    prov.append(["compare total", _q(_get(metrics, "timing_s.total"), "s")])
    for name, v in ((va, c), (vb, u)):
        for k, t in (v.get("timing_s") or {}).items():
            prov.append([f"{name} {k}", _q(t, "s")])
    provenance_section(rep, {**metrics, "software_version": metrics.get("software_version",
                                                                         __version__)},
                       title="Scene and provenance", extra=prov)
    rep.text("The scene as run (its keys after --set, presets named), from which the run "
             "repeats with the same seed:")
    rep.pre(json.dumps(scene.to_dict(), indent=2, sort_keys=True))
    return rep.render()


def _parameters(rep: HtmlReport, scene: ReportedScene, metrics: dict) -> None:
    """The scene's sections, each key with its value and unit (or why it has none), the
    keys the comparison varies per variant; the machine and the material as simulated."""
    sd = scene.to_dict()
    a = metrics["variants"][0]["name"]
    used = metrics.get(a) or {}
    keys = sorted({k for v in metrics["variants"] for k in v.get("values", {})})
    varied = {k: tuple((k in v.get("values", {}), v.get("values", {}).get(k))
                       for v in metrics["variants"]) for k in keys}
    rep.text("Every key of the scene with its value and unit; a key without a value says why "
             "(left to its preset, chosen automatically, or not used). Keys the comparison "
             "varies show both variants (a, b).")
    for sec in SECTION_ORDER:
        if sec not in sd or not isinstance(sd[sec], dict):
            continue
        if sec in ("machine", "material", "rcse") and sec not in used:
            continue  # the process does not use the section
        for title, rows in section_rows(sec, getattr(scene, sec, None), sd[sec], varied=varied):
            rep.table(rows, header=[title, "value", "meaning"])
        if sec == "machine" and (used.get("machine") or {}).get("settings"):
            m = used["machine"]
            rep.table(settings_rows(m["settings"]),
                      header=[f"[machine] as simulated (preset {m.get('preset')!r} with the "
                              f"scene's keys)", "value"])
        if sec == "material" and isinstance(used.get("material"), dict):
            rows = [[k, value_text(k, v)] for k, v in used["material"].items()
                    if not isinstance(v, (dict, list))]
            rep.table(rows, header=["[material] as simulated (the cut's mechanics)", "value"])


def _variants_text(metrics: dict) -> str:
    """The Mitsuba variants the comparison used: the interferometer's, and the diffuse
    views' where theirs differs (the turned-aluminium material renders spectrally)."""
    main = str(metrics.get("mitsuba_variant"))
    diffuse = ((metrics.get("render_settings") or {}).get("diffuse") or {}).values()
    others = sorted({str(d.get("mitsuba_variant")) for d in diffuse
                     if d.get("mitsuba_variant") and d.get("mitsuba_variant") != main})
    return main if not others else f"{main} (interferometer), {', '.join(others)} (diffuse views)"
