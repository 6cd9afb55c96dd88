"""The one-screen summaries of ``toolpath``, ``characterise`` and ``render``: their
headline numbers as (label, value) rows, read from what the commands wrote."""

from __future__ import annotations

import json
from pathlib import Path

from ..core.units import MIN_TO_S, MM_TO_UM

__all__ = ["toolpath_summary", "characterise_summary", "render_summary", "command_summary",
           "profile_compare_summary", "PROFILE_COLUMNS"]


def _num(v: object, unit: str = "", fmt: str = ".4g") -> str:
    if v is None:
        return "n/a"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, (int, float)):
        text = f"{v:,}" if isinstance(v, int) else format(float(v), fmt)
        return f"{text} {unit}".rstrip()
    return str(v)


def toolpath_summary(facts: dict) -> list[tuple[str, str]]:
    """Rows of ``toolpath.json``: the program's size, feed, time, accuracy and limits."""
    tp = facts.get("toolpath", {})
    rows = [("points", _num(tp.get("points")))]
    if "revolutions" in tp:
        rows.append(("revolutions", _num(tp.get("revolutions"))))
    if "lines" in tp:
        rows.append(("lines", _num(tp.get("lines"))))
    if tp.get("feed_per_rev_mm") is not None:
        rows.append(("feed per revolution", _num(tp["feed_per_rev_mm"] * MM_TO_UM, "um")))
    dur = tp.get("duration_s", tp.get("cut_time_s"))
    if dur is not None:
        rows.append(("cutting time", f"{dur / MIN_TO_S:.1f} min" if dur >= 120 else _num(dur, "s")))
    for key, label in (("chordal_error_max_nm", "chordal error, max"),
                       ("gouge_max_nm", "gouge, max")):
        if tp.get(key) is not None:
            rows.append((label, _num(tp[key], "nm")))
    acc = facts.get("accessibility") or {}
    if "ok" in acc:
        rows.append(("tool reaches the whole region", _num(bool(acc["ok"]))))
    rate = tp.get("block_rate") or {}
    if rate.get("max_per_s") is not None:
        lim = rate.get("limit_per_s")
        rows.append(("block rate, max", f"{rate['max_per_s']:,.0f} blocks/s "
                     + (f"(over the limit {lim:,.0f})" if not rate.get("ok", True)
                        else f"(limit {lim:,.0f})")))
    exceeded = tp.get("limits_exceeded")
    if exceeded is not None:
        rows.append(("machine limits exceeded", ", ".join(map(str, exceeded)) if exceeded else "none"))
    check = facts.get("program_check")
    if isinstance(check, dict) and "ok" in check:
        rows.append(("NC program read back and verified", _num(bool(check["ok"]))))
    return rows


def characterise_summary(metrics: dict) -> list[tuple[str, str]]:
    """Rows of ``characterise``'s metrics.json: transfer, noise, flatness, slope limit."""
    c = metrics.get("characterise", {})
    itf, flat, slope = c.get("itf") or {}, c.get("flat") or {}, c.get("slope") or {}
    inst = slope.get("instrument") or {}
    obj = c.get("objective")
    rows = [("objective", obj.get("name", str(obj)) if isinstance(obj, dict) else str(obj)),
            ("mode", str(c.get("mode"))),
            ("effective wavelength", _num(c.get("effective_wavelength_nm"), "nm")),
            ("transfer cut-off", f"{_num(itf.get('cutoff_per_mm'), '/mm')} "
                                 f"(period {_num(itf.get('cutoff_period_um'), 'um')})"),
            ("half transfer at", _num(itf.get("half_transfer_per_mm"), "/mm")),
            ("noise", _num(flat.get("noise_nm"), "nm")),
            ("flatness Sq", _num(flat.get("flatness_Sq_nm"), "nm")),
            ("slope limit", _num(inst.get("slope_limit_deg"), "deg")),
            ("50 % dropout at", _num(inst.get("dropout_50_deg"), "deg"))]
    return rows


def render_summary(result: dict) -> list[tuple[str, str]]:
    """Rows of ``render``'s result: each image with its settings and seconds."""
    r = result.get("render", result)
    rows = [("surface", str(r.get("surface"))), ("Mitsuba variant", str(r.get("mitsuba_variant")))]
    timing = r.get("timing_s") or {}
    for name, info in r.items():
        if not isinstance(info, dict) or name in ("timing_s", "big_map"):
            continue
        facts = []
        for key, unit in (("mode", ""), ("view", ""), ("resolution", "px"), ("spp", "spp"),
                          ("wavelength_nm", "nm"), ("numerical_aperture", "NA")):
            v = info.get(key)
            if isinstance(v, (list, tuple)) and len(v) == 2:
                facts.append(f"{v[0]} x {v[1]} {unit}".strip())
            elif v is not None and not isinstance(v, (dict, list)):
                facts.append(f"{v} {unit}".strip())
        if timing.get(name) is not None:
            facts.append(f"{timing[name]:.1f} s")
        rows.append((name.replace("_", " "), ", ".join(facts) or "written"))
    return rows


#: the profile compare's columns: metrics key, heading
PROFILE_COLUMNS = (("measured", "measured"), ("simulated_measured", "simulated measurement"),
                   ("true", "simulated cut"))


def profile_compare_summary(metrics: dict) -> tuple[list[tuple[str, ...]], list[str]]:
    """The headline numbers of ``compare --measured PROFILE``: rows (quantity, measured,
    simulated measurement, simulated cut) and lines (the registration, the filters, and
    the warnings: a virtual measurement that does not follow the cut, a registration no
    better than chance)."""
    p = metrics.get("profiles") or {}
    rows: list[tuple[str, ...]] = []
    for key, label, unit, scale in (("Ra_nm", "Ra", "nm", 1.0), ("Rq_nm", "Rq", "nm", 1.0),
                                    ("Rt_nm", "Rt", "nm", 1.0), ("Rku", "Rku", "", 1.0),
                                    ("RSm_mm", "RSm", "um", MM_TO_UM)):
        vals = [((p.get(k) or {}).get("profile") or {}).get(key) for k, _ in PROFILE_COLUMNS]
        rows.append((label, *(_num(None if v is None else v * scale, unit) for v in vals)))
    per = []
    for k, _ in PROFILE_COLUMNS:
        dom = (((p.get(k) or {}).get("periods") or {}).get("dominant") or {}).get("period_mm")
        per.append(_num(None if dom is None else dom * MM_TO_UM, "um"))
    rows.append(("dominant period", *per))
    reg = metrics.get("registration") or {}
    f = metrics.get("filter") or {}
    lines = []
    if reg:
        null = reg.get("null_correlation")
        on = (" against the cut as the instrument sees it (the virtual measurement failed)"
              if reg.get("against") == "cut_as_seen" else "")
        lines.append(f"registration{on}: shifted {_num((reg.get('shift_mm') or 0) * MM_TO_UM, 'um')}, "
                     f"correlation {_num(reg.get('correlation'), fmt='.3f')}"
                     + ("" if null is None else
                        f" ({'reliable' if reg.get('reliable') else 'not reliable'}: an "
                        f"unrelated profile reaches {_num(null, fmt='.3f')})"))
    if f:
        lines.append(f"filters: lambda_s {_num(f.get('lambda_s_mm') or 0)} mm, lambda_c "
                     f"{_num(f.get('lambda_c_mm'))} mm; parabola removed from each")
    lines += [f"WARNING: {w}" for w in metrics.get("warnings") or []]
    return rows, lines


def command_summary(command: str, result: object, out: str | Path) -> list[tuple[str, str]]:
    """The rows of ``command``'s summary (``toolpath`` reads its toolpath.json)."""
    if command == "toolpath":
        p = Path(out) / "toolpath.json"
        return toolpath_summary(json.loads(p.read_text())) if p.is_file() else []
    if command == "characterise":
        return characterise_summary(result if isinstance(result, dict) else {})
    if command == "render":
        return render_summary(result if isinstance(result, dict) else {})
    return []
