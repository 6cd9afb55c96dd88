"""Both arms of a diameter in a profile fit: the same radii as the fitted window on the
line's other side of the spindle axis (the stretch mirrored about the line's closest point
to the axis), simulated at its own place on the part and fitted together with the window;
each arm's own estimate and the arms' disagreement, folded into the standard errors."""

from __future__ import annotations

import json
import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

from ..core.errors import InputError
from ..core.units import MM_TO_UM
from ..fit import (ArmsTarget, arms_features, arms_text, combine_arms, get_value,
                   make_profile_target, profile_family, profile_residual_vector)
from ..processes import process_of
from ..report import key_unit
from ._fit_profile_model import MIN_POINTS, ProfileModel, after_verdict, profile_band

if TYPE_CHECKING:
    from ..io import MeasuredProfile
    from ..scene import Scene

__all__ = ["ArmsModel", "other_arm_window", "fold_arms"]

log = logging.getLogger("render_inspect")


@dataclass
class ArmsModel:
    """Both arms' :class:`ProfileModel` (each its own band, at its own place on the part):
    a task holds the arms' tasks (:func:`predict_profile`)."""

    models: list

    def task(self, values: dict) -> dict:
        return {"arms": [m.task(values) for m in self.models]}

    def draw(self, values: dict, r: int, *, only: str | None = None) -> dict:
        return {"arms": [m.draw(values, r, only=only) for m in self.models]}

    def has_floor(self) -> bool:
        return self.models[0].has_floor()


def _band(win_p0, u, s_first: float, count: int, spacing: float, sim_pixel: float):
    """The band one evaluation simulates about a stretch of the line (``count`` samples
    from ``s_first`` mm): (the interferometer's field, the simulated region, the line's
    task); the window's own stretch and the other arm's alike."""
    s_last = s_first + (count - 1) * spacing
    ends = [(win_p0[0] + u[0] * s, win_p0[1] + u[1] * s) for s in (s_first, s_last)]
    fov, region = profile_band(ends, spacing, sim_pixel)
    return fov, region, {"p0": list(win_p0), "direction": list(u), "s0": s_first,
                         "step": spacing, "count": count}


def other_arm_window(prof: MeasuredProfile, scene: Scene, win: dict,
                     period: float | None) -> tuple[dict | None, str]:
    """The same radii as the window on the line's other arm: the stretch mirrored about the
    line's closest point to the spindle axis (the line's geometry, as for the window that
    holds the axis).  Returns (``{"i0", "i1", "s0_mm", "axis_s_mm", "centre_on_part_mm"}``,
    "") or (None, why the other arm is not available)."""
    process = process_of(scene)
    axis = process.traits(process.inputs_of(scene)).axis
    if axis is None:
        return None, f"scene {scene.name!r} has no spindle axis"
    p0, u = win["p0"], win["direction"]
    dx, dy = axis[0] - p0[0], axis[1] - p0[1]
    s_ax = dx * u[0] + dy * u[1]
    miss = abs(-dx * u[1] + dy * u[0])
    if miss > (period or 0.0):
        return None, (f"the line passes {miss:.4g} mm from the spindle axis (more than a feed "
                      f"period): it is not a diameter")
    n = win["i1"] - win["i0"]
    s = prof.x - prof.x[0]
    spacing = prof.spacing
    s_end = win["s0_mm"] + (n - 1) * spacing
    if win["s0_mm"] - 1e-9 <= s_ax <= s_end + 1e-9:
        return None, "the window holds the line's closest point to the spindle axis"
    start = 2 * s_ax - s_end
    i0 = int(np.argmin(np.abs(s - start)))
    i1 = i0 + n
    ok = np.isfinite(prof.z)
    s_lo, s_hi = float(s[ok][0]), float(s[ok][-1])
    if (abs(s[i0] - start) > spacing or i1 > s.size or s[i0] < s_lo - 1e-9
            or s[i1 - 1] > s_hi + 1e-9 or int(ok[i0:i1].sum()) < MIN_POINTS):
        r0 = abs(win["s0_mm"] - s_ax)
        r1 = abs(s_end - s_ax)
        return None, (f"the measured profile does not reach radii {min(r0, r1):.4g}-"
                      f"{max(r0, r1):.4g} mm on the line's other arm")
    sc = float(s[i0]) + 0.5 * (n - 1) * spacing
    return {"i0": i0, "i1": i1, "s0_mm": float(s[i0]), "axis_s_mm": float(s_ax),
            "centre_on_part_mm": [p0[0] + u[0] * sc, p0[1] + u[1] * sc]}, ""


# ------------------------------------------------------------------- both arms
def _two_arms(prof, scene, win, period, arms, target, spec, lag, count, sim_pixel, icfg,
              model):
    """The other arm's stretch, target and model where both arms are fitted (``--arms
    both``, or by default where the line is a diameter that reaches the window's radii on
    its other side); None for one arm.  ``--arms both`` where the other arm is not
    available is refused, naming why."""
    if arms == "one":
        return None
    other, why = other_arm_window(prof, scene, win, period)
    z2 = None if other is None else prof.z[other["i0"]:other["i1"]]
    if other is not None:
        t2 = make_profile_target(z2, spacing=prof.spacing, lag=lag, spec=spec)
        if (t2.peak is None) != (target.peak is None):
            other, why = None, "the other arm's stretch has no feed marks"
    if other is None:
        if arms == "both":
            raise InputError(f"--arms both: the window's radii cannot be fitted on both arms: "
                             f"{why}; fit one arm (--arms one)")
        log.info("fit: one arm of the line (%s)", why)
        return {"why": why, "one": True}
    n = win["i1"] - win["i0"]
    lag_mm = lag * prof.spacing
    fov2, region2, line2 = _band(win["p0"], win["direction"], other["s0_mm"] - lag_mm, count,
                                 prof.spacing, sim_pixel)
    model2 = ProfileModel(model.base, model.fill, region2, sim_pixel,
                          dict(icfg, field_of_view=fov2), model.seed, model.random,
                          model.free_random, line=line2)
    family2 = profile_family(t2.z, prof.spacing, axis_at_mm=None)
    log.info("fit: both arms of the diameter: the window's %d points and the same radii on "
             "the other arm, centred at (%.4g, %.4g) mm (marks' period %s)", n,
             *other["centre_on_part_mm"],
             "none" if not t2.peak else f"{1.0 / t2.peak * MM_TO_UM:.4g} um")
    sha = np.ascontiguousarray(z2, dtype=np.float64).tobytes() + json.dumps(line2).encode()
    return {"target": ArmsTarget([target, t2]), "model": ArmsModel([model, model2]),
            "window": other, "family": family2, "line": line2, "band_mm": fov2,
            "region_mm": region2, "sha": sha, "one": False}


def _check_after_arms(target: ArmsTarget, pred, families, goodness) -> dict:
    """:func:`_check_after` of both arms: each arm's family, and the fitted marks' period
    against the arms' mean measured one (each arm's own reading differs from the mean by
    half their difference, which the arms' record reports)."""
    findings = []
    for name, fam in zip(("the window's arm", "the other arm"), families):
        if not fam["one_family"]:
            findings.append(f"{name}: {fam['reason']}")
    if not findings and all(t.peak for t in target.arms) and all(p.centroid for p in pred.arms):
        rel = float(np.mean([p.centroid / t.peak for p, t in zip(pred.arms, target.arms)])) - 1
        sf = max(t.sigma_frequency or t.spec.sigma_frequency for t in target.arms)
        if abs(rel) > max(5 * sf, 0.01):
            findings.append(f"the fitted marks' period differs from the arms' mean measured "
                            f"one by {100 * rel:+.3g} % (no values of the free keys "
                            f"give the measured period and the marks' shape together)")
    return after_verdict(findings, goodness,
                         "the model describes the marks of this window on both arms")


def _arms_record(two, one_arm_why, result, target, fitted, win, prof, *,
                 measurement: bool = True) -> dict:
    """``fit.json``'s ``arms``: which arms were fitted (and why one), each arm's stretch,
    measured and fitted periods, misfit and own estimate, and their disagreement; the
    disagreement is folded into the parameters' standard errors here
    (:func:`~render_inspect.fit.combine_arms`)."""
    if two is None:
        return {"fitted": "one", "why": one_arm_why}
    pars = result.params
    pred = arms_features(cast(np.ndarray, result.best.height), target)
    spacing = prof.spacing
    ax = two["window"]["axis_s_mm"]
    out: dict = {"fitted": "both", "axis_s_mm": ax, "arms": [], "parameters": {},
                 "summary": [],
                 "uncertainty": "stderr = sqrt(stderr_fit^2 + u_arms^2), u_arms = "
                                "sqrt(max(0, D^2 - sa^2 - sb^2)) / 2 with D the arms' own "
                                "estimates' difference and sa, sb their standard errors"}
    rpm = get_value(fitted, "process.spindle_rpm")
    for k, (name, w, t, p) in enumerate(zip(
            ("window", "other"), (win, two["window"]), target.arms, pred.arms)):
        d, a, terms = profile_residual_vector(p, t)
        s0 = w["s0_mm"]
        s1 = s0 + (t.z.size - 1) * spacing
        out["arms"].append({
            "arm": name, "i0": int(w["i0"]), "i1": int(w["i1"]),
            "centre_on_part_mm": [float(v) for v in w["centre_on_part_mm"]],
            "radii_mm": sorted([abs(s0 - ax), abs(s1 - ax)]),
            "measured_period_um": None if not t.peak else 1.0 / t.peak * MM_TO_UM,
            "fitted_period_um": None if not p.centroid else 1.0 / p.centroid * MM_TO_UM,
            "registration_shift_um": p.shift * spacing * MM_TO_UM,
            "misfit_terms": terms})
    words = {"window": "the window's arm", "other": "the other arm"}
    for a in out["arms"]:
        mp, fp = a["measured_period_um"], a["fitted_period_um"]
        out["summary"].append(
            f"{words[a['arm']]} (radii {a['radii_mm'][0]:.3g}-{a['radii_mm'][1]:.3g} mm): marks' "
            f"period measured {'none' if mp is None else f'{mp:.4g} um'}, fitted "
            f"{'none' if fp is None else f'{fp:.4g} um'}"
            + ("" if mp is None or fp is None else f" ({100 * (fp / mp - 1):+.2g} %)")
            + f", misfit {sum(a['misfit_terms'].values()):.3g}")
    est = two.get("estimates") or {}
    if "error" in est or not est:
        out["estimates_error"] = est.get("error", "not computed")
        out["budget"] = bool(est.get("budget"))
        out["summary"].append(f"both arms fitted together; each arm's own estimate failed: "
                              f"{out['estimates_error']}")
        return out
    ea, eb = est["arms"]
    for i, p in enumerate(pars):
        rp = _param_value(result, i)
        comb = combine_arms(rp[0], rp[1], ea["values"][i], ea["stderr"][i], eb["values"][i],
                            eb["stderr"][i])
        out_par = dict(comb, window_arm={"value": ea["values"][i], "stderr": ea["stderr"][i]},
                       other_arm={"value": eb["values"][i], "stderr": eb["stderr"][i]})
        out["parameters"][p.key] = out_par
        unit, name, unit_name = 1.0, "", key_unit(p.key)
        if p.key == "process.feed_mm_per_min" and isinstance(rpm, (int, float)) and rpm > 0:
            unit, name = MM_TO_UM / float(rpm), f"{p.key} as the feed per revolution (um)"
            unit_name = "um"
        out["summary"].append(arms_text(p.key, comb, ea["values"][i], eb["values"][i],
                                        unit=unit, name=name, stderr=measurement,
                                        unit_name=unit_name))
    out["steps"] = est.get("steps")
    out["scans"] = est.get("scans")
    return out


def _param_value(result, i):
    se = result.stderr[i]
    return float(result.values[i]), float(se) if np.isfinite(se) else float("nan")


def fold_arms(record: dict) -> None:
    """The arms' disagreement in each parameter's standard error (``stderr_fit`` keeps the
    fit's own)."""
    arms = record.get("arms") or {}
    for key, comb in (arms.get("parameters") or {}).items():
        p = record["parameters"].get(key)
        if p is None or p.get("stderr") is None or not math.isfinite(comb["stderr"]):
            continue
        p["stderr_fit"] = p["stderr"]
        p["stderr_arms"] = comb["u_arms"]
        p["stderr"] = comb["stderr"]
        if p["value"]:
            p["relative_stderr"] = p["stderr"] / abs(p["value"])
    if arms.get("parameters"):
        record.setdefault("uncertainty", {})["stderr_arms"] = (
            "both arms of a diameter fitted: stderr = sqrt(stderr_fit^2 + stderr_arms^2), "
            "stderr_arms = sqrt(max(0, D^2 - sa^2 - sb^2)) / 2, D the difference of the arms' "
            "own estimates, sa and sb their standard errors (the excess of the arms' "
            "disagreement over their own uncertainty, as the standard uncertainty of a mean "
            "of two readings)")
