"""The figures of ``compare``: the difference of the two variants over the common window
(the first figure), their residual, waviness, interferogram, measured and diffuse-light
panels, the sections and the axis motion; and the caption written into diffuse images."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from ..core.heightmap import HeightMap
from ..core.units import MM_TO_NM, MM_TO_UM
from ._figures import image_panels, map_panels, radial_profile_figure
from ._locator import difference_figure, height_background, locator_figure
from ._format import fmt_number, fmt_quantity, nice_length
from ..core.toolpath import ToolPath

__all__ = ["ComparedVariant", "comparison_figures", "comparison_summary", "diffuse_caption",
           "resolution_text",
           "srgb", "luminance"]


@dataclass
class ComparedVariant:
    """One column of a comparison as the figures show it.

    Attributes
    ----------
    name, label : str
    region : (x0, y0, x1, y1)
        The simulated region, mm.
    heightmap : HeightMap
        The simulated map.
    ig : Interferogram
        The interferometer's frames of it.
    maps : dict
        ``measured_height``, ``measured_residual``, ``error`` on the camera's grid.
    filtered : array
        The waviness map (mm) on the height map's grid.
    diffuse : dict
        View -> (linear RGB image, its meta).
    """

    name: str
    label: str
    region: tuple
    heightmap: HeightMap
    ig: Any
    maps: dict = field(default_factory=dict)
    filtered: np.ndarray | None = None
    diffuse: dict = field(default_factory=dict)


def diffuse_caption(meta: dict) -> list[str]:
    """The lines written into a diffuse image: vertical exaggeration, view and light."""
    ex = float(meta["vertical_exaggeration"])
    first = f"heights x{ex:g} (vertical exaggeration)" if ex != 1 else "heights true scale (x1)"
    light = meta["light"]["type"] + (" + lamp" if meta.get("lamp") else "")
    return [first, f"{meta['view']} view, {light}"]


def comparison_figures(a: ComparedVariant, b: ComparedVariant, meas: dict | None, *,
                       difference: dict,
                       window: dict, part: dict, identical: bool, sections: dict,
                       radial: bool, kinematics: bytes | None,
                       lowpass_mm: float | None = None) -> dict:
    """All top-level PNGs of a comparison (name -> bytes).

    Parameters
    ----------
    a, b : ComparedVariant
        The two columns.
    meas : dict or None
        The measured file's column (``maps``, ``extent``).
    difference : dict
        :func:`render_inspect.metrology.difference_profiles` of the two.
    window : dict
        The common window (``window``, ``peak``).
    part : dict
        The part's outline.
    identical : bool
        The two machined maps are equal (no difference figure, the windows instead).
    sections : dict
        Label -> :func:`render_inspect.metrology.sections` of that map.
    radial : bool
        The sections are radial about a spindle axis.
    kinematics : bytes or None
        The axis-motion figure.
    lowpass_mm : float, optional
        The first figure's maps are drawn low-passed at this nesting index (tool marks the
        simulation does not resolve).
    """
    figs = {}
    hm = a.heightmap
    ig = a.ig
    names = (a.name, b.name)
    labels = (a.label, b.label)
    d = difference
    true_full = (a.heightmap.machined - b.heightmap.machined) * MM_TO_NM
    # the two measurements' difference as instrument software forms it (piston and tilt
    # removed; the truth is drawn beside it, labelled as truth)
    meas_diff = d["measured_levelled"]
    lev = d.get("levelling") or {}
    ig_ext = ig.extent
    line = d["line"]
    along_x = d["along_x"]
    px, py = d["peak"]
    x0, y0 = d["metrics"]["window"]["window_mm"][:2]
    locator = _locator(a, part, window, ig)
    if not identical:
        figs["difference"] = difference_figure(
            names=names, locator=locator, true_diff=d["true_window"], true_extent=d["true_extent"],
            measured_diff=meas_diff, measured_extent=ig_ext,
            profile={"s": d["s"] + (x0 if along_x else y0), "true": d["true"], "a": d["a"],
                     "b": d["b"], "s_measured": d["s_measured"] + (x0 if along_x else y0),
                     "measured": d["measured"], "line": line,
                     "true_levelled": d.get("true_levelled"),
                     "measured_label": f"measured, {_removed(lev)} removed",
                     "axis": f"x (mm) at y = {py:.4g} mm" if along_x
                     else f"y (mm) at x = {px:.4g} mm",
                     "title": "profile across the largest difference"},
            panel_labels=("truth (the simulation)",
                          f"measured, {_removed(lev)} removed"),
            title=f"{labels[0]} ({names[0]}) - {labels[1]} ({names[1]}): measured with "
                  f"{_removed(lev)} removed (two set-ups differ by both), beside the truth"
                  + _reorder_note(lev), lowpass_mm=lowpass_mm)
    else:
        figs["windows"] = locator_figure(locator)
    # --- residual maps (full simulated region), one scale
    res_panels = [(f"{n}: machined - design", v.heightmap.residual * MM_TO_NM)
                  for n, v in zip(names, (a, b))]
    exts = [hm.extent, hm.extent]
    if meas is not None:
        res_panels.append(("measured file - design (registered)",
                           meas["maps"]["residual"] * MM_TO_NM))
        exts.append(meas["extent"])
    figs["residual_side_by_side"] = map_panels(res_panels, extent=exts, label="residual (nm)",
                                                 cmap="RdBu_r", symmetric=True)
    figs["residual_difference"] = map_panels(
        [(f"machined: {names[0]} - {names[1]}", true_full)], extent=hm.extent,
        label="height difference (nm)", cmap="RdBu_r", symmetric=True,
        lines=[(line[0], line[1])])
    # --- waviness (filtered) maps, one scale, and their difference
    fa, fb = cast(np.ndarray, a.filtered) * MM_TO_NM, cast(np.ndarray, b.filtered) * MM_TO_NM
    figs["filtered_side_by_side"] = map_panels(
        [(f"{names[0]}: waviness", fa), (f"{names[1]}: waviness", fb),
         (f"{names[0]} - {names[1]}", fa - fb)],
        extent=hm.extent, label="filtered height (nm)", cmap="RdBu_r", symmetric=True)
    # --- interferometer
    figs["interferogram_side_by_side"] = image_panels(
        [(f"{n}: intensity (zero-shift frame)", v.ig.intensity) for n, v in zip(names, (a, b))],
        extent=ig_ext, gray_label="intensity (0..1)",
        suptitle=f"Interferograms ({ig.mode.upper()}, {ig.objective}, NA "
                 f"{ig.numerical_aperture:g}, {ig.wavelength_nm:g} nm, "
                 f"{ig.pixel * MM_TO_UM:.3g} um pixels)")
    figs["interferogram_difference"] = map_panels(
        [(f"{names[0]} - {names[1]}", a.ig.intensity.astype(float) - b.ig.intensity)],
        extent=ig_ext, label="intensity difference", cmap="RdBu_r", symmetric=True)
    figs["measured_residual_side_by_side"] = map_panels(
        [(f"{n}: measured - design, {_removed(v.maps.get('measured_residual_levelling'))} "
          f"removed{_reorder_note(v.maps.get('measured_residual_levelling'))}",
          v.maps["measured_residual"] * MM_TO_NM) for n, v in zip(names, (a, b))],
        extent=ig_ext, label="residual seen by the instrument (nm)", cmap="RdBu_r",
        symmetric=True)
    figs["measurement_error_side_by_side"] = map_panels(
        [(f"{n}: measured - true (truth: the simulation)", v.maps["error"])
         for n, v in zip(names, (a, b))],
        extent=ig_ext, label="height error (nm)", cmap="RdBu_r", symmetric=True)
    # --- diffuse light
    (rc, mc), (ru, _) = a.diffuse["micro"], b.diffuse["micro"]
    x0m, y0m, x1m, y1m = mc["window_mm"]
    ext = (x0m, x1m, y0m, y1m)
    figs["diffuse_micro_side_by_side"] = image_panels(
        [(f"{n}: diffuse micro view", srgb(r)[::-1]) for n, r in zip(names, (rc, ru))],
        extent=ext, notes=[", ".join(diffuse_caption(mc))] * 2,
        suptitle=f"Diffuse light ({mc['light']['type']}), straight down, heights exaggerated "
                 f"{mc['vertical_exaggeration']:g}x")
    figs["diffuse_difference"] = map_panels(
        [(f"{names[0]} - {names[1]} (luminance)", (luminance(rc) - luminance(ru))[::-1])],
        extent=ext, label="linear luminance difference", cmap="RdBu_r", symmetric=True)
    (rm, mm_), (rmb, _) = a.diffuse["macro"], b.diffuse["macro"]
    sc = mm_["scale"]["mm_per_px_at_target"]
    bar = nice_length(0.2 * rm.shape[1] * sc)
    figs["diffuse_macro_side_by_side"] = image_panels(
        [(f"{n}: the whole part", srgb(r)) for n, r in zip(names, (rm, rmb))],
        extent=[(0, r.shape[1], 0, r.shape[0]) for r in (rm, rmb)], axis_labels=False,
        scale_mm=(bar, bar / sc), notes=[", ".join(diffuse_caption(mm_))] * 2,
        suptitle=("The part in the photo studio" if mm_["light"]["type"] == "studio"
                  else f"The part under the {mm_['light']['type']}")
                 + (" and a lamp" if mm_.get("lamp") else "")
                 + f", heights exaggerated {mm_['vertical_exaggeration']:g}x"
                 + (" (colours: diffraction by the feed marks)"
                    if mm_["material"].get("grating") else ""))
    # --- sections
    figs["sections"] = radial_profile_figure(sections, radial=radial)
    # --- machine axes
    if kinematics is not None:
        figs["kinematics"] = kinematics
    return figs


def _removed(levelling) -> str:
    """What a levelling removed, in words ("piston and tilt")."""
    return (levelling or {}).get("removed") or "piston and tilt"


def _reorder_note(levelling) -> str:
    """The fringe orders a PSI levelling assigned to the regions apart from the largest
    (PSI cannot tell orders apart across gaps), as a second title line."""
    lev = levelling or {}
    moved = lev.get("reordered") or []
    order = lev.get("fringe_order_nm")
    if not moved or order is None:
        return ""
    n = len(moved)
    return f";\n{n} region{'s' if n > 1 else ''} moved by whole fringe orders ({order:.0f} nm)"


def _locator(a: ComparedVariant, part: dict, window: dict, ig) -> dict:
    hm = a.heightmap
    r = [float(v) for v in a.region]
    x0, x1, y0, y1 = hm.extent
    windows = [("simulated region = macro residual patch", (x0, y0, x1, y1), "0.2", "-"),
               ("interferometer field = common window", tuple(ig.meta.get("window_mm",
                                                                          window["window"])),
                "C3", "-"),
               ("diffuse micro view", tuple(a.diffuse["micro"][1]["window_mm"]), "C0", "--")]
    pad = 0.04 * max(x1 - x0, y1 - y0)
    loc = {"part": part if part.get("shape") == "rect" else {}, "windows": windows,
           "limits": (x0 - pad, x1 + pad, y0 - pad, y1 + pad),
           **height_background(a.heightmap.design, hm.extent, "design height")}
    if part.get("shape") == "disc":
        R = part["radius"]
        loc["inset"] = {"part": part, "windows": [("region", tuple(r), "C3", "-")],
                        "limits": (-1.05 * R, 1.05 * R, -1.05 * R, 1.05 * R)}
    return loc


def srgb(rgb: np.ndarray) -> np.ndarray:
    """Linear RGB -> sRGB (0..1)."""
    a = np.clip(np.nan_to_num(rgb), 0.0, 1.0)
    return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)


def luminance(rgb: np.ndarray) -> np.ndarray:
    """Linear luminance (Rec. 709 weights) of linear RGB."""
    return rgb[..., 0] * 0.2126 + rgb[..., 1] * 0.7152 + rgb[..., 2] * 0.0722


def comparison_summary(metrics: dict) -> tuple[list, list]:
    """The headline numbers of a comparison for a one-screen summary: rows
    (quantity, variant a, variant b) and lines (quantity, text) about the difference."""
    va, vb = (v["name"] for v in metrics["variants"])
    a, b = metrics[va], metrics[vb]
    d = metrics["difference"]
    w = d.get("window", {})
    vrows = _variant_rows(metrics["variants"], (a["variant"]["label"], b["variant"]["label"]))
    shown = {x for r in vrows for x in r[1:]}
    rows = vrows + [
            ("residual Sq", fmt_quantity(a["residual"]["Sq_nm"], "nm"),
             fmt_quantity(b["residual"]["Sq_nm"], "nm")),
            ("residual min (< 0: overcut)", fmt_quantity(a["residual"]["min_nm"], "nm"),
             fmt_quantity(b["residual"]["min_nm"], "nm")),
            ("waviness Sq (filtered)", fmt_quantity(a["filtered"].get("Sq_nm"), "nm"),
             fmt_quantity(b["filtered"].get("Sq_nm"), "nm")),
            ("measured - true rms (truth)", fmt_quantity(a["measured"].get("rms_nm"), "nm"),
             fmt_quantity(b["measured"].get("rms_nm"), "nm"))]
    if "program" in a or "program" in b:  # a program read from a file: its findings
        def finding(m):
            prog = m.get("program")
            if prog is None:
                return "(planned)"
            n = f"{prog.get('findings_count', 0):,} points"
            # a file the variants' rows above name already is not repeated
            return n if prog.get("file", "") in shown else f"{n} ({prog.get('file', '')})"
        rows.append(("program findings (below the design, rapids in the part)",
                     finding(a), finding(b)))
    meas = w.get("measured") or {}
    same = w.get("true_same_form_removed") or {}
    removed = meas.get("form_removed", "piston and tilt")
    lines = [(f"{va} - {vb}, simulated region (truth)",
              f"rms {fmt_quantity(d.get('machined_rms_nm'), 'nm')}, "
              f"PV {fmt_quantity(d.get('machined_pv_nm'), 'nm')}"),
             (f"{va} - {vb}, common window",
              f"{_measured_text(meas)} ({removed} removed: the "
              f"measurements alone); truth: rms {fmt_quantity((w.get('true') or {}).get('rms_nm'), 'nm')}, "
              f"{fmt_quantity(same.get('rms_nm'), 'nm')} with the same {removed} removed")]
    verdict = resolution_text(meas)
    if verdict:
        lines.append((f"{va} - {vb}, resolved?", verdict))
    rep = meas.get("repeat")
    if rep:
        lines.append((f"{va} - {vb}, {rep['repeats']} repeats",
                      f"rms {fmt_quantity(rep.get('rms_mean_nm'), 'nm')} +- "
                      f"{fmt_quantity(rep.get('rms_std_nm'), 'nm')} (1 s.d.); per-pixel "
                      f"repeatability {fmt_quantity(rep.get('pixel_repeatability_nm'), 'nm')}; "
                      f"mean of the repeats {fmt_quantity(rep.get('mean_map_rms_nm'), 'nm')} rms "
                      f"against its noise {fmt_quantity(rep.get('mean_map_floor_nm'), 'nm')}: "
                      f"{(rep.get('mean_map') or {}).get('verdict', 'unknown')}"))
    mf = metrics.get("measured_file")
    if mf and mf.get("registration"):  # the measured map: its registration against chance
        reg = mf["registration"]
        ch = reg.get("chance") or {}
        best = reg.get("null_score")
        lines.append(("measured file, registration",
                      f"shifted ({fmt_number((reg.get('tx_mm') or 0) * MM_TO_UM)}, "
                      f"{fmt_number((reg.get('ty_mm') or 0) * MM_TO_UM)}) um; explains "
                      f"{fmt_number(reg.get('score'), resolution=1e-3)} of the map's variance "
                      f"against {'n/a' if best is None else fmt_number(best, resolution=1e-3)} "
                      f"for the best of {ch.get('surrogates', '?')} surrogates (seed "
                      f"{ch.get('seed', '?')}): "
                      + ("reliable" if reg.get("reliable") else
                         "NOT RELIABLE, its differences are not reliable")))
    edge = metrics.get("tool_edge")
    if edge:  # a measured cutting edge: what it leaves on each cut, and what it is
        per = edge["variants"]

        def form(name):
            e = per.get(name)
            return fmt_quantity(e.get("form_error_rms_nm"), "nm") if e else "(circular nose)"
        rows.append(("form error rms (measured edge)", form(va), form(vb)))
        rng = edge.get("measured_range_deg")
        imprint = next((e.get("imprint_predicted_rms_nm") for e in per.values() if e), None)
        said = sum(len((e or {}).get("warnings") or []) for e in per.values())
        lines.append(("measured cutting edge",
                      f"{edge.get('source') or 'differs between the variants'}"
                      + (f", measured {rng[0]:.4g} .. {rng[1]:.4g} deg" if rng else "")
                      + f"; imprint predicted on a path planned for the circular nose "
                        f"{fmt_quantity(imprint, 'nm')} rms"
                      + (f"; {said} warning(s) in metrics.json tool_edge" if said else "")))
    src = (metrics.get("measured_file") or {}).get("source") or {}
    if src:  # the measured file: what it is and what its header names
        lines.append(("measured file", _measured_file_text(src)))
    return rows, lines


def _measured_file_text(src: dict) -> str:
    """A measured file in one line: its format, the reader, the units it declares and the
    instrument its header names (``read_surface``'s description of it)."""
    units = src.get("units_in_file") or {}
    return (f"{src.get('format_name') or src.get('format') or '?'}, read by "
            f"{src.get('reader') or '?'}"
            + (f"; in the file: lateral {units.get('lateral')}, heights {units.get('vertical')}"
               if units else "")
            + f"; instrument: {src.get('instrument') or 'not stated in the file'}"
            + (f", acquired {src['date']}" if src.get("date") else ""))


def _short_value(v: object) -> str:
    """A varied value as the summary shows it: a file by its name (the folder both share
    says nothing about what differs)."""
    text = str(v)
    if isinstance(v, str) and ("/" in text or "\\" in text):
        return text.replace("\\", "/").rstrip("/").rsplit("/", 1)[-1]
    return text


def _variant_rows(variants: list, labels: tuple[str, str] | None = None
                  ) -> list[tuple[str, str, str]]:
    """The rows that say what differs between the two variants: one per varied key with
    its two values (files by their names), or the variants' ``labels`` (default: their
    own) for a process's own pair."""
    va, vb = variants[0].get("values") or {}, variants[1].get("values") or {}
    keys = [k for k in va if k in vb and va[k] != vb[k]]
    if not keys:
        la, lb = labels or (variants[0].get("label", ""), variants[1].get("label", ""))
        return [("variant", la, lb)]
    return [(k, _short_value(va[k]), _short_value(vb[k])) for k in keys]


def _measured_text(meas: dict) -> str:
    """The measured difference's rms, or why there is none (a failed measurement)."""
    if meas.get("status") == "failed":
        return "measured: FAILED (fringe-order failure, no measured difference)"
    return f"measured rms {fmt_quantity(meas.get('rms_nm'), 'nm')}"


def resolution_text(meas: dict) -> str | None:
    """One sentence: is the measured difference resolved above the two measurements'
    noise, failed, or of unknown noise (None for metrics without the verdict)."""
    res = meas.get("resolution")
    if not res:
        return None
    order = meas.get("fringe_order") or {}
    if meas.get("status") == "failed":
        why = "; ".join(order.get("reasons") or []) or "fringe-order failure"
        return (f"failed: {why} ({100 * order.get('unknown_fraction', 0):.3g} % of the pixels of "
                f"unknown fringe order); not a measured difference")
    floor = (meas.get("noise") or {}).get("floor_nm")
    masked = ""
    if meas.get("status") == "masked":
        n = int(round(order.get("unknown_fraction", 0) * order.get("pixels", 0)))
        masked = f"; {n} pixels of unknown fringe order masked"
    if res.get("resolved") is None:
        return f"unknown: the measurements give no noise estimate{masked}"
    word = "resolved" if res["resolved"] else "not resolved"
    return (f"{word}: {fmt_quantity(meas.get('rms_nm'), 'nm')} rms against a noise floor of "
            f"{fmt_quantity(floor, 'nm')} (the two measurements' own noise; "
            f"{fmt_quantity(res.get('above_noise_nm'), 'nm')} above it; {res['rule']}){masked}")
