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

The shipped scenes next to their papers (``papers_li``, ``papers``) are made with the
functions of ``tools/paper_comparison.py`` (which prints the same comparison as a table).
The runs marked cheap (seconds to a minute each) are what the slow test makes again; the
whole script takes about half an hour on a busy 2-core machine (each run's time is kept in
``docs/numbers.json``).  Not here: the Morris sensitivity results of
docs/machine_and_material.md, which come from the ``sensitivity_*`` sweeps (tens of
minutes each) and are updated by hand.
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
    """The documents whose marked numbers this script writes (docs/validation.md has its
    own script, tools/validation_numbers.py, and docs/validation.json)."""
    return [REPO / "README.md", *sorted(p for p in (REPO / "docs").glob("*.md")
                                        if p.name not in OWN_SCRIPT)]


#: docs whose marked numbers another script writes
OWN_SCRIPT = {"validation.md"}


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
    from render_inspect.design import make_surface
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
        f = waviness_choice(marks, make_surface(sc.design), sc.metrology, pixel=sc.simulation.pixel,
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


_SIMS: dict = {}


def _sim(scene_name: str, overrides=()):
    """``simulate`` of a shipped scene with overrides, kept for the other runs of the
    same invocation (the paper comparison and the paper runs share their simulations)."""
    from render_inspect.pipeline import simulate
    from render_inspect.scene import load_scene

    key = (scene_name, tuple(overrides))
    if key not in _SIMS:
        _SIMS.clear()  # one at a time: the maps are large
        _SIMS[key] = simulate(load_scene(scene_name, list(overrides)))
    return _SIMS[key]


def _paper_comparison():
    """``tools/paper_comparison.py`` as a module (the tools are scripts, not a package)."""
    import importlib.util

    if "paper_comparison" not in sys.modules:
        spec = importlib.util.spec_from_file_location("paper_comparison",
                                                      REPO / "tools" / "paper_comparison.py")
        mod = importlib.util.module_from_spec(spec)
        sys.modules["paper_comparison"] = mod
        spec.loader.exec_module(mod)
    return sys.modules["paper_comparison"]


def _range(values, spec: str) -> str:
    """``lo-hi`` of ``values`` in ``spec`` (one number when they print alike)."""
    lo, hi = fmt(min(values), spec), fmt(max(values), spec)
    return lo if lo == hi else f"{lo}-{hi}"


#: the windows of Li et al. (2018) that the paper measured, by the key of their numbers
LI_WINDOWS = {"grid_centre": ("sts_sinusoidal_grid", "scene (centre)"),
              "grid_offaxis": ("sts_sinusoidal_grid", "off axis"),
              "mla": ("sts_mla_2x2", "scene (lenslet rim)")}
#: the other shipped scenes compared (their paper gives no like-with-like value)
OTHER_WINDOWS = {"fig16": "sts_fig16_overcut", "compound": "compound_sinusoid",
                 "rcse": "rcse_circular_array", "sculpt": "sculpt_quad_mla", "hts": "hts_toric_msa"}
#: the illumination NA of the stopped-down objective
STOPPED_NA = 0.3


def _comparison_numbers(prefix: str, res: dict) -> dict:
    """Raw and instrument Sq / Sa as the table writes them: two decimals, one from 100 nm;
    and each to three figures (``..._3g``) for the text."""
    out = {}
    for key, name in (("raw_sq", "raw_Sq_nm"), ("raw_sa", "raw_Sa_nm"),
                      ("inst_sq", "instrument_Sq_nm"), ("inst_sa", "instrument_Sa_nm")):
        v = res[name]
        out[f"{prefix}.{key}"] = (v, ".1f" if abs(v) >= 100 else ".2f")
        out[f"{prefix}.{key}_3g"] = (v, ".3g")
    out[f"{prefix}.raw_sq_short"] = (res["raw_Sq_nm"], ".2g")
    return out


def run_papers_li() -> dict:
    """Li et al. (2018) compared like with like (`tools/paper_comparison.py`): the shipped
    grid (1 mm at the centre, 0.9 mm off the axis) and 2 x 2 MLA simulated, the residual
    raw and through the 20x objective's transfer function (filled pupil and stopped down
    to NA 0.3), the camera pixel and a poly2 form removal; the ideal scallop the same way;
    the transfer function at the feed's 100 and 200 cycles/mm; the spread of the instrument Sq
    over the instrument settings the paper does not give (its uncertainty) and whether the
    paper's band can discriminate."""
    from render_inspect.instruments import Microscope, led

    pc = _paper_comparison()
    out, above, raw, lows, highs, verdicts = {}, [], [], [], [], []
    for key, (name, label) in LI_WINDOWS.items():
        spec = pc.PAPERS[name]
        sim = _sim(name, spec["windows"][label])
        res = pc.compare_sim(sim)
        out.update(_comparison_numbers(f"papers.{key}", res))
        sq = res["instrument_Sq_nm"]
        out[f"papers.{key}.sigma"] = (abs(sq - spec["value"]) / spec["sd"], ".1f")
        out[f"papers.{key}.above_band"] = (sq - spec["value"] - spec["sd"], ".2f")
        stopped = pc.compare_sim(sim, illumination_na=STOPPED_NA)["instrument_Sq_nm"]
        out[f"papers.{key}.na03_sq"] = (stopped, ".2f")
        above.append(stopped - spec["value"] - spec["sd"])
        raw.append(res["raw_Sq_nm"])
        spread = pc.settings_spread(sim, value=spec["value"], sd=spec["sd"])
        out[f"papers.{key}.settings_range"] = _range([spread["lo_nm"], spread["hi_nm"]], ".3g")
        out[f"papers.{key}.settings_verdict"] = spread["verdict"]
        lows.append(spread["lo_nm"])
        highs.append(spread["hi_nm"])
        verdicts.append(spread["verdict"])
    out["papers.li_raw_sq_range"] = _range(raw, ".2g")
    out["papers.na03_above_band_range"] = _range(above, ".2f")
    out["papers.na03_above_band_range_short"] = _range(above, ".1f")
    out["papers.li_settings_range"] = _range([min(lows), max(highs)], ".3g")
    out["papers.li_settings_verdict"] = ("the band cannot discriminate"
                                         if "cannot discriminate" in verdicts
                                         else "the band discriminates")
    out["papers.settings_combinations"] = str(int(math.prod(
        [len(v) for v in pc.UNSTATED_SETTINGS.values()])))
    ideal_sim = _sim("sts_sinusoidal_grid", GRID_IDEAL)
    ideal = pc.compare_sim(ideal_sim)
    out["papers.ideal_grid_inst_sq"] = (ideal["instrument_Sq_nm"], ".3g")
    out["papers.ideal_grid_na03_sq"] = (
        pc.compare_sim(ideal_sim, illumination_na=STOPPED_NA)["instrument_Sq_nm"], ".3g")
    ideal_spread = pc.settings_spread(ideal_sim)
    out["papers.ideal_grid_settings_range"] = _range([ideal_spread["lo_nm"],
                                                      ideal_spread["hi_nm"]], ".3g")
    filled = Microscope(source=led(600.0, bandwidth_nm=120.0))
    stopped = Microscope(source=led(600.0, bandwidth_nm=120.0), illumination_na=STOPPED_NA)
    out["papers.itf_100"] = (float(filled.itf(100.0)), ".3f")
    out["papers.itf_200"] = (float(filled.itf(200.0)), ".2f")
    out["papers.itf_100_stopped"] = (float(stopped.itf(100.0)), ".2f")
    return out


def run_papers() -> dict:
    """The other shipped scenes next to their papers (`tools/paper_comparison.py`): each
    scene as shipped, the residual raw and through the 20x objective (filled pupil),
    the camera pixel and a poly2 form removal."""
    pc = _paper_comparison()
    out = {}
    for key, name in OTHER_WINDOWS.items():
        out.update(_comparison_numbers(f"papers.{key}", pc.compare_sim(_sim(name))))
    return out


RCSE_COMPLIANCES = (0.0, 0.02, 0.05, 0.1, 0.2, 0.5)


def run_rcse() -> dict:
    """The RCSE paper (2024): `rcse_circular_array` with `rcse.spread_elements = 10` (both
    paths cut on ten element fields through the `sts_lathe` and `al6061`): the X following
    errors, the mean Sa and its spread, at the preset's cross-compliance and over
    0-0.5 nm/N (`machine.coupling.{z,y}_compliance_nm_per_n`)."""
    from render_inspect.core.units import NM_TO_UM

    out, red = {}, []
    for c in RCSE_COMPLIANCES:
        tag = fmt(c, "g").replace(".", "p")
        over = ["rcse.spread_elements=10", f"machine.coupling.z_compliance_nm_per_n={c}",
                f"machine.coupling.y_compliance_nm_per_n={c}"]
        sp = _sim("rcse_circular_array", over).metrics["rcse"]["comparison"]["spread"]
        out[f"rcse.c{tag}.sa_rcse"] = (sp["rcse"]["Sa_mean_nm"], ".2f")
        out[f"rcse.c{tag}.sa_conv"] = (sp["conventional"]["Sa_mean_nm"], ".2f")
        out[f"rcse.c{tag}.sa_lower_pct"] = (sp["Sa_mean_reduction_percent"], ".1f")
        out[f"rcse.c{tag}.sd_lower_pct"] = (sp.get("Sa_sd_reduction_percent"), ".1f")
        if c == 0.1:  # the preset
            out["rcse.sa_reduction_pct"] = (sp["Sa_mean_reduction_percent"], ".0f")
            out["rcse.sd_reduction_pct"] = (sp.get("Sa_sd_reduction_percent"), ".0f")
            fe_r = sp["rcse"]["following_error"]["x_max_nm"]
            fe_c = sp["conventional"]["following_error"]["x_max_nm"]
            out["rcse.x_fe_rcse_nm"] = (fe_r, ".3g")
            out["rcse.x_fe_rcse_nm_short"] = (fe_r, ".2g")
            out["rcse.x_fe_conv_um"] = (fe_c * NM_TO_UM, ".2g")
        if c > 0:
            red.append(sp["Sa_mean_reduction_percent"])
    out["rcse.sa_reduction_range"] = f"{fmt(min(red), '.0f')} to {fmt(max(red), '.0f')}"
    return out


def run_rcse_ideal() -> dict:
    """The RCSE paper (2024), the commanded geometry (`machine.preset` and
    `material.preset` "ideal"): `rcse_circular_array` on the ring-4 element at 4 um
    pixels (0.4 mm window) and on the scene's window; the kinematics, profile errors and
    residuals of the RCSE and the conventional paths (`rcse.comparison`)."""
    from render_inspect.core.units import MM_TO_UM

    ideal = ["machine.preset='ideal'", "material.preset='ideal'"]
    out = {}
    small = ["simulation.region=[3.28,-0.2,3.68,0.2]", "simulation.pixel=0.004"]
    for tag, over in (("small", small),
                      ("scene", [])):
        m = _sim("rcse_circular_array", ideal + over).metrics
        c = m["rcse"]["comparison"]
        for path in ("rcse", "conventional"):
            short = "conv" if path == "conventional" else path
            r = c[path]["residual"]
            out[f"rcse_ideal.{tag}.{short}_sa"] = (r["Sa_nm"], "#.2g")
            out[f"rcse_ideal.{tag}.{short}_sz"] = (r["Sz_nm"], ".2g")
            out[f"rcse_ideal.{tag}.{short}_min"] = (r["min_nm"], ".3g" if tag == "small" else ".2g")
        if tag == "small":
            k, kc = c["rcse"], c["conventional"]
            out.update({
                "rcse_ideal.small.points": (m["toolpath"]["points"], ",.0f"),
                "rcse_ideal.small.rcse_vx_um_s": (k["x_velocity_max_mm_s"] * MM_TO_UM, ".2g"),
                "rcse_ideal.small.rcse_reversals": (k["x_reversals"], ".0f"),
                "rcse_ideal.small.conv_vx_mm_s": (kc["x_velocity_max_mm_s"], ".2g"),
                "rcse_ideal.small.conv_ax": f"{kc['x_acceleration_max_mm_s2'] / 1000:.2g}e3",
                "rcse_ideal.small.conv_reversals": (kc["x_reversals"], ",.0f"),
                "rcse_ideal.small.conv_profile_max": (kc["profile_error_max_nm"], ".2g"),
                "rcse_ideal.small.conv_profile_rms": (kc["profile_error_rms_nm"], ".1g")})
        else:
            out["rcse_ideal.scene.chordal_nm"] = (m["toolpath"]["chordal_error_max_nm"], ".2g")
    return out


def run_zhang() -> dict:
    """Zhang et al. (2022): `sculpt_quad_mla` on 3 x 3 lenslets at p / 40 pixels, with the
    104 kHz vibration, without it, and with an ideal material; a single lenslet's Sa and
    Sz after a degree-4 form removal over the middle cell, the largest burr, the contact
    ratio and the two overcuts (the shipped 10 x 10 array)."""
    from render_inspect.core.units import MM_TO_NM, MM_TO_UM
    from render_inspect.metrology._filters import remove_form
    from render_inspect.metrology._params import areal_parameters

    p = 0.19975
    cell_of = ["design.rows=3", "design.cols=3", f"simulation.pixel={p / 40}",
               f"simulation.region=[{-1.5 * p},{-1.5 * p},{1.5 * p},{1.5 * p}]"]

    def lenslet(over):
        sim = _sim("sculpt_quad_mla", cell_of + over)
        res = sim.heightmap.machined - sim.heightmap.design
        cell, _ = remove_form(res[42:79, 42:79], pixel=p / 40, method="polynomial", degree=4)
        a = areal_parameters(cell, pixel=p / 40)
        return a["Sa"] * MM_TO_NM, a["Sz"] * MM_TO_UM, sim.metrics

    sa, sz, m = lenslet([])
    out = {"zhang.sa_nm": (sa, ".3g"), "zhang.sa_nm_short": (sa, ".2g"), "zhang.sz_um": (sz, ".2g"),
           "zhang.burr_um": (m["burrs"]["max_added_um"], ".2f"),
           "zhang.contact_ratio": (m["material"]["contact_ratio"], ".2g")}
    sa0, _, m0 = lenslet(["artifacts.vibration.amplitude=0"])
    out["zhang.conv_sa_nm"] = (sa0, ".2f")
    out["zhang.conv_burr_um"] = (m0["burrs"]["max_added_um"], ".2f")
    sa_i, _, _ = lenslet(["material.preset='ideal'"])
    out["zhang.ideal_sa_nm"] = (sa_i, ".1f")
    out["zhang.unexplained_nm"] = (math.sqrt(max(4.0 ** 2 - sa ** 2, 0.0)), ".2g")
    whole = _sim("sculpt_quad_mla").metrics["sculpt"]
    out["zhang.vibration_overcut_um"] = (whole["vibration_overcut_um"], ".3g")
    out["zhang.tool_edge_overcut_um"] = (whole["tool_edge_overcut_um"], ".3g")
    return out


def run_zhang_wear() -> dict:
    """Zhang et al. (2022) with the wear model: `sculpt_quad_mla` on 3 x 3 lenslets at p / 40
    pixels with `tool.wear = true`, the 104 kHz vibration on and off: the middle lenslet's Sa
    (degree-4 form removed), the cut's length, the edge radius the cut wears to with and
    without the vibration (the chemical wear at the paper's 100 mm/min), the largest growth
    the assumed ranges allow (the rate range's top, the speed law's constants at their
    extremes) and the chemical wear rate on steel that would raise the edge radius by 50 nm
    over that cut without vibration (against the assumed range's top)."""
    import itertools
    from dataclasses import replace

    from render_inspect.core.units import MM_TO_NM
    from render_inspect.machining import WEAR_RATES
    from render_inspect.machining._wear import SPEED_LAW, speed_factor
    from render_inspect.metrology._filters import remove_form
    from render_inspect.metrology._params import areal_parameters

    p = 0.19975
    cell_of = ["design.rows=3", "design.cols=3", f"simulation.pixel={p / 40}",
               f"simulation.region=[{-1.5 * p},{-1.5 * p},{1.5 * p},{1.5 * p}]", "tool.wear=true"]

    def lenslet(over):
        sim = _sim("sculpt_quad_mla", cell_of + over)
        res = sim.heightmap.machined - sim.heightmap.design
        cell, _ = remove_form(res[42:79, 42:79], pixel=p / 40, method="polynomial", degree=4)
        return areal_parameters(cell, pixel=p / 40)["Sa"] * MM_TO_NM, sim.metrics["tool_wear"]

    sa, w = lenslet([])
    sa0, w0 = lenslet(["artifacts.vibration.amplitude=0"])
    steel = WEAR_RATES["die_steel"]
    v = w0["cutting_speed_m_min"]
    g = float(speed_factor(v))
    g_top = max(float(speed_factor(v, replace(SPEED_LAW, rise_ref_K=dT, activation_kj_mol=Q)))
                for dT, Q in itertools.product(SPEED_LAW.rise_range_K, SPEED_LAW.activation_range_kj_mol))
    L = w0["cutting_distance_km"]
    need = 50.0 / (L * g)
    # the paper's whole cut: 10 lines (one per column of lenslets) of 10 lenslets, four
    # layers (5/3/2/1 um); the flank land it leaves with every rate and constant at the top
    # of its range, without and with the vibration (the paper's SEM: a considerable land
    # after conventional sculpturing, none apparent after vibration sculpturing)
    L_paper = 4 * 10 * 10 * p / 1e6
    land_top = steel.flank_range[1] * L_paper * g_top
    return {"zhang_wear.sa_nm": (sa, ".3g"), "zhang_wear.conv_sa_nm": (sa0, ".2f"),
            "zhang_wear.cut_mm": (L * 1e6, ".3g"),
            "zhang_wear.growth_nm": f"{w['edge_radius_end_nm'] - w['edge_radius_start_nm']:.1e}",
            "zhang_wear.conv_growth_nm": f"{w0['edge_radius_end_nm'] - w0['edge_radius_start_nm']:.1e}",
            "zhang_wear.conv_growth_top_nm": f"{steel.edge_range[1] * L * g_top:.1e}",
            "zhang_wear.speed_factor": f"{g:.1e}", "zhang_wear.speed_factor_top": f"{g_top:.1g}",
            "zhang_wear.duty": (w["contact_duty_cycle"], ".2g"),
            "zhang_wear.paper_cut_mm": (L_paper * 1e6, ".3g"),
            "zhang_wear.paper_land_top_um": f"{land_top:.2g}",
            "zhang_wear.paper_land_top_vib_um": f"{land_top * w['contact_duty_cycle']:.1g}",
            "zhang_wear.rate_needed_nm_km": f"{need:.1e}",
            "zhang_wear.rate_over_top": f"{need / steel.edge_range[1]:.0e}"}


def run_hts() -> dict:
    """Kong et al. (2020): `hts_toric_msa` as shipped (the FTS 1.3 ms late): the lags, the
    lenslets' dislocations after registration on the base, their growth per mm of
    radius, the lenslets' form error and the residual's Sq."""
    import numpy as np

    from render_inspect.core.units import S_TO_MS, S_TO_US

    m = _sim("hts_toric_msa").metrics
    sv = m["servo"]
    out = {"hts.relative_lag_ms": (sv["relative_lag_s"] * S_TO_MS, ".3g"),
           "hts.fts_late_ms": (sv["relative_lag_s"] * S_TO_MS, ".2g"),
           "hts.slow_lag_us": (sv["slow_lag_s"] * S_TO_US, ".3g"),
           "hts.slow_lag_ms": (sv["slow_lag_s"] * S_TO_MS, ".2f"),
           "hts.relative_angle_mrad": (sv["relative_lag_s"] * sv["omega_rad_s"] * S_TO_MS, ".3g"),
           "hts.sq_nm": (m["residual"]["Sq_nm"], ".3g")}
    rows = sorted(((math.hypot(e["x_mm"], e["y_mm"]), math.hypot(e["dx_um"], e["dy_um"]), e)
                   for e in m["lenslets"]), key=lambda row: row[:2])
    mid = [d for r, d, _ in rows if 1.0 < r < 1.8]
    far = [(r, d) for r, d, _ in rows if r > 1.8]
    out["hts.disloc_centre_um"] = (rows[0][1], ".1g")
    out["hts.disloc_mid_um"] = (float(np.mean(mid)), ".3g")
    out["hts.disloc_far_um"] = (far[-1][1], ".3g")
    out["hts.disloc_per_mm"] = (far[-1][1] / far[-1][0], ".3g")
    out["hts.form_sa_um"] = (float(np.median([e["Sa_um"] for _, _, e in rows])), ".2g")
    return out


def _about(fn) -> str:
    """The first paragraph of a run's docstring, on one line."""
    return " ".join(fn.__doc__.split("\n\n")[0].split()).replace("``", "`")


RUNS = {r.name: r for r in (
    Run("grid", _about(run_grid), run_grid, cheap=True),
    Run("filters", _about(run_filters), run_filters, cheap=True),
    Run("papers_li", _about(run_papers_li), run_papers_li, cheap=True),
    Run("zhang", _about(run_zhang), run_zhang, cheap=True),
    Run("zhang_wear", _about(run_zhang_wear), run_zhang_wear, cheap=True),
    Run("fig16", _about(run_fig16), run_fig16),
    Run("instrument", _about(run_instrument), run_instrument),
    # papers ends on hts_toric_msa, which the hts run then takes from the same simulation
    Run("papers", _about(run_papers), run_papers),
    Run("hts", _about(run_hts), run_hts),
    Run("rcse", _about(run_rcse), run_rcse),
    Run("rcse_ideal", _about(run_rcse_ideal), run_rcse_ideal),
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
        try:
            got = run.make()
        except Exception as exc:  # one failed run keeps its old numbers; the others go on
            import traceback

            traceback.print_exc()
            print(f"docs_numbers: {name} failed ({type(exc).__name__}: {exc}); its numbers "
                  f"are kept as they were", file=sys.stderr)
            data.setdefault("failed", []).append(name)
            continue
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
    failed = []
    if not args.docs:
        t0 = time.perf_counter()
        for name in args.only or list(RUNS):
            data = make([name], data)        # numbers.json after each run: a stop keeps them
            failed += data.pop("failed", [])
            write_numbers(data)
        print(f"docs_numbers: {time.perf_counter() - t0:.0f} s", file=sys.stderr)
    write_numbers(data)
    unknown = write_docs(data)
    if unknown:
        print("marked spans without a number:\n  " + "\n  ".join(unknown), file=sys.stderr)
    if failed:
        print("runs that failed (their numbers are the earlier ones): " + ", ".join(failed),
              file=sys.stderr)
    return 1 if unknown or failed else 0


if __name__ == "__main__":
    sys.path.insert(0, str(REPO))
    sys.exit(main())
