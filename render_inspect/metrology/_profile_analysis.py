"""One measured profile analysed as a metrologist reads it: spikes counted (and left out
on request), form removed, ISO 16610-21 filters, ISO 21920-2 parameters, the material
ratio curve and the dominant periods (the feed marks; for a trace through the spindle
axis the centre and the period on each side).  Arrays in (mm), numbers out (heights in
nm where the key says so)."""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError, check_positive
from ..core.units import MM_TO_NM
from ._iso21920 import evaluate_profile
from ._periods import profile_periods
from ._registration import detect_outliers

__all__ = ["PROFILE_FORMS", "analyze_profile", "profile_metrics", "PROFILE_KEYS"]

#: ``--form`` for a profile: the map's names, ``plane`` being a line on a profile
PROFILE_FORMS = {"none": "none", "plane": "line", "line": "line", "poly2": "poly2"}

#: the ISO 21920-2 keys of ``metrics["profile"]``
PROFILE_KEYS = ("Ra_nm", "Rq_nm", "Rp_nm", "Rv_nm", "Rz_nm", "Rt_nm", "Rsk", "Rku", "RSm_mm",
                "Rdq", "Rmr")

_HEIGHTS = ("Ra", "Rq", "Rp", "Rv", "Rz", "Rt")


def _num(v):
    return None if v is None or (isinstance(v, float) and not math.isfinite(v)) else v


def profile_metrics(params: dict) -> dict:
    """:func:`~render_inspect.metrology.profile_texture`'s numbers under the names
    ``metrics.json`` uses (heights nm, RSm mm, Rmr in % at depths in % of Rz)."""
    out = {f"{k}_nm": _num(params[k] * MM_TO_NM) for k in _HEIGHTS}
    out.update({"Rsk": _num(params["Rsk"]), "Rku": _num(params["Rku"]),
                "RSm_mm": _num(params["RSm"]), "Rdq": _num(params["Rdq"]),
                "Rmr": {f"c={k}": _num(100.0 * v) for k, v in params["Rmr"].items()},
                "n_elements": params["n_elements"]})
    return out


def analyze_profile(x: np.ndarray, z: np.ndarray, *, spacing: float, form: str = "line",
                    lambda_s: float | None = None, lambda_c: float | None = None,
                    outliers: str = "none", outlier_sigma: float = 3.0) -> dict:
    """Analyse one profile.

    Parameters
    ----------
    x, z : (n,) arrays
        Positions (uniform step ``spacing``) and heights, mm; NaN = not measured.
    form : {"none", "line" (or "plane"), "poly2"}
        Form removed before filtering.
    lambda_s, lambda_c : float, optional
        Gaussian cut-offs, mm (default: ISO 21920-3's choice from RSm or Ra).
    outliers : {"none", "sigma"}
        Spikes (the ``outlier_sigma`` spike rule of
        :func:`~render_inspect.metrology.detect_outliers`) are counted either way and
        left out (as not measured) with ``"sigma"``.

    Returns
    -------
    dict
        ``metrics`` (what ``metrics.json`` holds: ``kind`` = "profile", ``profile``
        (:data:`PROFILE_KEYS`), ``filter``, ``evaluation_length_mm``, ``n_sections``,
        ``material_ratio``, ``periods``, ``outliers``, ``form``, ``spacing_mm``,
        ``n_points``, ``n_measured``, ``units``, ``warnings``) and ``arrays`` (``x``,
        ``primary``, ``waviness``, ``roughness``, ``evaluate``, ``spikes``) for figures.
    """
    x = np.asarray(x, dtype=np.float64).ravel()
    z = np.asarray(z, dtype=np.float64).ravel()
    check_positive("spacing", spacing)
    if form not in PROFILE_FORMS:
        raise InputError(f"--form for a profile must be one of none, plane (a line), poly2, "
                         f"received {form!r}")
    if outliers not in ("none", "sigma"):
        raise InputError(f"--outliers must be one of none, sigma, received {outliers!r}")
    check_positive("outlier_sigma", outlier_sigma)
    _, spikes = detect_outliers(z, pixel=spacing, k=outlier_sigma, replace=False)
    n_meas = int(np.isfinite(z).sum())
    n_flag = int(spikes.sum())
    use = np.where(spikes, np.nan, z) if outliers == "sigma" else z
    e = evaluate_profile(x, use, spacing=spacing, lambda_s=lambda_s, lambda_c=lambda_c,
                         form=PROFILE_FORMS[form])
    p = e["parameters"]
    warnings_ = list(e["warnings"])
    if outliers == "none" and n_flag:
        one = n_flag == 1
        warnings_.append(f"{n_flag} point{'' if one else 's'} ({n_flag / n_meas:.2%}) "
                         f"{'is a spike' if one else 'are spikes'} by the {outlier_sigma:g}-sigma rule; "
                         f"{'it is' if one else 'they are'} kept (--outliers sigma leaves "
                         f"{'it' if one else 'them'} out)")
    per = profile_periods(x, e["primary"], spacing=spacing)
    mr = p["material_ratio"]
    metrics = {
        "kind": "profile",
        "profile": profile_metrics(p),
        "filter": {"lambda_s_mm": e["filter"]["lambda_s"], "lambda_c_mm": e["filter"]["lambda_c"],
                   "chosen_by": e["filter"]["chosen_by"],
                   "standard": "ISO 16610-21 Gaussian; parameters ISO 21920-2"},
        "evaluation_length_mm": e["evaluation_length_mm"], "n_sections": p["n_sections"],
        "material_ratio": {"depth_nm": [d * MM_TO_NM for d in mr["depth"]],
                           "ratio_percent": [100.0 * r for r in mr["ratio"]]},
        "periods": _periods_metrics(per),
        "outliers": {"method": outliers, "sigma": float(outlier_sigma), "count": n_flag,
                     "fraction": n_flag / n_meas if n_meas else 0.0,
                     "left_out": outliers == "sigma",
                     "rule": "spikes: a second difference beyond k robust sigma (1.4826 MAD) "
                             "with both neighbours' of the opposite sign"},
        "form": {"method": PROFILE_FORMS[form]},
        "spacing_mm": float(spacing), "n_points": int(z.size), "n_measured": n_meas,
        "length_mm": float(x[-1] - x[0]),
        "units": {"lateral": "mm", "heights": "nm (keys ending _nm)"},
        "warnings": warnings_,
    }
    return {"metrics": metrics,
            "arrays": {"x": x, "primary": e["primary"], "waviness": e["waviness"],
                       "roughness": e["roughness"], "evaluate": e["evaluate"],
                       "spikes": spikes}}


def _periods_metrics(per: dict) -> dict:
    def one(d):
        out = {"period_mm": d.get("period_mm"), "fraction_of_variance": d.get("fraction"),
               "harmonics": [{"order": h["order"], "period_mm": h["period_mm"],
                              "relative_power": h["relative_power"]}
                             for h in d.get("harmonics", [])]}
        if d.get("note"):
            out["note"] = d["note"]
            if "longer than the longest" in d["note"]:
                # a profile's spectrum is taken with a parabola removed whatever the form
                # removal, so only form beyond a parabola can be left over
                out["note"] += ("; the spectrum already has a parabola removed (whatever "
                                "--form), so what is left is form of higher order or waviness")
        return out

    whole = per["whole"]
    out = {"dominant": one(whole),
           "method": "Hann-windowed periodogram, the strongest peak (a local maximum) between "
                     "4 samples and a quarter of the trace; harmonics 10x above the median"}
    if whole.get("search_mm"):
        out["search_mm"] = dict(whole["search_mm"])
    mc = per.get("mirror")
    if mc is not None:
        out["mirror"] = {"centre_mm": mc.get("centre_mm"), "symmetry": mc.get("symmetry"),
                         "through_axis": bool(mc.get("through_axis"))}
        if mc.get("why"):
            out["mirror"]["why_not_through_axis"] = mc["why"]
    ta = per.get("through_axis")
    if ta:
        out["through_axis"] = {"centre_mm": ta["centre_mm"], "symmetry": ta["symmetry"],
                               **{s: one(ta[s]) for s in ("left", "right") if s in ta}}
    return out
