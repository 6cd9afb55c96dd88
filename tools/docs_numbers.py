"""Every number the documentation quotes from a run of the package, made by one script.

    python tools/docs_numbers.py                # every run; writes docs/numbers.json and the docs
    python tools/docs_numbers.py --only grid    # some runs (the other numbers are kept)
    python tools/docs_numbers.py --docs         # only rewrite the docs from docs/numbers.json
    python tools/docs_numbers.py --check        # exit 1 if a doc differs from docs/numbers.json
    python tools/docs_numbers.py --list         # the runs and the numbers each makes

A number in README.md or docs/*.md that a run produces is written between markers,

    the compensated path still cuts <!-- n:fig16.min_a -->-20.9<!-- /n --> nm deep

and this script replaces the text between them with the run's value (a marker may also
hold a whole block, such as a command's printed summary).  ``docs/numbers.json`` keeps
each number with its value, its text, the run that made it and what that run is.
``tests/test_docs_numbers.py`` checks that every marked span equals ``docs/numbers.json``
(fast) and re-runs the cheap runs against it (slow).  Benchmark figures (times, rates,
memory) are not here: ``docs/benchmarks.md`` has its own generator (``make bench``).

Each run is a function of nothing but the shipped scenes and the package: the same
commands a user would type (``compare``, ``simulate``, ``render`` + ``measure``), through
the package's Python API.  After a change that moves the results, run this script and
commit ``docs/numbers.json`` with the docs.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import io
import json
import math
import os
import re
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

REPO = Path(__file__).resolve().parents[1]
NUMBERS_JSON = REPO / "docs" / "numbers.json"
#: a marked number: <!-- n:KEY -->TEXT<!-- /n -->
SPAN = re.compile(r"<!-- n:([A-Za-z0-9_.\-]+) -->(.*?)<!-- /n -->", re.S)


def doc_files() -> list[Path]:
    """The documents whose marked numbers this script writes."""
    return [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def fmt(value, spec: str = ".3g") -> str:
    """A number as the docs write it: ``spec`` (a format spec; ``.3g`` by default), with
    no ``-0``, and thousands without exponent."""
    if isinstance(value, str):
        return value
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "n/a"
    text = format(float(value), spec)
    if "e" in text and spec.endswith("g"):
        text = format(float(value), ".0f")
    if re.fullmatch(r"-0(\.0*)?", text):
        text = text[1:]
    return text


@dataclass
class Run:
    """One run of the package: ``about`` says what is run (written into numbers.json);
    ``make`` runs it and returns ``{key: (value, format spec)}`` (or ``{key: text}``);
    ``cheap`` runs are re-run by the slow test."""

    name: str
    about: str
    make: Callable[[], dict]
    cheap: bool = False


# ----------------------------------------------------------------------------- the runs
def _simulate(scene_name: str, overrides=()) -> dict:
    from render_inspect.pipeline import simulate
    from render_inspect.scene import load_scene

    return simulate(load_scene(scene_name, list(overrides))).metrics


GRID_IDEAL = ["machine.preset='ideal'", "material.preset='ideal'"]


def run_grid() -> dict:
    """Li et al. (2018) sinusoidal grid: the commanded geometry, the lathe, lathe and
    material (simulate, 1 x 1 mm at the centre, 1 um)."""
    ideal = _simulate("sts_sinusoidal_grid", GRID_IDEAL)
    lathe = _simulate("sts_sinusoidal_grid", ["material.preset='ideal'"])
    full = _simulate("sts_sinusoidal_grid")
    off = _simulate("sts_sinusoidal_grid", GRID_IDEAL + ["simulation.region=[0.5,0.5,1.4,1.4]"])
    return {"grid.sq_ideal": (ideal["residual"]["Sq_nm"], ".3g"),
            "grid.sq_offaxis_ideal": (off["residual"]["Sq_nm"], ".3g"),
            "grid.sq_lathe": (lathe["residual"]["Sq_nm"], ".3g"),
            "grid.sq": (full["residual"]["Sq_nm"], ".3g")}


def _summary_text(metrics: dict, seconds: float) -> str:
    """The summary ``compare`` prints, as a user sees it (80 columns)."""
    from render_inspect import cli

    shown = dict(metrics, report="/path/to/out/report.html")
    buf = io.StringIO()
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "100"
    try:
        with contextlib.redirect_stdout(buf):
            cli._print_compare_summary(shown, "/path/to/out", seconds)
    finally:
        if old is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(line.rstrip() for line in buf.getvalue().splitlines())


def _compare(scene_name: str, overrides=()) -> tuple[dict, float]:
    from render_inspect.pipeline import run_compare
    from render_inspect.scene import load_scene

    with tempfile.TemporaryDirectory(prefix="docs_numbers_") as tmp:
        t0 = time.perf_counter()
        m = run_compare(load_scene(scene_name, list(overrides)), Path(tmp) / "out")
        return m, time.perf_counter() - t0


def run_fig16() -> dict:
    """Li et al. (2018), Fig. 16: ``render-inspect compare sts_fig16_overcut`` as shipped."""
    from render_inspect.core.units import MM_TO_UM

    m, seconds = _compare("sts_fig16_overcut")
    a, b = (v["name"] for v in m["variants"])
    d, w = m["difference"], m["difference"]["window"]
    f = m["filters"]
    # a block: the markers on lines of their own, around the fenced text
    out = {"fig16.summary": "\n```\n" + _summary_text(m, seconds) + "\n```\n"}
    for tag, v in (("a", a), ("b", b)):
        out.update({f"fig16.min_{tag}": (m[v]["residual"]["min_nm"], ".3g"),
                    f"fig16.sq_{tag}": (m[v]["residual"]["Sq_nm"], ".3g"),
                    f"fig16.wav_sq_{tag}": (m[v]["filtered"].get("Sq_nm"), ".3g"),
                    f"fig16.err_rms_{tag}": (m[v]["measured"].get("rms_nm"), ".3g"),
                    f"fig16.inst_sq_{tag}": (m[v]["measured"].get("instrument_residual_Sq_nm"), ".3g"),
                    f"fig16.true_sq_{tag}": (m[v]["measured"].get("true_residual_Sq_nm"), ".3g")})
    out.update({"fig16.min_b_rounded": (m[b]["residual"]["min_nm"], ".0f"),
                "fig16.diff_rms": (d.get("machined_rms_nm"), ".3g"),
                "fig16.diff_pv": (d.get("machined_pv_nm"), ".3g"),
                "fig16.win_true_rms": ((w.get("true") or {}).get("rms_nm"), ".3g"),
                "fig16.win_true_pv": ((w.get("true") or {}).get("pv_nm"), ".3g"),
                "fig16.win_meas_rms": ((w.get("measured") or {}).get("rms_nm"), ".3g"),
                "fig16.win_meas_pv": ((w.get("measured") or {}).get("pv_nm"), ".3g"),
                "fig16.s_filter_um": (f["s_filter_mm"] * MM_TO_UM, ".3g"),
                "fig16.cut_mm": (f.get("cut_mm"), ".3g")})
    budget = m[a].get("overcut") or {}
    if budget:
        out["fig16.budget_geometry_a"] = (budget.get("geometry_nm"), ".2g")
        for k, v in (budget.get("alone_nm") or {}).items():
            out[f"fig16.budget_{k}_a"] = (v, ".3g")
    return out


def run_filters() -> dict:
    """The S-filters ``compare`` chooses from each scene's feed marks
    (``metrology.waviness_choice``): no simulation."""
    from render_inspect.core.units import MM_TO_UM
    from render_inspect.metrology import waviness_choice
    from render_inspect.processes import process_of
    from render_inspect.scene import load_scene

    out = {}
    for key, name in (("grid", "sts_sinusoidal_grid"), ("fig16", "sts_fig16_overcut"),
                      ("hts", "hts_toric_msa")):
        sc = load_scene(name)
        p = process_of(sc)
        marks = p.traits(p.inputs_of(sc)).marks
        x0, y0, x1, y1 = sc.simulation.region
        f = waviness_choice(marks, sc.design, sc.metrology, pixel=sc.simulation.pixel,
                            window_mm=(x1 - x0, y1 - y0))
        out[f"filters.{key}_s_um"] = (f["s_filter_mm"] * MM_TO_UM, ".3g")
        if key != "hts":
            out[f"filters.{key}_s_per_feed"] = (f["s_filter_mm"] / marks.period_mm, ".2g")
        out[f"filters.{key}_a1_nm"] = (f["mark_first_harmonic_nm"], ".3g")
    return out


def run_instrument() -> dict:
    """Li et al. (2018) grid through the virtual 20x microscope: the commanded geometry
    simulated on a 0.25 um grid around the centre, imaged over a 0.3 x 0.3 mm field by
    PSI (550/10 nm, 4 frames) and CSI (600/120 nm), measured from the frames alone; the Sq
    of measured - design next to the truth's on the same pixels."""
    import numpy as np

    from render_inspect.design import make_surface
    from render_inspect.instruments import height_instrument
    from render_inspect.metrology import areal_nm, measure_frames
    from render_inspect.pipeline import simulate
    from render_inspect.scene import load_scene

    field = (-0.15, -0.15, 0.15, 0.15)
    sc = load_scene("sts_sinusoidal_grid", GRID_IDEAL + [
        "simulation.region=[-0.16,-0.16,0.16,0.16]", "simulation.pixel=0.00025"])
    hm = simulate(sc).heightmap
    inside = ((hm.x[None, :] >= field[0]) & (hm.x[None, :] <= field[2])
              & (hm.y[:, None] >= field[1]) & (hm.y[:, None] <= field[3]))
    out = {"instrument.sim_sq": (areal_nm(np.where(inside, hm.residual, np.nan),
                                          hm.pixel)["Sq_nm"], ".3g")}
    surface = make_surface(sc.design)
    entry = height_instrument()
    base = sc.render.interferometer.model_copy(update={"objective": "20x", "field_of_view": field})
    for tag, mode, refine in (("psi", "psi", None), ("csi", "csi", "phase"),
                              ("csi_envelope", "csi", "envelope")):
        ig = entry.render(hm, base.model_copy(update={"mode": mode}), surface="machined", seed=0)
        res = measure_frames(ig, csi_refine=refine) if refine else measure_frames(ig)
        xx, yy = np.meshgrid(ig.x, ig.y)
        design = surface.height(xx, yy)
        meas = np.where(res.valid, res.height - design, np.nan)
        sq_m = areal_nm(meas - np.nanmean(meas), ig.pixel)["Sq_nm"]
        out[f"instrument.{tag}_sq"] = (sq_m, ".3g")
        if tag == "psi":
            true = np.where(res.valid, ig.height_true - design, np.nan)
            sq_t = areal_nm(true, ig.pixel)["Sq_nm"]
            out["instrument.true_sq"] = (sq_t, ".3g")
        out[f"instrument.{tag}_ratio"] = (sq_m / out["instrument.true_sq"][0], ".2f")
    return out


def _about(fn) -> str:
    """The first paragraph of a run's docstring, on one line."""
    return " ".join(fn.__doc__.split("\n\n")[0].split()).replace("``", "`")


RUNS = {r.name: r for r in (
    Run("grid", _about(run_grid), run_grid, cheap=True),
    Run("filters", _about(run_filters), run_filters, cheap=True),
    Run("fig16", _about(run_fig16), run_fig16),
    Run("instrument", _about(run_instrument), run_instrument),
)}


# ----------------------------------------------------------------------------- the files
def load_numbers(path: Path = NUMBERS_JSON) -> dict:
    if not path.is_file():
        return {"runs": {}, "numbers": {}}
    return json.loads(path.read_text())


def make(names, data: dict) -> dict:
    """Run ``names`` and put their numbers into ``data`` (numbers of other runs kept)."""
    from render_inspect import __version__

    for name in names:
        run = RUNS[name]
        print(f"docs_numbers: {name}: {run.about}", file=sys.stderr)
        t0 = time.perf_counter()
        got = run.make()
        data["numbers"] = {k: v for k, v in data.get("numbers", {}).items() if v.get("run") != name}
        for key, item in got.items():
            value, spec = (item, None) if isinstance(item, str) else item
            data["numbers"][key] = {"text": fmt(value, spec or ".3g"),
                                    "value": value if not isinstance(value, str) else None,
                                    "run": name}
        data.setdefault("runs", {})[name] = {
            "about": run.about, "seconds": round(time.perf_counter() - t0, 1),
            "date": datetime.date.today().isoformat(), "software_version": __version__}
    data["numbers"] = dict(sorted(data["numbers"].items()))
    return data


def write_numbers(data: dict, path: Path = NUMBERS_JSON) -> None:
    for name, run in data.get("runs", {}).items():
        if name in RUNS:
            run["about"] = RUNS[name].about
    path.write_text(json.dumps(data, indent=2, sort_keys=True, allow_nan=False) + "\n")


def rewrite(text: str, numbers: dict) -> tuple[str, list[str]]:
    """``text`` with every marked span replaced by its number; and the unknown keys."""
    unknown = []

    def sub(m):
        key = m.group(1)
        if key not in numbers:
            unknown.append(key)
            return m.group(0)
        return f"<!-- n:{key} -->{numbers[key]['text']}<!-- /n -->"

    return SPAN.sub(sub, text), unknown


def spans(text: str) -> list[tuple[str, str]]:
    """The (key, text) of every marked span."""
    return SPAN.findall(text)


def write_docs(data: dict) -> list[str]:
    """Rewrite the marked spans of every doc; returns the unknown keys."""
    unknown = []
    for doc in doc_files():
        text = doc.read_text()
        new, bad = rewrite(text, data["numbers"])
        unknown += [f"{doc.relative_to(REPO)}: {k}" for k in bad]
        if new != text:
            doc.write_text(new)
    return unknown


def check(data: dict) -> list[str]:
    """Every marked span that differs from ``data`` (or names no number)."""
    bad = []
    for doc in doc_files():
        for key, text in spans(doc.read_text()):
            n = data["numbers"].get(key)
            if n is None:
                bad.append(f"{doc.relative_to(REPO)}: {key} is not in docs/numbers.json")
            elif n["text"] != text:
                bad.append(f"{doc.relative_to(REPO)}: {key} says {text!r}, the run gave {n['text']!r}")
    return bad


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", nargs="+", choices=sorted(RUNS), help="runs to make")
    ap.add_argument("--docs", action="store_true", help="only rewrite the docs from numbers.json")
    ap.add_argument("--check", action="store_true", help="exit 1 if a doc differs from numbers.json")
    ap.add_argument("--list", action="store_true", help="the runs and their numbers")
    args = ap.parse_args(argv)
    data = load_numbers()
    if args.list:
        for name, run in RUNS.items():
            keys = [k for k, v in data.get("numbers", {}).items() if v.get("run") == name]
            print(f"{name}{' (cheap)' if run.cheap else ''}: {run.about}\n    " + ", ".join(keys))
        return 0
    if args.check:
        bad = check(data)
        print("\n".join(bad) or "every marked number is current", file=sys.stderr if bad else sys.stdout)
        return 1 if bad else 0
    if not args.docs:
        data = make(args.only or list(RUNS), data)
    write_numbers(data)
    unknown = write_docs(data)
    if unknown:
        print("marked spans without a number:\n  " + "\n  ".join(unknown), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    sys.exit(main())
