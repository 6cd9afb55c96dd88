"""The figures and the page of a fit (``render-inspect fit``): measured, fitted and residual
maps, the areal PSD of both, the misfit along each parameter, and ``fit.html``."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from ..core.units import MM_TO_NM
from ._figures import _plt, _to_png, line_panels, map_panels
from ._format import fmt_number
from ._html import HtmlReport
from ._keys import key_unit
from ._provenance import provenance_section

__all__ = ["fit_figures", "fit_page", "psd_figure", "fit_provenance_section"]


def psd_figure(curves: dict, *, title: str = "", dpi: int = 100) -> bytes:
    """Log-log areal PSD curves: ``curves`` name -> (k cycles/mm, PSD nm^2 mm^2)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=dpi, layout="constrained")
    styles = {"measured": {"color": "k", "lw": 1.6}, "fitted": {"color": "C3", "lw": 1.2},
              "start": {"color": "C0", "lw": 1.0, "ls": "--"},
              "fitted, with the random parts": {"color": "C1", "lw": 1.0, "ls": ":"}}
    for name, (k, p) in curves.items():
        ok = np.isfinite(p) & (p > 0)
        ax.loglog(np.asarray(k)[ok], np.asarray(p)[ok], label=name, **styles.get(name, {}))
    ax.set_xlabel("spatial frequency (1/mm)")
    ax.set_ylabel("areal PSD, radially averaged (nm$^2$ mm$^2$)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    return _to_png(fig)


def fit_figures(record: dict, *, measured: np.ndarray, fitted: np.ndarray, start: np.ndarray,
                measured_wavy: np.ndarray, fitted_wavy: np.ndarray,
                extent: tuple[float, float, float, float], psd: dict) -> dict:
    """``maps.png``, ``residual.png``, ``psd.png``, ``misfit.png`` as PNG bytes; maps in
    mm (form removed), ``extent`` = (x0, x1, y0, y1) of the pixel edges."""
    nm = MM_TO_NM
    figs = {}
    figs["maps.png"] = map_panels(
        [("measured", measured * nm), ("fitted (the model through the virtual instrument)",
                                       fitted * nm)],
        extent=extent, label="height, form removed (nm)", cmap="turbo",
        suptitle=f"misfit rms {fmt_number(record['misfit_rms_nm'])} nm")
    figs["residual.png"] = map_panels(
        [("fitted - measured", (fitted - measured) * nm),
         ("waviness: fitted - measured", (fitted_wavy - measured_wavy) * nm)],
        extent=extent, label="nm", cmap="RdBu_r", symmetric=True, shared=False,
        suptitle="residual of the fit (the feed marks' phase is not fitted: see fit.json's "
                 "waviness misfit)")
    figs["psd.png"] = psd_figure(psd, title="measured vs fitted (and the scene's values)")
    panels = []
    for key, prof in record.get("profiles", {}).items():
        p = record["parameters"][key]
        vals = [v for v, c in zip(prof["values"], prof["misfit"]) if c is not None]
        cost = [c for c in prof["misfit"] if c is not None]
        series = [{"x": vals, "y": cost, "label": "misfit", "style": "line"}]
        for term in ("map", "psd", "harmonics"):
            ys = [t.get(term) for t, c in zip(prof["terms"], prof["misfit"]) if c is not None]
            if ys and all(y is not None for y in ys):
                series.append({"x": vals, "y": ys, "label": term, "style": "dashed"})
        vl = [(p["value"], "fitted")]
        if p["bounds"][0] <= p["start"] <= p["bounds"][1] and vals and \
                min(vals) <= p["start"] <= max(vals):
            vl.append((p["start"], "start"))
        panels.append({"title": key, "xlabel": key, "ylabel": "misfit (sum of squares)",
                       "series": series, "vlines": vl})
    if panels:
        figs["misfit.png"] = line_panels(panels, suptitle="the misfit along each parameter "
                                                          "(the others at their fitted values)")
    return figs


def _val(v: Any) -> str:  # (as fmt_number takes it)
    return "n/a" if v is None else fmt_number(v, sig=5)


def _prediction_section(rep: HtmlReport, pr: dict) -> None:
    """The prediction of the next cut: its headline numbers with their standard
    uncertainty (k = 1) and the expanded one (k = 2), or why it carries none."""
    rep.section("Prediction")
    settings = ", ".join(pr["settings"])
    if not pr.get("measurement_backed", True):
        rep.text(f"Not a measurement-backed forecast: {pr.get('note', '')}.")
    unc = pr.get("uncertainty")
    window = (pr.get("window") or {}).get("description")
    spread = pr.get("window_spread") or {}
    if unc is None:
        rep.text(f"Settings {settings} on the fitted scene (files in {pr['folder']}/); "
                 + ("uncertainty not computed" if pr.get("uncertainty_skipped")
                    else "no uncertainty") + f": {pr.get('no_uncertainty', '')}.")
        if window:
            rep.text(window[0].upper() + window[1:] + ".")
        r = pr.get("residual") or {}
        rep.text(f"Residual Sq {_val(r.get('Sq_nm'))} nm, Sz {_val(r.get('Sz_nm'))} nm.")
        return
    rep.text(f"Settings {settings} on the fitted scene (files in {pr['folder']}/), with the "
             f"uncertainty of {', '.join(unc['keys'])} propagated ({unc['simulations']} "
             f"simulations, seed {unc.get('seed')} in each; {unc.get('budget', '')}).")
    if window:
        rep.text(window[0].upper() + window[1:] + ".")
    rows = []
    for path, q in unc["quantities"].items():
        rows.append([q["label"], q["unit"], _val(q["value"]), _val(q["u"]), _val(q["U"]),
                     _val(q.get("u_first_order")), _val(q["second_order_shift"]),
                     "yes" if q.get("smooth", True) else "no: a rough figure",
                     _val(spread.get(path))])
    rep.table(rows, header=["", "unit", "predicted", "standard uncertainty (k=1)",
                            f"expanded (k={unc['coverage_factor']:g})", "first order alone",
                            "second-order shift", "linear over +-1 SE",
                            "spread over where the marks fall"])
    notes = [f"without the uncertainty of {k}: {why}" for k, why in unc["without"].items()]
    rep.list(notes + ["Method: " + unc["method"] + ".",
                      "The second-order shift is how far the mean of the number over the "
                      "parameters' spread lies from its value at the fitted values; where the "
                      "second-order part outweighs the first the number is not linear in the "
                      "keys over their standard errors and its uncertainty is a rough one."])


def fit_page(record: dict, figs: dict) -> str:
    """``fit.html``: the fitted values, correlations, misfit, provenance and figures."""
    rep = HtmlReport(f"render-inspect fit: {record.get('run_name') or record.get('scene', '')}",
                     f"{record['measured']['path']}: {len(record['parameters'])} parameters, "
                     f"{record['evaluations']} evaluations, status {record['status']}")
    rep.section("Status")
    rep.text(f"{record['status']}: {record.get('message', '')}")
    after = (record.get("model_check") or {}).get("after")
    if after:
        rep.text(after["verdict"] + ".")
    rep.section("Fitted parameters")
    rows = []
    for k, p in record["parameters"].items():
        rel = p.get("relative_stderr")
        se = _val(p["stderr"]) if p.get("determined", True) else "not determined alone"
        rows.append([k, key_unit(k), _val(p["value"]), se,
                     "n/a" if rel is None else f"{100 * rel:.3g} %",
                     _val(p.get("stderr_formal")), _val(p.get("stderr_random_parts")),
                     _val(p["start"]), f"{_val(p['bounds'][0])} .. {_val(p['bounds'][1])}"])
    rep.table(rows, header=["key", "unit", "value", "stderr", "relative", "formal", "random parts",
                            "start", "bounds"])
    n = (record.get("uncertainty") or {}).get("realisations", 0)
    q = (record.get("goodness") or {}).get("birge_ratio")
    rep.text("The standard error combines the formal one (from the Jacobian at the solution), "
             f"the spread of the solution over {n} realisations of the random parts and the "
             "camera's noise, each taken as the measured map"
             + (f", scaled by {q:.3g} (the misfit over the misfit those realisations alone "
                "leave: the model's error)" if q and q > 1 else "")
             + ", the distance to the minimum of the misfit smoothed over the difference "
               "steps, and half the distance between the two starts' results; the misfit along "
               "each parameter below shows how well each one is pinned.")
    ident = record.get("identifiability") or {}
    if ident.get("directions") and len(record["parameters"]) > 1:
        rep.list([f"{d['text']}: relative standard error {d['relative_stderr']:.3g} "
                  f"({'determined' if d['determined'] else 'not determined by this measurement'})"
                  for d in ident["directions"]])
    held = (record.get("random_parts") or {}).get("held_at_zero_in_evaluations") or {}
    if held:
        rep.text("Random parts held at 0 in the evaluations (their power enters the spectra): "
                 + ", ".join(f"{k} = {fmt_number(v)}" for k, v in held.items()) + ".")
    keys = list(record["parameters"])
    if len(keys) > 1:
        rep.section("Correlation")
        rep.table([[a] + [f"{record['correlation'][a][b]:+.3f}" for b in keys] for a in keys],
                  header=[""] + keys)
        if record["unresolved_pairs"]:
            rep.list([f"{p['keys'][0]} and {p['keys'][1]} cannot be told apart by this "
                      f"measurement (correlation {p['correlation']:+.3f})"
                      for p in record["unresolved_pairs"]])
        else:
            rep.text("Every pair is told apart (|correlation| below 0.95).")
    rep.section("Misfit")
    mf = record["misfit"]
    rep.table([["misfit (sum of squares)", _val(mf["start"]), _val(mf["value"])],
               *[[f"term {t}", _val(mf["start_terms"].get(t)), _val(mf["terms"].get(t))]
                 for t in mf["terms"]],
               ["map rms (nm)", "", _val(record["misfit_rms_nm"])],
               ["waviness rms (nm)", "", _val(mf["waviness_rms_nm"])]],
              header=["", "start", "fitted"])
    for name, cap in (("maps.png", "Measured and fitted heights (form removed)."),
                      ("residual.png", "Fitted minus measured; right: after the waviness "
                                       "filter that removes the feed marks."),
                      ("psd.png", "Areal PSD, radially averaged: measured, the fitted "
                                  "expected surface (without the random parts), the same "
                                  "with one realisation of the random parts and the "
                                  "camera's noise, and the scene's values."),
                      ("misfit.png", "The misfit along each parameter through the solution "
                                     "(the others held at their fitted values).")):
        if name in figs:
            rep.figure(figs[name], cap)
    if record.get("prediction"):
        _prediction_section(rep, record["prediction"])
    fit_provenance_section(rep, record, extra=[
        ["placement", record["placement"]["method"]],
        ["fit window (mm)", ", ".join(f"{v:.5g}" for v in record["placement"]["window_mm"])]])
    return rep.render()


def fit_provenance_section(rep: HtmlReport, record: dict,
                           extra: Iterable[Sequence[object]] = ()) -> None:
    """The "Provenance" section of a fit's page (a map's or a profile's): the command line
    it was made with, the scene and the input files with their SHA-256 (``fit.json``'s
    ``inputs``, :func:`provenance_section`), the measured file and its reader, ``extra``
    rows (where the fit window lies), the bounds of the schema's range that a measured
    cutting edge narrowed, the objective and the fit's time."""
    meas = record["measured"]
    provenance_section(rep, record, seed_text="seed (the virtual camera's noise and the "
                                              "global search)", extra=[
        ["measured file", meas["path"]], ["reader", str(meas.get("reader"))],
        *[list(r) for r in extra],
        *[[f"{n['key']}: {n['bound']} bound narrowed (the measured cutting edge)",
           f"{_val(n['from'])} -> {_val(n['to'])}"] for n in record.get("bounds_narrowed") or []],
        ["objective", f"{record['objective']} (from the {record['objective_from']})"],
        ["fit time (s)", _val(record["timing_s"].get("total"))],
        ["per evaluation (s)", _val(record["timing_s"].get("per_evaluation"))]])
