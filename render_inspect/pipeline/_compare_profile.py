"""``compare --measured PROFILE``: a measured profile against the same line of the
simulated part, seen through the virtual interference microscope.

Chain: the profile is read (:func:`~render_inspect.io.read_profile`); the line is
``--line X0,Y0,X1,Y1`` (mm, on the part) or, for a turned part, a diameter along x through
the spindle axis placed so that the measured profile's mirror centre falls on the axis;
the scene is simulated over a thin band about the line and the band imaged by the scene's
interferometer (``render.interferometer``, its field of view the band); the true profile
(the simulated cut) and the simulated measurement are sampled along the line at the
measured spacing; the measured profile is registered along the line to the simulated
measurement (to the cut as the instrument sees it where the simulated measurement does
not follow the cut; the shift with the largest correlation, weighted by the overlap's share of the
longest overlap possible, searched within one feed period of the mirror centres' match when both profiles have one, over the whole line otherwise);
the three get the same form removal (a parabola, the sag of the design over the line)
and the same ISO 16610-21 filters (ISO 21920-3's choice for the measured profile, or
``--filter``), and their ISO 21920-2 parameters and periods are set side by side.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import logging
import math
import time
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.units import MM_TO_NM, MM_TO_UM
from ..instruments import microscope_from_config, render_interferogram
from ..io import (MeasuredProfile, atomic_output_dir, atomic_write_bytes, atomic_write_text,
                  check_output_dir, is_profile_file, json_safe, read_profile)
from ..metrology import (analyze_profile, dominant_periods, line_profile, measure_frames, mirror_centre,
                         parse_profile_filter)
from ..processes import cut_name, process_of
from ..report import (HtmlReport, profile_figure, profile_overlay_figure, provenance_section,
                      warnings_section)
from ..scene import scene_from_dict
from ._compare import run_compare
from ._compare_profile_checks import (NULL_SURROGATES, _fmt, _measurement_check,
                                      _measurement_warning, _register, _registration_warning,
                                      cut_as_seen)
from ._metrics import write_metrics
from ._provenance import keeps_warnings, run_inputs, said_warnings
from ._simulate import simulate

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["run_compare_profile", "run_compare_command", "parse_line", "default_line",
           "registration_period", "axis_on_line"]

log = logging.getLogger("render_inspect")

#: half-width of the band simulated and imaged about the line, mm
BAND_HALF_MM = 0.012
#: the simulated region reaches this far beyond the imaged band, mm
REGION_MARGIN_MM = 0.02

_NAMES = (("measured", "measured profile"),
          ("simulated_measured", "simulated, through the virtual interferometer"),
          ("true", "simulated cut (truth)"))


def parse_line(text: str) -> tuple[tuple[float, float], tuple[float, float]]:
    """``"X0,Y0,X1,Y1"`` (mm) -> ((x0, y0), (x1, y1))."""
    parts = str(text).split(",") if not isinstance(text, (list, tuple)) else list(text)
    try:
        v = [float(p) for p in parts]
    except ValueError:
        v = []
    if len(v) != 4 or not all(math.isfinite(a) for a in v):
        raise InputError(f"--line must be X0,Y0,X1,Y1: four numbers in mm, received {text!r}")
    if math.hypot(v[2] - v[0], v[3] - v[1]) <= 0:
        raise InputError(f"--line must have two different end points, received {text!r}")
    return (v[0], v[1]), (v[2], v[3])


def default_line(scene: Scene, profile: MeasuredProfile
                 ) -> tuple[tuple[float, float], tuple[float, float], str] | None:
    """A diameter along x through the spindle axis, as long as the measured profile, with
    the profile's mirror centre (when it has one) on the axis; None for a scene without a
    spindle axis.  Returns (p0, p1, how)."""
    process = process_of(scene)
    axis = process.traits(process.inputs_of(scene)).axis
    if axis is None:
        return None
    mc = mirror_centre(profile.z, spacing=profile.spacing, x0=float(profile.x[0]))
    length = profile.length
    if mc["centre_mm"] is not None and mc["symmetry"] >= 0.5:
        before = mc["centre_mm"] - float(profile.x[0])
        how = (f"a diameter along x through the spindle axis ({axis[0]:g}, {axis[1]:g}) mm, "
               f"the measured profile's mirror centre ({mc['centre_mm']:.4g} mm) on the axis")
    else:
        before = 0.0
        how = f"a radius along +x from the spindle axis ({axis[0]:g}, {axis[1]:g}) mm"
    p0 = (axis[0] - before, axis[1])
    return p0, (p0[0] + length, axis[1]), how


def _band_scene(scene: Scene, p0, p1):
    d = scene.model_dump(mode="json")
    x0, x1 = sorted((p0[0], p1[0]))
    y0, y1 = sorted((p0[1], p1[1]))
    h = BAND_HALF_MM
    fov = [x0 - h, y0 - h, x1 + h, y1 + h]
    m = REGION_MARGIN_MM
    d["simulation"]["region"] = [fov[0] - m, fov[1] - m, fov[2] + m, fov[3] + m]
    d["render"]["interferometer"]["field_of_view"] = fov
    return scene_from_dict(d, f"{scene.name} (band about the line)"), fov


def registration_period(scene: Scene, z_meas: np.ndarray, *, spacing: float) -> float | None:
    """The period (mm) that bounds the registration's search around the mirror centres'
    match: the measured profile's own dominant period (the marks it shows repeat at it,
    whatever fed them: a program read from a file may vary its feed with the radius), or,
    where the profile shows none, the scene's planned feed marks.  None when neither is
    known."""
    own = dominant_periods(z_meas, spacing=spacing)["period_mm"]
    if own:
        return float(own)
    process = process_of(scene)
    marks = process.traits(process.inputs_of(scene)).marks
    return float(marks.period_mm) if marks is not None and marks.period_mm else None


def axis_on_line(scene: Scene, p0: Sequence[float], p1: Sequence[float], *,
                 tolerance: float) -> float | None:
    """Where the spindle axis lies along the line p0 -> p1 (mm from p0), when the line
    passes within ``tolerance`` mm of it; None otherwise (or without a spindle axis)."""
    process = process_of(scene)
    axis = process.traits(process.inputs_of(scene)).axis
    if axis is None:
        return None
    dx, dy = p1[0] - p0[0], p1[1] - p0[1]
    length = math.hypot(dx, dy)
    ax, ay = axis[0] - p0[0], axis[1] - p0[1]
    along = (ax * dx + ay * dy) / length
    off = abs(ax * dy - ay * dx) / length
    if off > tolerance or not 0.0 <= along <= length:
        return None
    return float(along)


@keeps_warnings
def run_compare_profile(scene: Scene, out: str | Path, *, measured: str | Path,
                        line: str | None = None, units: str | None = None,
                        filter_spec: str | tuple | None = None,
                        overwrite: bool = False, scene_file: str | Path | None = None) -> dict:
    """Compare a measured profile with the same line of the simulated part.

    Parameters
    ----------
    scene : Scene
        The validated scene (its interferometer is the virtual instrument).
    out : str or Path
        Output folder (``metrics.json``, ``overlay.png``, ``measured_profile.png``,
        ``report.html``), written atomically.
    measured : str or Path
        A profile :func:`~render_inspect.io.read_profile` reads.
    line : "X0,Y0,X1,Y1", optional
        The line on the part (mm); default for a turned part: :func:`default_line`.
    units, filter_spec : optional
        As for ``analyze`` of a profile.
    scene_file : str or Path, optional
        The scene file the scene was read from, recorded with its SHA-256 in ``inputs``.

    Returns
    -------
    dict
        The content of ``metrics.json``: ``kind`` = "profile", ``line_mm``, ``line_from``,
        ``registration`` (``shift_mm``, ``correlation``, ``how``, ``null_correlation``,
        ``reliable``, ``against``: "virtual_measurement", or "cut_as_seen" when the virtual
        measurement failed), ``virtual_measurement`` (the check), ``filter``,
        ``profiles`` (``measured``, ``simulated_measured``, ``true``: each the ISO 21920-2
        parameters and periods of :func:`~render_inspect.metrology.analyze_profile`),
        ``input``, ``inputs`` (the files read, with their SHA-256), ``scene``, ``seed``,
        ``software_version``, ``warnings`` (every warning said while it ran), ``timing_s``.
    """
    t0 = time.perf_counter()
    check_output_dir(out, overwrite=overwrite, command="compare", scene=scene,
                     inputs=(measured,))
    s_mm, l_mm = parse_profile_filter(filter_spec)
    prof = read_profile(measured, units=units)
    if line is not None:
        p0, p1 = parse_line(line)
        how_line = "--line"
    else:
        d = default_line(scene, prof)
        if d is None:
            raise InputError(f"--line X0,Y0,X1,Y1 (mm) is needed: scene {scene.name!r} has no "
                             f"spindle axis to draw the default radial line through")
        p0, p1, how_line = d
    band, fov = _band_scene(scene, p0, p1)
    seed = int(scene.simulation.seed)
    log.info("compare %s with %s along (%g, %g) -> (%g, %g) mm", cut_name(scene), Path(measured).name,
             *p0, *p1)
    sim = simulate(band)
    hm = sim.heightmap
    ig = render_interferogram(hm, band.render.interferometer, seed=seed)
    r = measure_frames(ig.recorded())
    h_meas = np.where(r.valid, r.height, np.nan)
    step = prof.spacing
    s_true, z_true = line_profile(hm.machined, pixel=hm.pixel, origin=hm.origin, p0=p0, p1=p1,
                                  step=step)
    s_sim, z_sim = line_profile(h_meas, pixel=ig.pixel, origin=ig.origin, p0=p0, p1=p1, step=step)
    if np.isfinite(z_sim).sum() < 16:
        raise InputError(f"the virtual instrument measured {int(np.isfinite(z_sim).sum())} points "
                         f"along the line; check --line against the part (simulated region "
                         f"{list(band.simulation.region)} mm)")
    # the simulated profiles are resampled to exactly the measured spacing
    s_pos = prof.x - prof.x[0]
    period = registration_period(scene, prof.z, spacing=step)
    axis_s = axis_on_line(scene, p0, p1, tolerance=(period or step) / 2)
    # the cut as the instrument sees it: through the objective's lateral response, at the
    # camera's pixels, sampled along the line as the measurement is
    seen = cut_as_seen(hm.machined, pixel=hm.pixel, origin=hm.origin,
                       microscope=microscope_from_config(band.render.interferometer),
                       camera_pixel=float(ig.pixel), camera_origin=ig.origin,
                       camera_shape=(h_meas.shape[0], h_meas.shape[1]))
    _, z_seen = line_profile(seen, pixel=ig.pixel, origin=ig.origin, p0=p0, p1=p1, step=step)
    opts: dict[str, Any] = {"form": "poly2", "lambda_s": s_mm, "lambda_c": l_mm}
    res = {}
    noise_line = None
    if r.height_noise is not None:
        _, noise_line = line_profile(np.where(r.valid, r.height_noise, np.nan), pixel=ig.pixel,
                                     origin=ig.origin, p0=p0, p1=p1, step=step)
    check = _measurement_check(z_sim, z_seen, noise_line, lambda_eff_nm=float(ig.lambda_eff_nm),
                               mode=band.render.interferometer.mode, rt_sim=None, rt_true=None)
    # a measurement that does not follow the cut would align the measured profile to its
    # failures: the cut as the instrument sees it is registered against instead
    failed = check["status"] == "failed"
    against = "cut_as_seen" if failed else "virtual_measurement"
    shift, corr, how_reg, null = _register(s_pos, prof.z, s_sim, z_seen if failed else z_sim,
                                           spacing=step, period=period, axis_s=axis_s, seed=seed)
    s_reg = s_pos + shift
    res["measured"] = analyze_profile(s_reg, prof.z, spacing=step, **opts)
    fil = res["measured"]["metrics"]["filter"]
    same = {"form": "poly2", "lambda_s": fil["lambda_s_mm"] or 0.0, "lambda_c": fil["lambda_c_mm"]}
    res["simulated_measured"] = analyze_profile(s_sim, z_sim, spacing=step, **same)
    res["true"] = analyze_profile(s_true, z_true, spacing=step, **same)
    check["Rt_nm"] = res["simulated_measured"]["metrics"]["profile"].get("Rt_nm")
    check["Rt_cut_nm"] = res["true"]["metrics"]["profile"].get("Rt_nm")
    reg = {"shift_mm": shift, "correlation": corr, "how": how_reg, "null_correlation": null,
           "beats_chance": null is None or corr > null,
           "reliable": null is None or corr > null,
           "against": against,
           "against_why": ("the virtual measurement failed: it does not follow the cut"
                           if failed else "the virtual measurement follows the cut"),
           "rule": f"reliable when the correlation beats the best of {NULL_SURROGATES} "
                   f"phase-randomised surrogates of the measured profile searched the same "
                   f"way (the 95 % level of an unrelated profile of the same spectrum)"}
    warns = [w for w in (_measurement_warning(check), _registration_warning(reg)) if w]
    for w in warns:
        log.warning("%s", w)
    figs = {
        "overlay": profile_overlay_figure(
            [{"s": res[k]["arrays"]["x"], "z": res[k]["arrays"]["primary"], "label": lab}
             for k, lab in _NAMES],
            title=f"along ({p0[0]:.4g}, {p0[1]:.4g}) -> ({p1[0]:.4g}, {p1[1]:.4g}) mm; measured "
                  f"shifted {shift * MM_TO_UM:+.4g} um (correlation {corr:.3f}"
                  f"{'' if reg['reliable'] else ': not reliable'}); parabola removed"),
        "roughness_overlay": profile_overlay_figure(
            [{"s": res[k]["arrays"]["x"],
              "z": np.where(res[k]["arrays"]["evaluate"], res[k]["arrays"]["roughness"], np.nan),
              "label": lab} for k, lab in _NAMES],
            title=f"roughness profiles (lambda_s {same['lambda_s']:g}, lambda_c "
                  f"{same['lambda_c']:g} mm)"),
        "measured_profile": profile_figure(res["measured"]["arrays"], res["measured"]["metrics"],
                                           title=f"measured: {Path(measured).name}"),
    }
    metrics: dict[str, Any] = {
        "command": "compare", "kind": "profile", "scene": scene.name,
        "run_name": cut_name(scene), "seed": seed,
        "software_version": __version__,
        "line_mm": [list(p0), list(p1)], "line_from": how_line,
        "registration": reg, "virtual_measurement": check, "warnings": warns,
        "filter": {"lambda_s_mm": same["lambda_s"] or None, "lambda_c_mm": same["lambda_c"],
                   "chosen_by": fil["chosen_by"] + " (of the measured profile)", "form": "poly2"},
        "band_mm": {"field_of_view": fov, "simulation_region": list(band.simulation.region)},
        "profiles": {k: {kk: res[k]["metrics"][kk] for kk in
                         ("profile", "periods", "evaluation_length_mm", "n_measured",
                          "n_points", "outliers", "warnings")} for k, _ in _NAMES},
        "input": {"path": str(measured), "reader": prof.meta.get("reader"),
                  "format_name": prof.meta.get("format_name"),
                  "units_in_file": prof.meta.get("units_in_file"),
                  "units_from": prof.meta.get("units_from"),
                  "instrument": prof.meta.get("instrument"),
                  "instrument_fields": prof.meta.get("instrument_fields") or {},
                  "date": prof.meta.get("date"), "n_points": prof.meta["n_points"],
                  "n_measured": prof.n_measured, "spacing_mm": step},
        "instrument": {"objective": band.render.interferometer.objective,
                       "mode": band.render.interferometer.mode, "pixel_mm": float(ig.pixel)},
        "files": {"metrics.json": "these metrics", "overlay.png": "the three profiles overlaid",
                  "roughness_overlay.png": "their roughness profiles overlaid",
                  "measured_profile.png": "the measured profile analysed",
                  "report.html": "the report"},
    }
    metrics["inputs"] = run_inputs(scene.to_dict(), scene_file=scene_file, measured=measured,
                                   seed=seed)
    metrics["warnings"] = said_warnings(
        [f"{lab}: {w}" for k, lab in _NAMES for w in metrics["profiles"][k]["warnings"]])
    with atomic_output_dir(out, overwrite=overwrite, command="compare", scene=scene,
                           inputs=(measured,)) as tmp:
        tmp = Path(tmp)
        for name, png in figs.items():
            atomic_write_bytes(tmp / f"{name}.png", png)
        metrics["timing_s"] = {"total": time.perf_counter() - t0}
        write_metrics(tmp, metrics)
        atomic_write_text(tmp / "report.html", _page(metrics, figs))
    return json_safe(metrics)


_ROWS = (("Ra_nm", "Ra (nm)"), ("Rq_nm", "Rq (nm)"), ("Rp_nm", "Rp (nm)"), ("Rv_nm", "Rv (nm)"),
         ("Rz_nm", "Rz (nm)"), ("Rt_nm", "Rt (nm)"), ("Rsk", "Rsk"), ("Rku", "Rku"),
         ("RSm_mm", "RSm (um)"), ("Rdq", "Rdq"))


def _page(metrics: dict, figs: dict) -> str:
    p = metrics["profiles"]
    f = metrics["filter"]
    rep = HtmlReport(f"{metrics.get('run_name') or metrics['scene']}: measured profile against "
                     f"the simulation",
                     f"{Path(metrics['input']['path']).name} along {metrics['line_from']}; "
                     f"lambda_s {f['lambda_s_mm'] or 0:g} mm, lambda_c {f['lambda_c_mm']:g} mm "
                     f"({f['chosen_by']}); parabola removed from each")
    warnings_section(rep, metrics.get("warnings"))
    failed = (metrics.get("virtual_measurement") or {}).get("status") == "failed"
    reg = metrics["registration"]
    rep.section("Profiles overlaid")
    rep.figure(figs["overlay"], "Measured (black), simulated through the virtual "
               "interferometer (blue) and the simulated cut itself (orange, dashed), registered "
               "along the line; primary profiles (a parabola removed, lambda_s filter only); "
               "heights in nm, positions along the line in mm."
               + (" The virtual measurement FAILED (Warnings): its blue line is not what the "
                  "instrument would report." if failed else "")
               + ("" if reg.get("reliable", True) else " The registration is NOT reliable: "
                  "the profiles are not aligned point for point."))
    rep.figure(figs["roughness_overlay"], "Roughness profiles: the same after the ISO 16610-21 "
               f"Gaussian filters (lambda_s {f['lambda_s_mm'] or 0:g} mm, lambda_c "
               f"{f['lambda_c_mm']:g} mm), over each profile's evaluation length; heights in "
               "nm, positions in mm.")
    rep.section("Parameters side by side (ISO 21920-2)")
    rep.text(f"ISO 21920-2 parameters of each roughness profile (a parabola removed, ISO 16610-21 "
             f"Gaussian lambda_s {f['lambda_s_mm'] or 0:g} mm and lambda_c {f['lambda_c_mm']:g} "
             f"mm, {f['chosen_by']}; Rsk, Rku and Rdq have no unit): the measured profile as "
             f"the real instrument reported it, the simulated cut as the virtual "
             f"interferometer measures it, and the simulated cut itself (the truth).")
    head = ["parameter"] + [lab for _, lab in _NAMES]
    rows = [[lab] + [_fmt(p[k]["profile"].get(key), key) for k, _ in _NAMES]
            for key, lab in _ROWS]
    rows.append(["evaluation length (mm)"] + [_fmt(p[k]["evaluation_length_mm"]) for k, _ in _NAMES])
    rows.append(["measured points"] + [str(p[k]["n_measured"]) for k, _ in _NAMES])
    rows.append(["spikes (kept)"] + [str(p[k]["outliers"]["count"]) for k, _ in _NAMES])
    rep.table(rows, header=head)
    rep.section("Periods")
    prow = []
    for k, lab in _NAMES:
        per = p[k]["periods"]
        dom = per["dominant"]
        ta = per.get("through_axis") or {}
        prow.append([lab, _fmt(dom.get("period_mm") and dom["period_mm"] * MM_TO_UM),
                     ", ".join(str(h["order"]) for h in dom.get("harmonics", [])) or "none",
                     _fmt(ta.get("centre_mm")),
                     _fmt((ta.get("left") or {}).get("period_mm") and
                          ta["left"]["period_mm"] * MM_TO_UM),
                     _fmt((ta.get("right") or {}).get("period_mm") and
                          ta["right"]["period_mm"] * MM_TO_UM)])
    rep.table(prow, header=["profile", "dominant period (um)", "harmonics", "mirror centre (mm)",
                            "period left (um)", "period right (um)"])
    rep.section("Measured profile")
    rep.figure(figs["measured_profile"], "Primary profile and mean line, roughness profile, power "
               "spectrum (feed period and harmonics), material ratio curve.")
    chk = metrics.get("virtual_measurement") or {}
    null = reg.get("null_correlation")
    notes = [f"registration: measured positions shifted by {reg['shift_mm'] * MM_TO_UM:+.4g} um "
             f"along the line against "
             f"{'the cut as the instrument sees it' if reg.get('against') == 'cut_as_seen' else 'the virtual measurement'}"
             f" ({reg.get('against_why', '')}; correlation {reg['correlation']:.3f}, searched "
             f"{reg['how']}); "
             + ("" if null is None else
                f"{'reliable' if reg.get('reliable') else 'NOT reliable'}: an unrelated profile "
                f"of the same spectrum reaches {null:.3f} ({reg.get('rule')})"),
             f"virtual measurement against the cut it measured, as the instrument sees it: "
             f"{'FAILED' if chk.get('status') == 'failed' else chk.get('status', 'n/a')}; rms "
             f"departure {_fmt(chk.get('rms_departure_nm'))} nm, instrument noise "
             f"{_fmt(chk.get('noise_nm'))} nm, {chk.get('departing', 0)} points off by more "
             f"than {_fmt(chk.get('threshold_nm'))} nm ({chk.get('rule', '')})",
             f"virtual instrument: {metrics['instrument']['objective']} "
             f"{metrics['instrument']['mode']}, pixel {metrics['instrument']['pixel_mm'] * MM_TO_UM:.4g} um",
             _measured_note(metrics["input"])]
    for k, lab in _NAMES:
        notes += [f"{lab}: {w}" for w in p[k]["warnings"]]
    rep.section("Notes")
    rep.list(notes)
    provenance_section(rep, metrics, extra=[
        ["virtual instrument", f"{metrics['instrument']['objective']} "
                               f"{metrics['instrument']['mode']}"],
        ["line on the part (mm)", f"({metrics['line_mm'][0][0]:.6g}, {metrics['line_mm'][0][1]:.6g})"
                                  f" -> ({metrics['line_mm'][1][0]:.6g}, "
                                  f"{metrics['line_mm'][1][1]:.6g}), {metrics['line_from']}"]])
    return rep.render()


def run_compare_command(scene: Scene, out: str | Path, *, measured: str | Path | None = None,
                        vary: str | None = None, force: bool = False, line: str | None = None,
                        units: str | None = None, filter_spec: str | tuple | None = None,
                        repeat: int = 1, overwrite: bool = False,
                        scene_file: str | Path | None = None) -> dict:
    """``compare``: :func:`run_compare_profile` when ``measured`` is a profile file,
    :func:`~render_inspect.pipeline.run_compare` otherwise (``line``, ``units`` and
    ``filter_spec`` are then refused, naming the option)."""
    if measured is not None and is_profile_file(measured):
        if vary is not None or force or repeat != 1:
            opt = "--vary" if vary is not None else "--force" if force else "--repeat"
            raise InputError(f"{opt} is for two variants or a measured map; --measured "
                             f"{str(measured)!r} is a profile")
        return run_compare_profile(scene, out, measured=measured, line=line, units=units,
                                   filter_spec=filter_spec, overwrite=overwrite,
                                   scene_file=scene_file)
    for opt, v in (("--line", line), ("--units", units), ("--filter", filter_spec)):
        if v is not None:
            raise InputError(f"{opt} is for --measured PROFILE (a profile file); received "
                             f"{opt} {v} with --measured {measured!r}")
    return run_compare(scene, out, measured=measured, vary=vary, force=force,
                       overwrite=overwrite, repeat=repeat, scene_file=scene_file)


def _measured_note(inp: dict) -> str:
    """The report's note on the measured file: its format, the instrument it names, its
    points, spacing and units."""
    date = f" (acquired {inp['date']})" if inp.get("date") else ""
    return (f"measured file: {inp.get('format_name')}, instrument {inp.get('instrument')}{date}; "
            f"{inp['n_measured']} of {inp['n_points']} points measured, spacing "
            f"{inp['spacing_mm'] * MM_TO_UM:.4g} um, units {_units_text(inp['units_in_file'])} "
            f"({inp['units_from']})")


def _units_text(units: object) -> str:
    """``{"position": "um", "height": "nm"}`` as "position um, height nm" (as given otherwise)."""
    if isinstance(units, dict):
        return ", ".join(f"{k} {v if v else 'not stated'}" for k, v in units.items())
    return str(units)
