"""``fit`` on the real turned slices: the feed per revolution fitted to windows of each
measured slice (``../shared/realdata/turned``), beside the feed the program gives at those
radii, and the nose radius fitted with the program's own path.

    python tools/profile_fit_numbers.py          # run the fits, write docs/fit_profiles.json
                                                 # and the tables in docs/fit.md and
                                                 # docs/validation.md
    python tools/profile_fit_numbers.py --docs   # rewrite the tables from the json alone

Each case is what ``render-inspect fit SLICE --units um --scene S --free KEY --at X,0
--window W`` runs, S being docs/examples/turned/scene.toml with the white-light virtual
instrument (the slices are white-light measurements) and, for the feed fits, without its
program (a planned spiral of one feed per revolution, whose feed is fitted).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tomllib
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
REAL = REPO / ".." / "shared" / "realdata" / "turned"
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
#: feed per revolution of 1016 by its program's name ("x0.01"), mm
FEED_1016 = 0.01
RPM = 100.0


def program_feed(part: str, r0: float, r1: float):
    """The program's mean X step per revolution (mm) between radii r0 < r1: the radial
    distance over the revolutions the C axis turns between them."""
    if part not in PROGRAMS:
        return FEED_1016
    xs, cs = [], []
    for line in open(REAL / PROGRAMS[part]):
        d = dict(re.findall(r"([CX])(-?[\d.]+)", line))
        if "C" in d and "X" in d:
            cs.append(float(d["C"]))
            xs.append(float(d["X"]))
    c = np.array(cs)
    x = np.array(xs)
    dc = np.diff(c)
    dc = np.where(dc < -180, dc + 360, np.where(dc > 180, dc - 360, dc))
    rev = np.concatenate([[0.0], np.cumsum(np.abs(dc))]) / 360.0
    order = np.argsort(x)
    ra, rb = np.interp([r0, r1], x[order], rev[order])
    return float((r1 - r0) / abs(ra - rb))


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


def run(out_root: Path) -> dict:
    from render_inspect.pipeline import run_fit_profile

    rows = []
    for part, xc, w, free, program in CASES:
        scene = _scene(part, program, free)
        out = out_root / f"{part}_{xc:+.2f}_{free.split('.')[-1]}"
        rec = run_fit_profile(REAL / f"{part}-WLI-2D.csv", scene, [free], out, units="um",
                              at=(xc, 0.0), window_mm=w, global_points=0,
                              max_evaluations=40, profile_points=0, overwrite=True,
                              cache=out_root / "cache" / out.name)
        r0, r1 = sorted((abs(xc) - w / 2, abs(xc) + w / 2))
        par = rec["parameters"][free]
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
        rows.append(row)
        print(json.dumps(row), flush=True)
    return {"cases": rows, "nominal_nose_radius_mm": 0.2,
            "command": "python tools/profile_fit_numbers.py"}


def _f(v, fmt="{:.4g}"):
    return "n/a" if v is None else fmt.format(v)


def table(data: dict) -> str:
    head = ("| part | window (radii, mm) | marks | measured period (um) | programmed feed "
            "(um/rev) | fitted (um/rev, or nose radius mm) | difference | status |\n"
            "|---|---|---|---|---|---|---|---|")
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
                     f"{prog} | {fitted} | {diff} | {r['status']} |")
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


def write_docs(data: dict) -> None:
    for page in ("fit.md", "validation.md"):
        p = REPO / "docs" / page
        text = p.read_text()
        i, j = text.index(BEGIN), text.index(END)
        p.write_text(text[:i + len(BEGIN)] + "\n" + table(data) + "\n" + text[j:])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--docs", action="store_true", help="rewrite the tables from the json")
    ap.add_argument("--out", default="out/profile_fits", help="the fits' output folders")
    a = ap.parse_args(argv)
    if not a.docs:
        if not REAL.is_dir():
            print(f"{REAL} is absent", file=sys.stderr)
            return 1
        data = run(Path(a.out))
        JSON.write_text(json.dumps(data, indent=1) + "\n")
    write_docs(json.loads(JSON.read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
