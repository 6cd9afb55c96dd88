"""``compare --measured PROFILE``: a measured profile against the same line of the
simulated part, seen through the virtual interference microscope.

Chain: the profile is read (:func:`~render_inspect.io.read_profile`); the line is
``--line X0,Y0,X1,Y1`` (mm, on the part) or, for a turned part, a diameter along x through
the spindle axis placed so that the measured profile's mirror centre falls on the axis;
the scene is simulated over a thin band about the line and the band imaged by the scene's
interferometer (``render.interferometer``, its field of view the band); the true profile
(the simulated cut) and the simulated measurement are sampled along the line at the
measured spacing; the measured profile is registered along the line to the simulated
measurement (the shift with the largest correlation, weighted by the overlap's share of the
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
from ..instruments import render_interferogram
from ..io import (MeasuredProfile, atomic_output_dir, atomic_write_bytes, atomic_write_text,
                  check_output_dir, is_profile_file, json_safe, read_profile)
from ..metrology import (analyze_profile, dominant_periods, line_profile, measure_frames, mirror_centre,
                         parse_profile_filter)
from ..processes import process_of
from ..report import HtmlReport, profile_figure, profile_overlay_figure
from ..scene import scene_from_dict
from ._compare import run_compare
from ._metrics import write_metrics
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


def _filled(z):
    ok = np.isfinite(z)
    i = np.arange(z.size)
    f = np.interp(i, i[ok], z[ok])
    c = np.polyfit(i - i.mean(), f, 2)
    return f - np.polyval(c, i - i.mean())


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


#: phase-randomised surrogates of the measured profile the registration's correlation is
#: set against (19: the best of them is the 95 % level of an unrelated profile)
NULL_SURROGATES = 19
#: a point of the virtual measurement departs from the cut it measured when it is off by
#: more than this many of the instrument's own noise (one standard deviation; a Gaussian
#: excursion this large has a chance of 6e-7 per point)
DEPARTURE_NOISE_FACTOR = 5.0
#: ... and by more than this fraction of the effective wavelength: half a fringe order
#: (a lost fringe order puts a point off by lambda_eff / 2, a whole order)
DEPARTURE_WAVELENGTH_FRACTION = 0.25
#: the virtual measurement failed when this many neighbouring points depart together (a lost
#: fringe order moves a connected run of the profile; a point or two at the edge of a
#: dropout, or at a steep edge the objective blurs, do not), or ...
DEPARTURE_MIN_RUN = 3
#: ... when at least this share of the points depart, run or not
DEPARTURE_MIN_FRACTION = 0.01


def _register(s_meas, z_meas, s_sim, z_sim, *, spacing, period, axis_s=None, seed=0):
    """The shift (mm) to add to the measured positions so that they best match the
    simulated measurement, the correlation there and how the search was bounded.

    Feed marks repeat every period, so many scallops match many scallops about equally
    well: the search is bounded to one period either side of where the measured mirror
    centre (a trace through the spindle axis) meets the simulated profile's centre: its
    heights' own mirror centre and, where the line passes through the spindle axis, the
    axis's place on the line (``axis_s``, mm from the line's start); the best match over
    both windows is taken."""
    a = _filled(z_meas)
    b = _filled(z_sim)
    ma = mirror_centre(z_meas, spacing=spacing, x0=float(s_meas[0]))
    mb = mirror_centre(z_sim, spacing=spacing, x0=float(s_sim[0]))
    n = min(a.size, b.size)
    # where the simulated profile's centre may be: its heights' mirror centre (a row of
    # cusps is mirror-symmetric about every cusp, so it can be a period or more off) and,
    # on a line through the spindle axis, the axis's place on the line
    centres = []
    if (mb["symmetry"] or 0) >= 0.5:
        centres.append((mb["centre_mm"], "the simulated profile's mirror centre"))
    if axis_s is not None:
        centres.append((float(axis_s), "the spindle axis on the line"))
    if (ma["symmetry"] or 0) >= 0.5 and centres and period:
        reach = int(math.ceil(period / spacing))
        lags = np.unique(np.concatenate([
            np.arange(int(round((c - ma["centre_mm"]) / spacing)) - reach,
                      int(round((c - ma["centre_mm"]) / spacing)) + reach + 1)
            for c, _ in centres]))
        how = ("within one period of the measured mirror centre on "
               + " or on ".join(w for _, w in centres))
    else:
        lags = np.arange(-(n // 2), n // 2 + 1)
        how = "over half the line either way"
    k_start = int(round((s_meas[0] - s_sim[0]) / spacing))
    r, lag = _best_lag(a, b, lags, k_start)
    null = _null_correlation(a, b, lags, k_start, seed=seed)
    return lag * spacing, r, how, null


def _best_lag(a, b, lags, k_start):
    """(correlation, lag) of the best-scoring lag: the correlation weighted by the
    overlap's share of the longest overlap possible."""
    n = min(a.size, b.size)
    best = (-2.0, 0, -2.0)
    for lag in lags:
        # measured sample i lies at simulated sample i + lag (positions from the line start)
        k0 = k_start + int(lag)
        i0, i1 = max(0, -k0), min(a.size, b.size - k0)
        if i1 - i0 < max(16, a.size // 3):
            continue
        u, v = a[i0:i1], b[i0 + k0:i1 + k0]
        su, sv = u.std(), v.std()
        if su == 0 or sv == 0:
            continue
        r = float(np.mean((u - u.mean()) * (v - v.mean())) / (su * sv))
        # a partial overlap counts for its share of the longest one possible
        score = r * (i1 - i0) / n
        if score > best[2]:
            best = (r, int(lag), score)
    return best[0], best[1]


def _null_correlation(a, b, lags, k_start, *, seed=0, n=NULL_SURROGATES) -> float | None:
    """The correlation the same search reaches with profiles unrelated to the simulation:
    the best of ``n`` phase-randomised surrogates of the measured profile (the same power
    spectrum, so the same feed marks and roughness, with random phases), searched over
    the same lags.  A registration whose correlation does not beat it has found nothing
    a profile of the same spectrum would not find by chance."""
    if a.size < 16:
        return None
    rng = np.random.default_rng(seed)
    spec = np.fft.rfft(a - a.mean())
    best = []
    for _ in range(n):
        ph = rng.uniform(0, 2 * np.pi, spec.size)
        ph[0] = 0.0
        if a.size % 2 == 0:
            ph[-1] = 0.0
        sur = np.fft.irfft(np.abs(spec) * np.exp(1j * ph), n=a.size)
        best.append(_best_lag(sur, b, lags, k_start)[0])
    return float(max(best)) if best else None


def _measurement_check(z_sim, z_true, noise, *, lambda_eff_nm, mode, rt_sim, rt_true) -> dict:
    """Does the virtual measurement along the line follow the cut it measured?  Points of
    the simulated measurement (its median offset removed: an interferometer's heights are
    relative) depart from the cut when they are off by more than both
    :data:`DEPARTURE_NOISE_FACTOR` times the instrument's own noise (the median, along the
    line, of each pixel's noise estimated from its frames) and
    :data:`DEPARTURE_WAVELENGTH_FRACTION` of the effective wavelength (half a fringe
    order), after a line (the instrument's levelling: piston and tilt) is removed; a run of
    :data:`DEPARTURE_MIN_RUN` neighbouring such points, or :data:`DEPARTURE_MIN_FRACTION`
    of all: ``status`` "failed".  An approximation: the cut is compared as sampled, not
    blurred by the objective, so a design with edges steeper than the objective resolves
    can depart at them without a lost fringe order."""
    d = (np.asarray(z_sim) - np.asarray(z_true)) * MM_TO_NM
    ok = np.isfinite(d)
    out: dict[str, Any] = {"status": "ok", "points": int(ok.sum()), "mode": mode,
                           "lambda_eff_nm": lambda_eff_nm, "Rt_nm": rt_sim, "Rt_cut_nm": rt_true}
    nz = np.asarray(noise, float)[ok] * MM_TO_NM if noise is not None else np.zeros(0)
    nz = nz[np.isfinite(nz)]
    sigma = float(np.median(nz)) if nz.size else None
    out["noise_nm"] = sigma
    if not ok.any():
        out.update(status="unknown", rms_departure_nm=None, threshold_nm=None, departing=0,
                   departing_fraction=0.0)
        return out
    i = np.flatnonzero(ok)
    d = d[ok]
    thr = max(DEPARTURE_WAVELENGTH_FRACTION * lambda_eff_nm,
              DEPARTURE_NOISE_FACTOR * (sigma or 0.0))
    # piston and tilt (the instrument's levelling), fitted to the points that follow the
    # cut (those within the threshold of the median offset, twice over), so that the
    # points that do not cannot tilt the line
    r = d - np.median(d)
    for _ in range(2):
        inl = np.abs(r) <= thr
        if inl.sum() < 2:
            break
        r = d - np.polyval(np.polyfit(i[inl].astype(float), d[inl], 1), i)
    d = r
    off = np.abs(d) > thr
    far = int(np.count_nonzero(off))
    run = _longest_run(off, i)
    out.update(rms_departure_nm=float(np.sqrt(np.mean(d ** 2))), threshold_nm=float(thr),
               departing=far, departing_fraction=far / d.size,
               rule=f"a point departs when it is off the cut by more than "
                    f"{DEPARTURE_NOISE_FACTOR:g} x the instrument's noise and more than half a "
                    f"fringe order (lambda_eff / 4 = {lambda_eff_nm / 4:.4g} nm), a line "
                    f"removed; failed with a run of {DEPARTURE_MIN_RUN} neighbouring such "
                    f"points or {100 * DEPARTURE_MIN_FRACTION:g} % of all",
               longest_run=run)
    if run >= DEPARTURE_MIN_RUN or far >= DEPARTURE_MIN_FRACTION * d.size:
        out["status"] = "failed"
    return out


def _longest_run(flags: np.ndarray, index: np.ndarray) -> int:
    """The most ``flags`` in a row at neighbouring ``index`` positions (a gap breaks a
    run)."""
    best = cur = 0
    prev = None
    for f, k in zip(flags, index):
        cur = cur + 1 if f and prev is not None and k == prev + 1 and cur > 0 else (1 if f else 0)
        best = max(best, cur)
        prev = k
    return best


def _measurement_warning(chk: dict) -> str | None:
    """The one-line warning of a failed virtual measurement (None when it followed the
    cut)."""
    if chk.get("status") != "failed":
        return None
    noise = "" if chk.get("noise_nm") is None else \
        f" against the instrument's noise of {chk['noise_nm']:.2g} nm"
    other = ("coherence scanning (CSI: render.interferometer.mode = \"csi\") follows slopes "
             "phase shifting cannot, and is how the real parts were measured (a white-light "
             "interferometer)" if chk.get("mode") == "psi" else
             "check render.interferometer (objective, mode) against the part's slopes")
    return (f"the virtual measurement ({str(chk.get('mode')).upper()}) does not follow the cut "
            f"it measured: {chk['departing']} of {chk['points']} points "
            f"({100 * chk['departing_fraction']:.3g} %) are off by more than "
            f"{chk['threshold_nm']:.3g} nm (rms departure {chk['rms_departure_nm']:.4g} nm"
            f"{noise}; Rt {_fmt(chk.get('Rt_nm'))} nm against the cut's "
            f"{_fmt(chk.get('Rt_cut_nm'))} nm): lost fringe orders or dropouts, so its column is "
            f"not what the instrument would report of this part; {other}")


def _registration_warning(reg: dict) -> str | None:
    """The one-line warning of a registration no better than chance (None otherwise)."""
    if reg.get("reliable", True):
        return None
    why = (f"its correlation {reg['correlation']:.3f} is no better than the "
           f"{reg['null_correlation']:.3f} a profile of the same spectrum unrelated to the "
           f"simulation reaches in the same search" if not reg.get("beats_chance", True) else
           f"it aligns the measured profile to a virtual measurement that does not follow the "
           f"cut (correlation {reg['correlation']:.3f})")
    return (f"the registration is not reliable: {why}; the profiles overlaid "
            f"are not aligned point for point (compare their parameters and periods, which "
            f"do not depend on the registration, not their shapes)")


def run_compare_profile(scene: Scene, out: str | Path, *, measured: str | Path,
                        line: str | None = None, units: str | None = None,
                        filter_spec: str | tuple | None = None,
                        overwrite: bool = False) -> dict:
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

    Returns
    -------
    dict
        The content of ``metrics.json``: ``kind`` = "profile", ``line_mm``, ``line_from``,
        ``registration`` (``shift_mm``, ``correlation``, ``how``), ``filter``,
        ``profiles`` (``measured``, ``simulated_measured``, ``true``: each the ISO 21920-2
        parameters and periods of :func:`~render_inspect.metrology.analyze_profile`),
        ``input``, ``scene``, ``seed``, ``software_version``, ``timing_s``.
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
    log.info("compare %s with %s along (%g, %g) -> (%g, %g) mm", scene.name, Path(measured).name,
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
    shift, corr, how_reg, null = _register(s_pos, prof.z, s_sim, z_sim, spacing=step,
                                           period=period, axis_s=axis_s, seed=seed)
    s_reg = s_pos + shift
    opts: dict[str, Any] = {"form": "poly2", "lambda_s": s_mm, "lambda_c": l_mm}
    res = {"measured": analyze_profile(s_reg, prof.z, spacing=step, **opts)}
    fil = res["measured"]["metrics"]["filter"]
    same = {"form": "poly2", "lambda_s": fil["lambda_s_mm"] or 0.0, "lambda_c": fil["lambda_c_mm"]}
    res["simulated_measured"] = analyze_profile(s_sim, z_sim, spacing=step, **same)
    res["true"] = analyze_profile(s_true, z_true, spacing=step, **same)
    noise_line = None
    if r.height_noise is not None:
        _, noise_line = line_profile(np.where(r.valid, r.height_noise, np.nan), pixel=ig.pixel,
                                     origin=ig.origin, p0=p0, p1=p1, step=step)
    check = _measurement_check(z_sim, z_true, noise_line, lambda_eff_nm=float(ig.lambda_eff_nm),
                               mode=band.render.interferometer.mode,
                               rt_sim=res["simulated_measured"]["metrics"]["profile"].get("Rt_nm"),
                               rt_true=res["true"]["metrics"]["profile"].get("Rt_nm"))
    reg = {"shift_mm": shift, "correlation": corr, "how": how_reg, "null_correlation": null,
           "beats_chance": null is None or corr > null,
           # a registration to a measurement that does not follow the cut aligns to its
           # failures, whatever its correlation
           "reliable": (null is None or corr > null) and check["status"] != "failed",
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
    metrics = {
        "command": "compare", "kind": "profile", "scene": scene.name, "seed": seed,
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
                  "units_in_file": prof.meta.get("units_in_file"),
                  "units_from": prof.meta.get("units_from"), "n_points": prof.meta["n_points"],
                  "n_measured": prof.n_measured, "spacing_mm": step},
        "instrument": {"objective": band.render.interferometer.objective,
                       "mode": band.render.interferometer.mode, "pixel_mm": float(ig.pixel)},
        "files": {"metrics.json": "these metrics", "overlay.png": "the three profiles overlaid",
                  "roughness_overlay.png": "their roughness profiles overlaid",
                  "measured_profile.png": "the measured profile analysed",
                  "report.html": "the report"},
    }
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


def _fmt(v, key=""):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    if key == "RSm_mm":
        v = v * MM_TO_UM
    return f"{v:.4g}"


def _page(metrics: dict, figs: dict) -> str:
    p = metrics["profiles"]
    f = metrics["filter"]
    rep = HtmlReport(f"{metrics['scene']}: measured profile against the simulation",
                     f"{Path(metrics['input']['path']).name} along {metrics['line_from']}; "
                     f"lambda_s {f['lambda_s_mm'] or 0:g} mm, lambda_c {f['lambda_c_mm']:g} mm "
                     f"({f['chosen_by']}); parabola removed from each")
    if metrics.get("warnings"):
        rep.section("Warnings")
        rep.list(metrics["warnings"])
    rep.section("Profiles overlaid")
    rep.figure(figs["overlay"], "Measured (black), simulated through the virtual "
               "interferometer (blue) and the simulated cut itself (orange, dashed), registered "
               "along the line; heights in nm, positions along the line in mm.")
    rep.figure(figs["roughness_overlay"], "The same after the ISO 16610-21 filters, over each "
               "profile's evaluation length.")
    rep.section("Parameters side by side (ISO 21920-2)")
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
    reg = metrics["registration"]
    chk = metrics.get("virtual_measurement") or {}
    null = reg.get("null_correlation")
    notes = [f"registration: measured positions shifted by {reg['shift_mm'] * MM_TO_UM:+.4g} um "
             f"along the line (correlation {reg['correlation']:.3f}, searched {reg['how']}); "
             + ("" if null is None else
                f"{'reliable' if reg.get('reliable') else 'NOT reliable'}: an unrelated profile "
                f"of the same spectrum reaches {null:.3f} ({reg.get('rule')})"),
             f"virtual measurement against the cut it measured: "
             f"{'FAILED' if chk.get('status') == 'failed' else chk.get('status', 'n/a')}; rms "
             f"departure {_fmt(chk.get('rms_departure_nm'))} nm, instrument noise "
             f"{_fmt(chk.get('noise_nm'))} nm, {chk.get('departing', 0)} points off by more "
             f"than {_fmt(chk.get('threshold_nm'))} nm ({chk.get('rule', '')})",
             f"virtual instrument: {metrics['instrument']['objective']} "
             f"{metrics['instrument']['mode']}, pixel {metrics['instrument']['pixel_mm'] * MM_TO_UM:.4g} um",
             f"measured file: {metrics['input']['n_measured']} of {metrics['input']['n_points']} "
             f"points measured, spacing {metrics['input']['spacing_mm'] * MM_TO_UM:.4g} um, units "
             f"{metrics['input']['units_in_file']} ({metrics['input']['units_from']})"]
    for k, lab in _NAMES:
        notes += [f"{lab}: {w}" for w in p[k]["warnings"]]
    rep.section("Notes")
    rep.list(notes)
    return rep.render()


def run_compare_command(scene: Scene, out: str | Path, *, measured: str | Path | None = None,
                        vary: str | None = None, force: bool = False, line: str | None = None,
                        units: str | None = None, filter_spec: str | tuple | None = None,
                        repeat: int = 1,
                        overwrite: bool = False) -> dict:
    """``compare``: :func:`run_compare_profile` when ``measured`` is a profile file,
    :func:`~render_inspect.pipeline.run_compare` otherwise (``line``, ``units`` and
    ``filter_spec`` are then refused, naming the option)."""
    if measured is not None and is_profile_file(measured):
        if vary is not None or force or repeat != 1:
            opt = "--vary" if vary is not None else "--force" if force else "--repeat"
            raise InputError(f"{opt} is for two variants or a measured map; --measured "
                             f"{str(measured)!r} is a profile")
        return run_compare_profile(scene, out, measured=measured, line=line, units=units,
                                   filter_spec=filter_spec, overwrite=overwrite)
    for opt, v in (("--line", line), ("--units", units), ("--filter", filter_spec)):
        if v is not None:
            raise InputError(f"{opt} is for --measured PROFILE (a profile file); received "
                             f"{opt} {v} with --measured {measured!r}")
    return run_compare(scene, out, measured=measured, vary=vary, force=force,
                       overwrite=overwrite, repeat=repeat)
