"""The numbers of docs/validation.md: the published diamond-turning programs simulated and
set against the parts' measured slices.

    python tools/validation_numbers.py                # the runs; docs/validation.json and the doc
    python tools/validation_numbers.py --docs         # only rewrite the doc from the json
    python tools/validation_numbers.py --check        # exit 1 if the doc differs from the json
    python tools/validation_numbers.py --renumber     # the numbers again from the json's runs
    python tools/validation_numbers.py --figures DIR  # also write the overlaid profiles (PNG)

For each public program of ``../shared/realdata/turned`` (1021, 1022, 1023; SOURCES.md
there) the example scene ``docs/examples/turned/scene.toml`` (tool 0.2 mm) is simulated
along the line its measured slice ``*-WLI-2D.csv`` lies on, exactly as
``render-inspect compare SCENE --measured SLICE`` does it (the functions of
``render_inspect.pipeline._compare_profile``: the default diameter through the spindle
axis with the slice's mirror centre on it, a band of +-12 um about it, the virtual
interferometer over the band, the same-line extraction, the parabola and the ISO 16610-21
filters the measured slice's ISO 21920-3 choice gives; compare's registration along the line,
against the simulated measurement or, where that fails its check against the cut, against
the cut as the instrument sees it, is computed with its check against chance and recorded,
not applied; the shift against the failed image is recorded beside it).  The roughness
profiles of the measured slice, of the simulated measurement and of the simulated cut are
then cut into radial bands (both
sides of the axis together) and their Ra, Rq, Rt, Rsk, Rku and RSm taken there.

What the parts do not say (the material, the spindle speed, the objective) is varied over
its plausible range rather than chosen: every material preset that diamond turning cuts
(``ideal``, ``al6061``, ``ofhc_copper``, ``nip``), spindle speeds of 500 and 2000 rpm, and
the 20x and 50x objectives, each through the virtual interferometer as phase shifting
(the example scene's mode) and as white-light scanning (the instrument of the slices); the
doc gives the least and largest value over them.  The programs' feeds over the bands'
radii and their steps point by point come from the program files.  No preset
is changed.  Numbers go to ``docs/validation.json`` and into the marked spans
``<!-- n:KEY -->TEXT<!-- /n -->`` of docs/validation.md (the span machinery of
``tools/docs_numbers.py``); ``tests/test_validation_doc.py`` checks the spans against the
json.  Takes about twelve minutes on a busy 2-core machine (the parts in parallel).
"""

from __future__ import annotations

import argparse
import datetime
import importlib.util
import json
import math
import os
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
VALIDATION_JSON = REPO / "docs" / "validation.json"
VALIDATION_MD = REPO / "docs" / "validation.md"
SCENE = REPO / "docs" / "examples" / "turned" / "scene.toml"
#: the published files (RENDER_INSPECT_REALDATA names the folder for a checkout that does
#: not sit beside ``shared/realdata``)
REALDATA = Path(os.environ.get("RENDER_INSPECT_REALDATA",
                               REPO.parent / "shared" / "realdata")) / "turned"

#: part -> (program, measured slice)
PARTS = {
    "1021": ("1021-spiralPath20230418T214748.nc", "1021-WLI-2D.csv"),
    "1022": ("1022-spiralPath20230418T214917.nc", "1022-WLI-2D.csv"),
    "1023": ("1023-spiralPath20230418T221742.nc", "1023-WLI-2D.csv"),
}
#: the parts' radius, mm (the programs' X runs from 1.031 mm to the axis: a radius)
PART_RADIUS_MM = 1.1
#: radial bands, um from the spindle axis
BANDS = {"inner": (20.0, 140.0), "outer": (150.0, 420.0)}
MATERIALS = ("ideal", "al6061", "ofhc_copper", "nip")
SPINDLES_RPM = (500, 2000)
#: the (material, spindle speed) pairs simulated: the full grid
CASES = tuple((m, rpm) for m in MATERIALS for rpm in SPINDLES_RPM)
OBJECTIVES = ("20x", "50x")
#: the virtual interferometer's modes: the example scene's phase shifting (PSI) and the
#: white-light scanning (CSI) of the instrument that measured the slices
MODES = ("psi", "csi")
#: the parameters of the bands, their formats
PARAMS = (("Ra_nm", ".3g"), ("Rq_nm", ".3g"), ("Rt_nm", ".3g"), ("Rsk", ".2f"),
          ("Rku", ".2f"), ("RSm_um", ".3g"))


def _docs_numbers():
    """``tools/docs_numbers.py`` as a module: its span machinery (``SPAN``, ``fmt``,
    ``rewrite``, ``spans``) is the one used here."""
    spec = importlib.util.spec_from_file_location("docs_numbers", REPO / "tools" / "docs_numbers.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("docs_numbers", mod)
    spec.loader.exec_module(mod)
    return mod


# ------------------------------------------------------------------------ band parameters
def band_parameters(s_mm, r_mm, evaluate, *, axis_mm: float, band_um: tuple[float, float],
                    spacing: float) -> dict:
    """Ra, Rq, Rt, Rsk, Rku (about the band's own mean) and RSm (ISO 21920-2 profile
    elements, each side of the axis separately, widths pooled) of the roughness profile
    ``r_mm`` at positions ``s_mm`` whose distance from ``axis_mm`` lies in ``band_um``."""
    import numpy as np

    from render_inspect.core.units import MM_TO_NM, MM_TO_UM
    from render_inspect.metrology._iso21920 import rsm

    s = np.asarray(s_mm, float)
    r = np.where(np.asarray(evaluate, bool), np.asarray(r_mm, float), np.nan)
    d = np.abs(s - axis_mm) * MM_TO_UM
    sel = (d >= band_um[0]) & (d <= band_um[1])
    v = r[sel & np.isfinite(r)]
    if v.size < 16:
        return {k: None for k, _ in PARAMS} | {"n": int(v.size)}
    c = v - v.mean()
    rq = float(np.sqrt(np.mean(c * c)))
    rt = float(c.max() - c.min())
    widths, count = 0.0, 0
    for side in (s < axis_mm, s > axis_mm):
        seg = np.where(sel & side)[0]
        if seg.size < 16 or not np.isfinite(r[seg]).any():
            continue
        part = r[seg[0]:seg[-1] + 1] - np.nanmean(r[seg])
        w, n = rsm(part, spacing=spacing, rz=rt, section_length=(seg[-1] - seg[0]) * spacing)
        if n:
            widths += w * n
            count += n
    return {"Ra_nm": float(np.mean(np.abs(c))) * MM_TO_NM, "Rq_nm": rq * MM_TO_NM,
            "Rt_nm": rt * MM_TO_NM, "Rsk": float(np.mean(c ** 3) / rq ** 3),
            "Rku": float(np.mean(c ** 4) / rq ** 4),
            "RSm_um": widths / count * MM_TO_UM if count else None, "n": int(v.size)}


# ------------------------------------------------------------------------------ one run
def _scene(part: str, material: str, rpm: float):
    from render_inspect.scene import load_scene

    program = (REALDATA / PARTS[part][0]).resolve()
    return load_scene(str(SCENE), [f"process.program='{program}'",
                                   f"material.preset='{material}'",
                                   f"process.spindle_rpm={rpm:g}",
                                   # feed per revolution of the program kept: the feed words
                                   # are the program's, this is the scene's F for moves
                                   # without C (none in these programs)
                                   f"process.feed_mm_per_min={0.0396 * rpm:g}"])


def profiles_along_slice(part: str, material: str, rpm: float, objectives=OBJECTIVES,
                         modes=MODES) -> dict:
    """``compare SCENE --measured SLICE`` up to its parameters, for each objective: the
    measured slice, the simulated measurement and the simulated cut along the same line,
    with the same form removal and filters (the measured slice's choice); the slice placed
    with its mirror centre on the axis, compare's registration kept (shift, correlation,
    the surrogates' level, reliable, what it was made against, the virtual measurement's
    check, and the shift and correlation against the image itself).
    Returns {(objective, mode): {"line", "axis_mm", "shift_mm", "correlation",
    "null_correlation", "reliable", "against", "check", "image_shift_mm",
    "image_correlation", "filter", "profiles": {name: analyze_profile's dict}}}."""
    import numpy as np

    from render_inspect.instruments import microscope_from_config, render_interferogram
    from render_inspect.io import read_profile
    from render_inspect.metrology import analyze_profile, line_profile, measure_frames
    from render_inspect.pipeline._compare_profile import (_band_scene, axis_on_line,
                                                           default_line, registration_period)
    from render_inspect.pipeline._compare_profile_checks import (_measurement_check, _register,
                                                                 cut_as_seen)
    from render_inspect.pipeline._simulate import simulate
    from render_inspect.processes import process_of
    from render_inspect.scene import scene_from_dict

    scene = _scene(part, material, rpm)
    prof = read_profile(REALDATA / PARTS[part][1], units="um")
    p0, p1, _ = default_line(scene, prof)
    axis = process_of(scene).traits(process_of(scene).inputs_of(scene)).axis
    band, _fov = _band_scene(scene, p0, p1)
    seed = int(scene.simulation.seed)
    hm = simulate(band).heightmap
    step = prof.spacing
    s_true, z_true = line_profile(hm.machined, pixel=hm.pixel, origin=hm.origin, p0=p0, p1=p1,
                                  step=step)
    period = registration_period(scene, prof.z, spacing=step)
    s_pos = prof.x - prof.x[0]
    out = {}
    for obj, mode in ((o, m) for o in objectives for m in modes):
        d = band.model_dump(mode="json")
        d["render"]["interferometer"]["objective"] = obj
        d["render"]["interferometer"]["mode"] = mode
        b = scene_from_dict(d, band.name)
        ig = render_interferogram(hm, b.render.interferometer, seed=seed)
        r = measure_frames(ig.recorded())
        h_meas = np.where(r.valid, r.height, np.nan)
        s_sim, z_sim = line_profile(h_meas, pixel=ig.pixel, origin=ig.origin, p0=p0, p1=p1,
                                    step=step)
        # compare's registration: against the virtual measurement, or, where that fails its
        # check against the cut as the instrument sees it, against the cut as seen
        seen = cut_as_seen(hm.machined, pixel=hm.pixel, origin=hm.origin,
                           microscope=microscope_from_config(b.render.interferometer),
                           camera_pixel=float(ig.pixel), camera_origin=ig.origin,
                           camera_shape=(h_meas.shape[0], h_meas.shape[1]))
        _, z_seen = line_profile(seen, pixel=ig.pixel, origin=ig.origin, p0=p0, p1=p1, step=step)
        noise_line = None
        if r.height_noise is not None:
            _, noise_line = line_profile(np.where(r.valid, r.height_noise, np.nan),
                                         pixel=ig.pixel, origin=ig.origin, p0=p0, p1=p1,
                                         step=step)
        check = _measurement_check(z_sim, z_seen, noise_line,
                                   lambda_eff_nm=float(ig.lambda_eff_nm), mode=mode,
                                   rt_sim=None, rt_true=None)
        axis_s = axis_on_line(scene, p0, p1, tolerance=(period or step) / 2)
        image = _register(s_pos, prof.z, s_sim, z_sim, spacing=step, period=period,
                          axis_s=axis_s, seed=seed)
        failed = check["status"] == "failed"
        shift, corr, _how, null = (_register(s_pos, prof.z, s_sim, z_seen, spacing=step,
                                             period=period, axis_s=axis_s, seed=seed)
                                   if failed else image)
        # the slice stays where the default line put it (its mirror centre on the axis);
        # compare's registration along the line is recorded beside it, not applied: on these
        # periodic profiles it can lock onto a match some feed periods away
        meas = analyze_profile(s_pos, prof.z, spacing=step, form="poly2")
        fil = meas["metrics"]["filter"]
        same = {"form": "poly2", "lambda_s": fil["lambda_s_mm"] or 0.0,
                "lambda_c": fil["lambda_c_mm"]}
        out[(obj, mode)] = {"line": (p0, p1), "axis_mm": float(math.hypot(axis[0] - p0[0], axis[1] - p0[1])),
                    "shift_mm": shift, "correlation": corr, "null_correlation": null,
                    "reliable": null is None or corr > null,
                    "against": "cut_as_seen" if failed else "virtual_measurement",
                    "check": check["status"], "image_shift_mm": image[0],
                    "image_correlation": image[1], "filter": same,
                    "profiles": {"measured": meas,
                                 "simulated_measured": analyze_profile(s_sim, z_sim, spacing=step, **same),
                                 "true": analyze_profile(s_true, z_true, spacing=step, **same)}}
    return out


def _bands_of(res: dict, spacing: float) -> dict:
    out = {}
    for name, a in res["profiles"].items():
        arr = a["arrays"]
        out[name] = {b: band_parameters(arr["x"], arr["roughness"], arr["evaluate"],
                                        axis_mm=res["axis_mm"], band_um=lim, spacing=spacing)
                     for b, lim in BANDS.items()}
    return out


def overlay_figure(res: dict, path: Path, title: str) -> None:
    """The measured, simulated-measured and true primary profiles overlaid (PNG)."""
    from render_inspect.report import profile_overlay_figure

    names = (("measured", "measured slice"),
             ("simulated_measured", "simulated, through the virtual interferometer"),
             ("true", "simulated cut (truth)"))
    png = profile_overlay_figure(
        [{"s": res["profiles"][k]["arrays"]["x"], "z": res["profiles"][k]["arrays"]["primary"],
          "label": lab} for k, lab in names], title=title)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(png)


# ------------------------------------------------------------------------------ the runs
def _part_rows(part: str, figures: Path | None) -> list[dict]:
    """One part over the cases and objectives: a row of band parameters each."""
    from render_inspect.core.units import MM_TO_UM
    from render_inspect.io import read_profile

    spacing = read_profile(REALDATA / PARTS[part][1], units="um").spacing
    rows = []
    for material, rpm in CASES:
        t0 = time.perf_counter()
        got = profiles_along_slice(part, material, rpm)
        for (obj, mode), res in got.items():
            rows.append({"material": material, "spindle_rpm": rpm, "objective": obj,
                         "mode": mode,
                         "shift_um": res["shift_mm"] * MM_TO_UM,
                         "correlation": res["correlation"],
                         "null_correlation": res["null_correlation"],
                         "reliable": res["reliable"], "against": res["against"],
                         "virtual_measurement": res["check"],
                         "image_shift_um": res["image_shift_mm"] * MM_TO_UM,
                         "image_correlation": res["image_correlation"],
                         "lambda_c_mm": res["filter"]["lambda_c"],
                         "lambda_s_mm": res["filter"]["lambda_s"],
                         "bands": _bands_of(res, spacing)})
            if figures is not None and material == "ideal" and rpm == SPINDLES_RPM[0]:
                overlay_figure(res, figures / f"{part}_{obj}_{mode}_overlay.png",
                               f"part {part}, {obj} {mode.upper()}, material ideal: the slice's "
                               f"mirror centre on the axis; parabola removed")
        print(f"validation_numbers: {part} {material} {rpm} rpm: "
              f"{time.perf_counter() - t0:.0f} s", file=sys.stderr)
    return rows


def program_numbers(part: str) -> dict:
    """What the part's program commands, from the file as ``read_program`` reads it (its C
    and X words): the feed per revolution over each band's radii
    (:func:`render_inspect.processes.feed_over_radii`, the radial distance over the
    revolutions the spindle turns between the band's radii) and the least and largest
    step point by point (:func:`render_inspect.processes.feed_per_rev`: how far the radius
    moves in the revolution that starts at each point, over the whole program)."""
    from render_inspect.core.units import MM_TO_UM, UM_TO_MM
    from render_inspect.io import read_program
    from render_inspect.processes import feed_over_radii, feed_per_rev

    path = read_program(REALDATA / PARTS[part][0], part_radius=PART_RADIUS_MM).program
    _, step = feed_per_rev(path)
    out = {f"val.{part}.program.feed_{band}_um":
           (feed_over_radii(path, lo * UM_TO_MM, hi * UM_TO_MM) * MM_TO_UM, ".3g")
           for band, (lo, hi) in BANDS.items()}
    out[f"val.{part}.program.step_min_um"] = (float(step.min()) * MM_TO_UM, ".3g")
    out[f"val.{part}.program.step_max_um"] = (float(step.max()) * MM_TO_UM, ".3g")
    return out


def make(figures: Path | None = None):
    """Every part over the cases (material, spindle speed) and objectives, the parts in
    parallel; returns the numbers ``{key: (value, format) | text}`` and the raw table."""
    # imported here: only a full run needs the process pool
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=len(PARTS)) as pool:
        futures = {part: pool.submit(_part_rows, part, figures) for part in PARTS}
        table = {part: f.result() for part, f in futures.items()}
    return numbers_of(table), table


def numbers_of(table: dict) -> dict:
    """The doc's numbers ``{key: (value, format) | text}`` from the runs' table (a part ->
    its rows) and the programs' files (:func:`program_numbers`)."""
    from render_inspect.core.units import MM_TO_UM

    numbers: dict = {}
    for part, rows in table.items():
        numbers.update(program_numbers(part))
        first = rows[0]   # the measured slice's band values: the same in every row
        numbers[f"val.{part}.lambda_c_mm"] = (first["lambda_c_mm"], ".3g")
        numbers[f"val.{part}.lambda_s_um"] = ((first["lambda_s_mm"] or 0) * MM_TO_UM, ".3g")
        for mode in MODES:
            cors = [r["correlation"] for r in rows if r["mode"] == mode]
            numbers[f"val.{part}.corr_{mode}"] = _range(cors, ".2f")
            shifts = [r["shift_um"] for r in rows if r["mode"] == mode]
            numbers[f"val.{part}.shift_{mode}_um"] = _range(shifts, ".3g")
            numbers[f"val.{part}.null_{mode}"] = _range(
                [r["null_correlation"] for r in rows if r["mode"] == mode], ".2f")
            numbers[f"val.{part}.image_corr_{mode}"] = _range(
                [r["image_correlation"] for r in rows if r["mode"] == mode], ".2f")
            numbers[f"val.{part}.image_shift_{mode}_um"] = _range(
                [r["image_shift_um"] for r in rows if r["mode"] == mode], ".3g")
            of = [r for r in rows if r["mode"] == mode]
            numbers[f"val.{part}.failed_{mode}"] = (
                f"{sum(r['virtual_measurement'] == 'failed' for r in of)} of {len(of)}")
            numbers[f"val.{part}.reliable_{mode}"] = (
                f"{sum(bool(r['reliable']) for r in of)} of {len(of)}")
        for band in BANDS:
            for key, spec in PARAMS:
                m = first["bands"]["measured"][band][key]
                numbers[f"val.{part}.{band}.meas.{key}"] = (m, spec)
                for name, tag, mode in (("simulated_measured", "psi", "psi"),
                                        ("simulated_measured", "csi", "csi"),
                                        ("true", "true", None)):
                    sel = [r for r in rows if mode is None or r["mode"] == mode]
                    vals = [r["bands"][name][band][key] for r in sel]
                    numbers[f"val.{part}.{band}.{tag}.{key}"] = _range(vals, spec)
                    ratio = [r["bands"][name][band][key] / r["bands"]["measured"][band][key]
                             for r in sel if r["bands"][name][band][key] is not None
                             and r["bands"]["measured"][band][key]]
                    if key in ("Ra_nm", "Rq_nm", "Rt_nm"):
                        numbers[f"val.{part}.{band}.ratio_{tag}.{key}"] = _range(ratio, ".2f")
    return numbers


def _range(values, spec: str) -> str:
    """'a' when the least and largest agree to the format, 'a-b' (or 'a to b') otherwise."""
    fmt = _docs_numbers().fmt
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return "n/a"
    lo, hi = fmt(min(v), spec), fmt(max(v), spec)
    if lo == hi:
        return lo
    return f"{lo} to {hi}" if min(v) < 0 else f"{lo}-{hi}"


# ------------------------------------------------------------------------------ the files
def load(path: Path = VALIDATION_JSON) -> dict:
    if not path.is_file():
        return {"numbers": {}}
    return json.loads(path.read_text())


def check(data: dict, doc: Path = VALIDATION_MD) -> list[str]:
    """Every marked span of docs/validation.md that differs from ``data`` (or names no
    number in it)."""
    dn = _docs_numbers()
    bad = []
    for key, text in dn.spans(doc.read_text()):
        n = data["numbers"].get(key)
        if n is None:
            bad.append(f"docs/validation.md: {key} is not in docs/validation.json")
        elif n["text"] != text:
            bad.append(f"docs/validation.md: {key} says {text!r}, the run gave {n['text']!r}")
    return bad


def _formatted(numbers: dict) -> dict:
    """``{key: (value, format) | text}`` -> the json's ``{key: {"text", "value"}}``."""
    fmt = _docs_numbers().fmt
    return {k: {"text": fmt(*(v if isinstance(v, tuple) else (v,))),
                "value": v[0] if isinstance(v, tuple) else None}
            for k, v in sorted(numbers.items())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--docs", action="store_true", help="only rewrite the doc from the json")
    ap.add_argument("--check", action="store_true", help="exit 1 if the doc differs from the json")
    ap.add_argument("--renumber", action="store_true",
                    help="no runs: the numbers again from the json's table of runs and the "
                         "programs' files (after a change to how they are summed up), then "
                         "the doc")
    ap.add_argument("--figures", type=Path, default=None,
                    help="folder for the overlaid profiles (PNG; not part of the repository)")
    args = ap.parse_args(argv)
    dn = _docs_numbers()
    data = load()
    if args.check:
        bad = check(data)
        print("\n".join(bad) or "every marked number is current",
              file=sys.stderr if bad else sys.stdout)
        return 1 if bad else 0
    if args.renumber:
        if not data.get("table"):
            print("validation_numbers: docs/validation.json holds no table of runs: run "
                  "the tool without --renumber", file=sys.stderr)
            return 1
        if not REALDATA.is_dir():
            print(f"validation_numbers: {REALDATA} is absent: the programs are read from "
                  f"there", file=sys.stderr)
            return 1
        data["numbers"] = _formatted(numbers_of(data["table"]))
        VALIDATION_JSON.write_text(json.dumps(data, indent=2, sort_keys=True, allow_nan=False)
                                   + "\n")
    elif not args.docs:
        if not REALDATA.is_dir():
            print(f"validation_numbers: {REALDATA} is absent: the measured slices and the "
                  f"programs are read from there", file=sys.stderr)
            return 1
        from render_inspect import __version__

        t0 = time.perf_counter()
        numbers, table = make(args.figures)
        data = {"about": __doc__.split("\n\n")[0],
                "varied": {"material": list(MATERIALS), "spindle_rpm": list(SPINDLES_RPM),
                           "objective": list(OBJECTIVES),
                           "mode": list(MODES)},
                "bands_um": BANDS,
                "numbers": _formatted(numbers),
                "table": table,
                "seconds": round(time.perf_counter() - t0, 1),
                "date": datetime.date.today().isoformat(), "software_version": __version__}
        VALIDATION_JSON.write_text(json.dumps(data, indent=2, sort_keys=True, allow_nan=False)
                                   + "\n")
    text = VALIDATION_MD.read_text()
    new, unknown = dn.rewrite(text, data["numbers"])
    if new != text:
        VALIDATION_MD.write_text(new)
    if unknown:
        print("marked spans without a number:\n  " + "\n  ".join(unknown), file=sys.stderr)
    return 1 if unknown else 0


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    sys.exit(main())
