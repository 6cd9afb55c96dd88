"""``fit`` on the real turned slices: the feed per revolution fitted to windows of each
measured slice (``../shared/realdata/turned``), beside the feed the program gives at those
radii, and the nose radius fitted with the program's own path.

    python tools/profile_fit_numbers.py          # run the fits, write docs/fit_profiles.json
                                                 # and the tables in docs/fit.md and
                                                 # docs/validation.md
    python tools/profile_fit_numbers.py --docs   # rewrite the tables from the json alone
    python tools/profile_fit_numbers.py --checks # no fits: the windows' radii and
                                                 # programmed feed again, the checks of the
                                                 # feed's reference and of the line's other
                                                 # arm, the slices' table (json and the
                                                 # tables in docs/fit.md)
    python tools/profile_fit_numbers.py --only 1023:-0.33,1016:0.30
                                                 # run those cases again, keep the others
                                                 # from the json

Each window is fitted on both arms of the slice where the slice reaches its radii on the
other side of the axis (``--arms`` left to its default), and on the window's arm alone
(``--arms one``): the table shows both.  ``--one-arm-from-json`` takes the one-arm fit from
the json's previous row of the case (a fit of one arm, the same one ``--arms one`` runs)
instead of running it again.  The fits' caches lie under ``--out``: a run again reuses
them.

The programmed feed of a window is :func:`program_feed` over the radii its measured samples
cover (:func:`window_radii`: their distances from where the line passes the spindle axis,
the slice's mirror centre), one rule for every table.

Each case is what ``render-inspect fit SLICE --units um --scene S --free KEY --at X,0
--window W`` runs, S being docs/examples/turned/scene.toml with the white-light virtual
instrument (the slices are white-light measurements) and, for the feed fits, without its
program (a planned spiral of one feed per revolution, whose feed is fitted).
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import sys
import tomllib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
#: the real files (RENDER_INSPECT_REALDATA names the folder for a checkout that does not sit
#: beside shared/, as for the tests)
REAL = Path(os.environ.get("RENDER_INSPECT_REALDATA",
                           REPO / ".." / "shared" / "realdata")) / "turned"
JSON = REPO / "docs" / "fit_profiles.json"
SCENE = REPO / "docs" / "examples" / "turned" / "scene.toml"
PROGRAMS = {"1021": "1021-spiralPath20230418T214748.nc",
            "1022": "1022-spiralPath20230418T214917.nc",
            "1023": "1023-spiralPath20230418T221742.nc"}
#: (part, window centre x mm on the radial line, window mm, free key, with the program)
CASES = [("1021", -0.30, 0.3, "process.feed_mm_per_min", False),
         ("1021", 0.25, 0.3, "process.feed_mm_per_min", False),
         ("1022", -0.15, 0.2, "process.feed_mm_per_min", False),
         ("1023", -0.33, 0.2, "process.feed_mm_per_min", False),
         ("1016", 0.30, 0.2, "process.feed_mm_per_min", False),
         ("1021", 0.0, 0.3, "process.feed_mm_per_min", False),
         ("1021", -0.30, 0.3, "tool.nose_radius", True)]
#: the evaluations a fit may take: of one arm, of both arms (each of whose evaluations
#: simulates two stretches; a fit that converges stops before)
MAX_EVALUATIONS = {"one": 45, "both": 74}
#: feed per revolution of 1016 by its program's name ("x0.01"), mm
FEED_1016 = 0.01
RPM = 100.0


def program_feed(part: str, r0: float, r1: float, weighting: str = "plain") -> float:
    """The feed per revolution (mm) the part's program commands over radii r0 < r1:
    :func:`render_inspect.processes.feed_over_radii` of the program as ``read_program``
    reads it (its C and X words), ``plain`` (the radial distance over the revolutions the
    C axis turns between the radii) or ``hann`` (the marks' local frequency averaged under
    a Hann window over the radii, inverted: as the fit's spectrum reads a window).  1016's
    program is not published: its 10 um by its name."""
    if part not in PROGRAMS:
        return FEED_1016
    from render_inspect.processes import feed_over_radii

    return feed_over_radii(_program_path(part), r0, r1, weighting=weighting)


@functools.lru_cache(maxsize=None)
def _program_path(part: str):
    from render_inspect.io import read_program

    return read_program(REAL / PROGRAMS[part], part_radius=1.1, spindle_rpm=RPM).program


def window_radii(prof, scene, win) -> list:
    """The radii (mm) the measured samples of a fit's window cover: their distances from
    where the line passes the spindle axis (the default line puts the slice's mirror
    centre there), first and last measured sample."""
    from render_inspect.pipeline._fit_profile import _axis_in_window

    z = prof.z[win["i0"]:win["i1"]]
    s = prof.x[win["i0"]:win["i1"]] - prof.x[win["i0"]]
    ok = np.isfinite(z)
    axis = _axis_in_window(scene, win, float("inf"))
    r = np.abs(s[ok] - axis)
    return [float(r.min()), float(r.max())]


def slices(parts=("1016", "1021", "1022", "1023")) -> list:
    """The table of docs/fit.md's "Real measurements": each slice's mirror (the line's
    closest point to the spindle axis) and, on each side of it, the two halves' radii,
    the program's feed per revolution over each half's radii (:func:`program_feed`,
    plain) and the marks' period there (``profile_marks``, two segments)."""
    from render_inspect.fit import profile_marks
    from render_inspect.io import read_profile

    rows = []
    for part in parts:
        prof = read_profile(REAL / f"{part}-WLI-2D.csv", units="um")
        z, px = prof.z, prof.spacing
        m = profile_marks(z, px)["mirror_at"]
        row = {"part": part, "mirror_at_mm": float(prof.x[m] - prof.x[0]), "sides": []}
        for name, side, radii in (("beyond", z[m + 1:], np.arange(1, z.size - m) * px),
                                  ("before", z[:m][::-1], np.arange(1, m + 1) * px)):
            marks = profile_marks(side, px, segments=2, mirror=False)
            bounds = np.linspace(0, side.size, 3).astype(int)
            halves = []
            for (a, b), period in zip(zip(bounds[:-1], bounds[1:]), marks["periods_mm"]):
                ok = np.isfinite(side[a:b])
                r0, r1 = float(radii[a:b][ok][0]), float(radii[a:b][ok][-1])
                prog = program_feed(part, r0, r1)
                halves.append({"radii_mm": [r0, r1], "programmed_feed_um": prog * 1e3,
                               "period_um": None if period is None else period * 1e3})
            row["sides"].append({"side": name, "halves": halves,
                                 "one_family": bool(marks["one_family"]),
                                 "reason": marks["reason"]})
        rows.append(row)
    return rows


def slices_table(rows: list) -> str:
    lines = ["| slice | side of the mirror (mm along the slice) | radii (mm) | programmed "
             "feed (um/rev) | period found (um) | period / programmed | marks |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        for sd in r["sides"]:
            where = ("beyond" if sd["side"] == "beyond" else "before") + \
                f" {r['mirror_at_mm']:.3f}"
            for k, h in enumerate(sd["halves"]):
                prog = f"{h['programmed_feed_um']:.2f}" + (" (by its name)" if r["part"] == "1016"
                                                          else "")
                per = "n/a" if h["period_um"] is None else f"{h['period_um']:.2f}"
                ratio = ("n/a" if h["period_um"] is None
                         else f"{100 * (h['period_um'] / h['programmed_feed_um'] - 1):+.1f} %")
                marks = ("" if k else "one family" if sd["one_family"] else sd["reason"])
                lines.append(f"| {r['part'] if k == 0 else ''} | {where if k == 0 else ''} | "
                             f"{h['radii_mm'][0]:.3f}-{h['radii_mm'][1]:.3f} | {prog} | {per} | "
                             f"{ratio} | {marks} |")
    return "\n".join(lines)


def arm_checks(data: dict) -> list:
    """For each one-family feed window of the table, without a fit: the programmed step
    weighted as the fit sees it, and the marks' period (the fit's own estimator,
    :func:`~render_inspect.fit._profile.make_profile_target`) in the same radii on the
    line's other arm (the slice is a diameter: the same radii, the same program, the other
    side of the axis)."""
    from render_inspect.core.errors import InputError
    from render_inspect.fit._profile import ProfileSpec, make_profile_target, profile_family
    from render_inspect.io import read_profile
    from render_inspect.pipeline._fit_profile import _axis_in_window, profile_window

    rows = []
    for c in data["cases"]:
        if (c["free"] != "process.feed_mm_per_min" or not c["one_family"]
                or c.get("feed_difference") is None):
            continue
        r0, r1 = c["radii_mm"]
        prof = read_profile(REAL / f"{c['part']}-WLI-2D.csv", units="um")
        scene = _scene(c["part"], False, c["free"])
        arms = {}
        for name, xc in (("fitted", c["centre_mm"]), ("other", -c["centre_mm"])):
            try:
                win = profile_window(prof, scene, at=(xc, 0.0), window_mm=c["window_mm"])
            except InputError:  # the measured profile does not reach these radii there
                arms[name] = {"centre_mm": xc, "period_um": None, "one_family": None}
                continue
            t = make_profile_target(prof.z[win["i0"]:win["i1"]], spacing=prof.spacing,
                                    lag=0, spec=ProfileSpec())
            fam = profile_family(t.z, prof.spacing,
                                 axis_at_mm=_axis_in_window(scene, win, 1.0 / t.peak))
            arms[name] = {"centre_mm": xc, "period_um": 1e3 / t.peak,
                          "one_family": bool(fam["one_family"])}
        weighted = program_feed(c["part"], r0, r1, "hann") * 1e3
        rows.append({"part": c["part"], "radii_mm": [r0, r1], "window_mm": c["window_mm"],
                     "programmed_feed_um": c["programmed_feed_um"],
                     "programmed_feed_weighted_um": weighted,
                     "fitted_feed_um": c["fitted_feed_um"],
                     "difference_weighted": c["fitted_feed_um"] / weighted - 1.0,
                     "period_fitted_arm_um": arms["fitted"]["period_um"],
                     "period_other_arm_um": arms["other"]["period_um"],
                     "other_arm_one_family": arms["other"]["one_family"],
                     "other_centre_mm": arms["other"]["centre_mm"],
                     "arms_ratio": (None if arms["other"]["period_um"] is None else
                                    arms["other"]["period_um"] / arms["fitted"]["period_um"]
                                    - 1.0)})
    return rows


def curvature_factor() -> float:
    """1 + R_n / R_s of the example scene: the marks' spacing along the radius over the tool
    centre's feed per revolution on its concave paraboloid (docs/fit.md)."""
    d = tomllib.loads(SCENE.read_text())
    return 1.0 + d["tool"]["nose_radius"] / abs(d["design"]["radius_x"])


def period_scan(part: str, window_mm: float, *, step_mm: float = 0.02,
                radii=(0.09, 0.43)) -> list:
    """Windows of ``window_mm`` moved along both arms of a slice, no fit: the marks' period
    (the fit's estimator) over the program's weighted step times :func:`curvature_factor`,
    less 1 (the excess a fit of the window would show, near enough)."""
    from render_inspect.core.errors import InputError
    from render_inspect.fit._profile import ProfileSpec, make_profile_target
    from render_inspect.io import read_profile
    from render_inspect.pipeline._fit_profile import profile_window

    prof = read_profile(REAL / f"{part}-WLI-2D.csv", units="um")
    scene = _scene(part, False, "process.feed_mm_per_min")
    k = curvature_factor()
    rows = []
    for r0 in np.arange(radii[0], radii[1] - window_mm + 1e-9, step_mm):
        r0 = round(float(r0), 4)
        r1 = round(r0 + window_mm, 4)
        row = {"radii_mm": [r0, r1]}
        for arm, sign in (("minus", -1.0), ("plus", 1.0)):
            try:
                win = profile_window(prof, scene, at=(sign * (r0 + r1) / 2, 0.0),
                                     window_mm=window_mm)
            except InputError:
                row[arm] = None
                continue
            ref = program_feed(part, *window_radii(prof, scene, win), "hann") * 1e3
            t = make_profile_target(prof.z[win["i0"]:win["i1"]], spacing=prof.spacing,
                                    lag=0, spec=ProfileSpec())
            row[arm] = 1e3 / t.peak / (ref * k) - 1.0
        rows.append(row)
    return rows


def scan_table(part: str, rows: list) -> str:
    def pc(v):
        return "n/a" if v is None else f"{100 * v:+.1f} %"

    return "\n".join([f"| {part}: radii (mm) | arm at negative positions | arm at positive "
                       f"positions |", "|---|---|---|"]
                      + [f"| {r['radii_mm'][0]:.2f}-{r['radii_mm'][1]:.2f} | {pc(r['minus'])} "
                         f"| {pc(r['plus'])} |" for r in rows])


def checks_table(rows: list) -> str:
    lines = ["| part | radii (mm) | programmed (um/rev): over the radii / weighted as the fit "
             "reads | fitted (um/rev) | difference against the weighted step | period, "
             "fitted arm (um) | period, other arm (um) | arms differ by |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        prog = ("10 (by its name)" if r["part"] == "1016" else
                f"{r['programmed_feed_um']:.4g} / {r['programmed_feed_weighted_um']:.4g}")
        if r["period_other_arm_um"] is None:
            other, ratio = "n/a (the slice does not reach these radii)", "n/a"
        else:
            other = f"{r['period_other_arm_um']:.4g}" + ("" if r["other_arm_one_family"]
                                                          else " (not one family)")
            ratio = f"{100 * r['arms_ratio']:+.1f} %"
        lines.append(f"| {r['part']} | {r['radii_mm'][0]:.2f}-{r['radii_mm'][1]:.2f} | {prog} "
                     f"| {r['fitted_feed_um']:.4g} | {100 * r['difference_weighted']:+.1f} % "
                     f"| {r['period_fitted_arm_um']:.4g} | {other} | {ratio} |")
    return "\n".join(lines)


def measured_radii(part: str, xc: float, w: float, free: str, program: bool) -> list:
    """The radii (mm) a case's window covers (:func:`window_radii`)."""
    from render_inspect.io import read_profile
    from render_inspect.pipeline._fit_profile import profile_window

    prof = read_profile(REAL / f"{part}-WLI-2D.csv", units="um")
    scene = _scene(part, program, free)
    return window_radii(prof, scene, profile_window(prof, scene, at=(xc, 0.0), window_mm=w))


def references(data: dict) -> None:
    """Each window's radii and programmed feed (and the fitted feed's difference from it)
    taken again from the files, in place: no fit."""
    for c in data["cases"]:
        if c["through_axis"]:
            continue
        c["radii_mm"] = measured_radii(c["part"], c["centre_mm"], c["window_mm"], c["free"],
                                       c["program"])
        c["programmed_feed_um"] = program_feed(c["part"], *c["radii_mm"]) * 1e3
        if c.get("fitted_feed_um") and c["programmed_feed_um"]:
            c["feed_difference"] = c["fitted_feed_um"] / c["programmed_feed_um"] - 1.0
        detail = c.get("one_arm")
        if isinstance(detail, dict) and detail.get("fitted_feed_um"):
            detail["feed_difference"] = detail["fitted_feed_um"] / c["programmed_feed_um"] - 1.0


def _scene(part: str, program: bool, free: str):
    from render_inspect.scene import scene_from_dict

    d = tomllib.loads(SCENE.read_text())
    d["render"]["interferometer"]["mode"] = "csi"
    if program:
        d["process"]["program"] = str((REAL / PROGRAMS[part]).resolve())
    else:
        d["process"].pop("program", None)
        d["process"]["feed_mm_per_min"] = (FEED_1016 if part == "1016" else 0.0396) * RPM
    return scene_from_dict(d, f"turned {part}")


def _case_key(text: str) -> str:
    part, xc = text.split(":")
    return f"{part}:{float(xc):+.2f}"


def case_id(part: str, xc: float, free: str) -> str:
    return f"{part}:{xc:+.2f}:{free}"


#: the fields of a one-arm row kept as ``one_arm`` of its both-arms row
ONE_ARM_FIELDS = ("fitted_feed_um", "fitted_feed_stderr_um", "feed_difference", "value",
                  "stderr", "status", "evaluations", "misfit_over_noise")


def arms_available(part, xc, w, free, program):
    """Whether ``fit`` fits the window on both arms by default (no fit): (bool, why not)."""
    from render_inspect.fit._profile import ProfileSpec, make_profile_target
    from render_inspect.io import read_profile
    from render_inspect.pipeline._fit_profile import profile_window
    from render_inspect.pipeline._fit_profile_arms import other_arm_window

    prof = read_profile(REAL / f"{part}-WLI-2D.csv", units="um")
    scene = _scene(part, program, free)
    win = profile_window(prof, scene, at=(xc, 0.0), window_mm=w)
    t = make_profile_target(prof.z[win["i0"]:win["i1"]], spacing=prof.spacing, lag=0,
                            spec=ProfileSpec())
    other, why = other_arm_window(prof, scene, win, None if not t.peak else 1.0 / t.peak)
    return other is not None, why


def run(out_root: Path, *, only=None, old=None, one_arm_from_json: bool = False) -> dict:
    """Fit the cases (those ``only`` names, ``PART:CENTRE``; the others kept from ``old``,
    the json's previous rows).  A window fitted on both arms is fitted on its own arm too
    (``--arms one``), or, with ``one_arm_from_json``, that fit is taken from ``old``'s row
    of the case where it was a one-arm fit (the same fit: ``--arms one`` runs what a
    profile fit ran before both arms were used)."""
    old_rows = {case_id(r["part"], r["centre_mm"], r["free"]): r
                for r in (old or {}).get("cases", [])}
    rows = []
    for part, xc, w, free, program in CASES:
        cid = case_id(part, xc, free)
        prev = old_rows.get(cid)
        if only is not None and f"{part}:{xc:+.2f}" not in only and prev is not None:
            if "arms" not in prev:
                both, why = arms_available(part, xc, w, free, program)
                if both:
                    print(f"{cid}: the json's row is a one-arm fit, the default now fits both "
                          f"arms: run it again (--only)", file=sys.stderr)
                prev = dict(prev, arms="one", arms_why=why or "a fit of one arm")
            rows.append(prev)
            continue
        row = fit_case(out_root, part, xc, w, free, program)
        if row.get("arms") == "both":
            if (one_arm_from_json and prev is not None and prev.get("arms", "one") == "one"):
                row["one_arm"] = {k: prev.get(k) for k in ONE_ARM_FIELDS}
                row["one_arm"]["from"] = "the json's previous row (a fit of one arm)"
            elif one_arm_from_json and prev is not None and prev.get("one_arm"):
                row["one_arm"] = prev["one_arm"]
            else:
                one = fit_case(out_root, part, xc, w, free, program, arms="one")
                row["one_arm"] = {k: one.get(k) for k in ONE_ARM_FIELDS}
        rows.append(row)
        print(json.dumps(row), flush=True)
    return {"cases": rows, "nominal_nose_radius_mm": 0.2,
            "command": "python tools/profile_fit_numbers.py"}


def fit_case(out_root: Path, part, xc, w, free, program, *, arms=None) -> dict:
    """One case's fit (``arms``: None for the default, both arms where available) and its
    row of the json."""
    from render_inspect.pipeline import run_fit_profile

    scene = _scene(part, program, free)
    how = "one" if arms == "one" or not arms_available(part, xc, w, free, program)[0] else "both"
    out = out_root / (f"{part}_{xc:+.2f}_{free.split('.')[-1]}"
                      + ("" if arms is None else f"_{arms}"))
    rec = run_fit_profile(REAL / f"{part}-WLI-2D.csv", scene, [free], out, units="um",
                          at=(xc, 0.0), window_mm=w, global_points=0,
                          max_evaluations=MAX_EVALUATIONS[how], profile_points=0,
                          overwrite=True,
                          cache=out_root / "cache" / out.name, arms=arms)
    r0, r1 = sorted((abs(xc) - w / 2, abs(xc) + w / 2))
    par = rec["parameters"][free]
    if r0 >= 0:
        r0, r1 = measured_radii(part, xc, w, free, program)
    fpr = rec.get("feed_per_rev_mm") or {}
    fam = rec["model_check"]["before"]["family"]
    row = {"part": part, "centre_mm": xc, "window_mm": w, "radii_mm": [r0, r1],
           "free": free, "program": program,
           "through_axis": r0 < 0,
           "programmed_feed_um": (None if r0 < 0 else program_feed(part, r0, r1) * 1e3),
           "measured_period_um": rec["model_check"]["before"]["measured_period_um"],
           "halves_period_um": [None if p is None else p * 1e3
                                for p in fam["periods_mm"]],
           "one_family": rec["one_family"], "reason": fam["reason"],
           "status": rec["status"], "value": par["value"], "stderr": par["stderr"],
           "fitted_feed_um": None if not fpr else fpr["value"] * 1e3,
           "fitted_feed_stderr_um": (None if not fpr or fpr.get("stderr") is None
                                     else fpr["stderr"] * 1e3),
           "misfit_over_noise": rec["model_check"]["after"]["misfit_over_noise"],
           "evaluations": rec["evaluations"]}
    if row["fitted_feed_um"] and row["programmed_feed_um"]:
        row["feed_difference"] = row["fitted_feed_um"] / row["programmed_feed_um"] - 1.0
    row["max_evaluations"] = MAX_EVALUATIONS[how]
    arms_rec = rec.get("arms") or {}
    row["arms"] = arms_rec.get("fitted", "one")
    row["arms_why"] = arms_rec.get("why")
    if row["arms"] == "both":
        row["arms_detail"] = arms_detail(arms_rec, free, rec)
    return row


def arms_detail(arms_rec: dict, free: str, rec: dict) -> dict:
    """The json's account of a both-arms fit: each arm's stretch, periods and own estimate
    (um/rev for the feed), their disagreement and the standard error's parts."""
    k = 1e3 / RPM if free == "process.feed_mm_per_min" else 1.0
    par = arms_rec.get("parameters", {}).get(free)
    out = {"arms": [{"arm": a["arm"], "radii_mm": a["radii_mm"],
                     "centre_mm": a["centre_on_part_mm"][0],
                     "measured_period_um": a["measured_period_um"],
                     "fitted_period_um": a["fitted_period_um"],
                     "misfit": sum(a["misfit_terms"].values())} for a in arms_rec["arms"]],
           "unit": "um/rev" if free == "process.feed_mm_per_min" else "mm",
           "error": arms_rec.get("estimates_error")}
    if par is not None:
        p = rec["parameters"][free]
        out.update({"window_arm": par["window_arm"]["value"] * k,
                    "window_arm_stderr": par["window_arm"]["stderr"] * k,
                    "other_arm": par["other_arm"]["value"] * k,
                    "other_arm_stderr": par["other_arm"]["stderr"] * k,
                    "difference_relative": par["difference_relative"],
                    "difference_over_stderr": par["difference_over_stderr"],
                    "disagree": par["disagree"],
                    "u_arms": par["u_arms"] * k,
                    "stderr_fit": par["stderr_fit"] * k,
                    "stderr": None if p.get("stderr") is None else p["stderr"] * k})
    return out


def _f(v, fmt="{:.4g}"):
    return "n/a" if v is None else fmt.format(v)


def arms_cell(r: dict) -> str:
    if r.get("arms") == "both":
        return "both"
    why = r.get("arms_why")
    return "one" + ("" if not why else f" ({why})")


def one_arm_cell(r: dict) -> str:
    """The single-arm fit of a window fitted on both arms (the same fit as before both arms
    were used)."""
    o = r.get("one_arm")
    if r.get("arms") != "both" or not o:
        return "(a fit of one arm)"
    if o.get("fitted_feed_um") is None:
        return "n/a"
    text = _f(o["fitted_feed_um"]) + ("" if o.get("fitted_feed_stderr_um") is None else
                                       f" +- {o['fitted_feed_stderr_um']:.2g}")
    if o.get("feed_difference") is not None:
        text += f" ({100 * o['feed_difference']:+.1f} %" + ("" if r["one_family"] else
                                                             ": not a measurement") + ")"
    return text


def arms_table(data: dict) -> str:
    """Each window fitted on both arms: the arms' periods, each arm's own estimate, their
    disagreement and the standard error's parts."""
    lines = ["| part | radii (mm) | period: window's arm / other arm (um) | window's arm's own "
             "estimate (um/rev) | other arm's own estimate (um/rev) | arms differ by | in "
             "standard errors of the difference | fit's standard error (um/rev) | from the "
             "arms (um/rev) | combined (um/rev) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in data["cases"]:
        a = r.get("arms_detail")
        if r.get("arms") != "both" or not a or a.get("window_arm") is None:
            continue
        w, o = a["arms"]
        if not r["one_family"]:
            # not a measurement: the arms' own values and their difference, no standard
            # error of any kind
            na = "n/a (not a measurement)"
            lines.append(
                f"| {r['part']} | {r['radii_mm'][0]:.2f}-{r['radii_mm'][1]:.2f} | "
                f"{_f(w['measured_period_um'])} / {_f(o['measured_period_um'])} | "
                f"{a['window_arm']:.4g} | {a['other_arm']:.4g} | "
                f"{100 * a['difference_relative']:+.1f} % | {na} | {na} | {na} | {na} |")
            continue
        lines.append(
            f"| {r['part']} | {r['radii_mm'][0]:.2f}-{r['radii_mm'][1]:.2f} | "
            f"{_f(w['measured_period_um'])} / {_f(o['measured_period_um'])} | "
            f"{a['window_arm']:.4g} +- {a['window_arm_stderr']:.2g} | "
            f"{a['other_arm']:.4g} +- {a['other_arm_stderr']:.2g} | "
            f"{100 * a['difference_relative']:+.1f} % | {a['difference_over_stderr']:.2g}"
            + (" (disagree)" if a["disagree"] else "") + f" | {a['stderr_fit']:.2g} | "
            f"{a['u_arms']:.2g} | " + ("n/a" if a["stderr"] is None else f"{a['stderr']:.2g}")
            + " |")
    return "\n".join(lines)


def table(data: dict) -> str:
    head = ("| part | window (radii, mm) | marks | measured period (um) | programmed feed "
            "(um/rev) | arms fitted | fitted (um/rev, or nose radius mm) | difference | "
            "the window's arm alone (um/rev) | status |\n"
            "|---|---|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in data["cases"]:
        rad = ("through the axis" if r["through_axis"] else
               f"{r['radii_mm'][0]:.2f}-{r['radii_mm'][1]:.2f}")
        marks = "one family" if r["one_family"] else "not one family: " + r["reason"]
        if r["free"] == "tool.nose_radius":
            fitted = (f"nose {r['value']:.4g} mm" + ("" if r["stderr"] is None else
                                                     f" +- {r['stderr']:.2g}")
                      + " (nominal 0.2; path from the program)")
            diff = f"{100 * (r['value'] / data['nominal_nose_radius_mm'] - 1):+.1f} % vs nominal"
        else:
            fitted = _f(r["fitted_feed_um"]) + ("" if r["fitted_feed_stderr_um"] is None
                                                 else f" +- {r['fitted_feed_stderr_um']:.2g}")
            if not r["one_family"]:
                fitted += " (no standard error: not a measurement)"
            diff = ("n/a" if r.get("feed_difference") is None
                    else f"{100 * r['feed_difference']:+.1f} %")
            if not r["one_family"] and r.get("feed_difference") is not None:
                diff = f"({diff}: not a measurement)"
        prog = ("n/a" if r["programmed_feed_um"] is None else
                f"{r['programmed_feed_um']:.4g}" + (" (by its name)" if r["part"] == "1016"
                                                     else ""))
        lines.append(f"| {r['part']} | {rad} | {marks} | {_f(r['measured_period_um'])} | "
                     f"{prog} | {arms_cell(r)} | {fitted} | {diff} | {one_arm_cell(r)} | "
                     f"{r['status']} |")
    feeds = [r for r in data["cases"] if r["free"] == "process.feed_mm_per_min"
             and r.get("feed_difference") is not None]
    one = [r for r in feeds if r["one_family"]]
    within = [r for r in one if abs(r["feed_difference"]) <= 0.02]
    out = [r for r in one if abs(r["feed_difference"]) > 0.02]
    lines.append("")
    lines.append(f"Where the window's marks are one family, the fitted feed per revolution is "
                 f"within 2 % of the program's in {len(within)} of {len(one)} windows ("
                 + ", ".join(f"{r['part']} {r['radii_mm'][0]:.2f}-{r['radii_mm'][1]:.2f} mm: "
                             f"{100 * r['feed_difference']:+.1f} %" for r in within) + ")"
                 + ("" if not out else "; not in " + ", ".join(
                     f"{r['part']} {r['radii_mm'][0]:.2f}-{r['radii_mm'][1]:.2f} mm "
                     f"({100 * r['feed_difference']:+.1f} %)" for r in out))
                 + ". Where they are not, the fit says so and gives no standard error.")
    return "\n".join(lines)


BEGIN, END = "<!-- profile-fit-table -->", "<!-- /profile-fit-table -->"
ARMS_BEGIN, ARMS_END = "<!-- profile-fit-arms -->", "<!-- /profile-fit-arms -->"
CHECKS_BEGIN, CHECKS_END = "<!-- profile-fit-checks -->", "<!-- /profile-fit-checks -->"
SCAN_BEGIN, SCAN_END = "<!-- profile-fit-scan -->", "<!-- /profile-fit-scan -->"
SLICES_BEGIN, SLICES_END = "<!-- profile-slices -->", "<!-- /profile-slices -->"
#: the slice whose windows are scanned along both arms, and the window's length (mm)
SCAN = ("1023", 0.2)


def _replace(text: str, begin: str, end: str, body: str) -> str:
    i, j = text.index(begin), text.index(end)
    return text[:i + len(begin)] + "\n" + body + "\n" + text[j:]


def write_docs(data: dict) -> None:
    for page in ("fit.md", "validation.md"):
        p = REPO / "docs" / page
        text = _replace(p.read_text(), BEGIN, END, table(data))
        if ARMS_BEGIN in text:
            text = _replace(text, ARMS_BEGIN, ARMS_END, arms_table(data))
        if data.get("checks") and CHECKS_BEGIN in text:
            text = _replace(text, CHECKS_BEGIN, CHECKS_END, checks_table(data["checks"]))
        if data.get("slices") and SLICES_BEGIN in text:
            text = _replace(text, SLICES_BEGIN, SLICES_END, slices_table(data["slices"]))
        if data.get("scan") and SCAN_BEGIN in text:
            text = _replace(text, SCAN_BEGIN, SCAN_END,
                            scan_table(data["scan"]["part"], data["scan"]["rows"]))
        p.write_text(text)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--docs", action="store_true", help="rewrite the tables from the json")
    ap.add_argument("--checks", action="store_true",
                    help="recompute the checks (no fits) into the json, and the tables")
    ap.add_argument("--out", default="out/profile_fits", help="the fits' output folders")
    ap.add_argument("--only", default=None, metavar="PART:CENTRE,...",
                    help="fit these cases again (e.g. 1023:-0.33), keep the others' rows")
    ap.add_argument("--one-arm-from-json", action="store_true",
                    help="for a window fitted on both arms, take its one-arm fit from the "
                         "json's previous row of the case instead of fitting it again")
    a = ap.parse_args(argv)
    if not a.docs:
        if not REAL.is_dir():
            print(f"{REAL} is absent", file=sys.stderr)
            return 1
        only = None if a.only is None else {_case_key(v) for v in a.only.split(",")}
        old = json.loads(JSON.read_text()) if JSON.is_file() else None
        data = old if a.checks else run(Path(a.out), only=only, old=old,
                                             one_arm_from_json=a.one_arm_from_json)
        references(data)
        data["checks"] = arm_checks(data)
        data["slices"] = slices()
        data["scan"] = {"part": SCAN[0], "window_mm": SCAN[1],
                        "curvature_factor": curvature_factor(),
                        "rows": period_scan(*SCAN)}
        JSON.write_text(json.dumps(data, indent=1) + "\n")
    write_docs(json.loads(JSON.read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
