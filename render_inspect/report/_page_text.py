"""The comparison page's words: the small formatters of its tables (a value with its unit,
a parameter as given), and the sentences and fact lists it writes from the metrics (the
low-pass caption, why each variant cuts below the design, the light of the diffuse views,
the process's facts side by side)."""

from __future__ import annotations

from ..core.units import MM_TO_NM, MM_TO_UM
from ._format import fmt_number, fmt_quantity
from ._params import value_text


def _get(d, path, default=None):
    for k in path.split("."):
        if not isinstance(d, dict) or k not in d:
            return default
        d = d[k]
    return d


def _q(v, unit=""):
    """A value with its unit; ``unit="fraction"`` writes a fraction (0..1) in per cent."""
    if unit == "fraction":
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            return fmt_quantity(100.0 * float(v), "%")
        return fmt_quantity(v)
    return fmt_quantity(v, unit)


def _value_text(k: str, v):
    """A value of a measured file's source for a table, with its unit."""
    return "not stated in the file" if v is None else value_text(k, v)


def _g(x) -> str:
    """A parameter as given: up to 6 significant figures, no trailing zeros."""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, float)):
        return f"{x:.6g}"
    return str(x)


def _scaled(v, scale):
    """``v * scale`` for a number; anything else as it is (None stays None: ``n/a``)."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return float(v) * scale
    return v


def _lowpass_caption(metrics: dict) -> str:
    """The sentence saying the first figure's maps are low-passed, when the simulation
    does not resolve the tool marks (fewer than 4 pixels per period)."""
    f = metrics.get("filters") or {}
    a = metrics["variants"][0]["name"]
    pixel = _get(metrics, f"{a}.grid.pixel_mm")
    period, cut = f.get("mark_period_mm"), f.get("s_filter_mm")
    if not (period and cut and pixel) or period >= 4 * pixel:
        return ""
    return (f" The two maps are drawn through the ISO Gaussian low-pass of "
            f"{_q(cut * MM_TO_UM, 'um')}: the simulation samples the {_q(period * MM_TO_UM, 'um')} "
            f"feed marks with {fmt_number(period / pixel, sig=2)} pixels per period, and drawn "
            f"as sampled they would alias into false stripes.")


def _lathe_facts(v: dict) -> list[str]:
    """What the lathe does to the cut, from the variant's machine facts and settings."""
    facts = []
    fe = v.get("following_error") or {}
    if fe.get("z_max_nm"):
        facts.append(f"its Z slide follows the program within {_q(fe['z_max_nm'], 'nm')} "
                     f"(rms {_q(fe.get('z_rms_nm'), 'nm')})")
    if fe.get("fts_max_nm"):
        facts.append(f"its fast tool servo within {_q(fe['fts_max_nm'], 'nm')}")
    err = _get(v, "machine.settings.errors") or {}
    sync = sum(abs(a) for _, a, _ in err.get("axial_sync") or []) * MM_TO_NM
    asyn = (err.get("axial_async_rms") or 0.0) * MM_TO_NM
    if sync or asyn:
        facts.append(f"its spindle moves axially by up to {_q(sync, 'nm')} once per turn "
                     f"(synchronous error motion) and {_q(asyn, 'nm')} rms at random "
                     f"(asynchronous)")
    return facts


def _material_facts(v: dict) -> list[str]:
    """What the material does below the design: its random grooves along the cut."""
    mat = v.get("material") or {}
    rms = mat.get("grooves_rms_nm") or mat.get("groove_rms_nm")
    return [f"its grooves along the cut ({_q(rms, 'nm')} rms)"] if rms else []


def _overcut_sentences(metrics: dict) -> list[str]:
    """Why each variant cuts below the design: its deepest point split into the commanded
    geometry, the lathe and the material (``overcut`` of the variant's metrics, from
    simulations of a window around that point with one contribution at a time)."""
    out = []
    for var in metrics["variants"]:
        v = metrics.get(var["name"]) or {}
        b = v.get("overcut")
        if not b:
            continue
        x, y = b["at_mm"]
        text = (f"Why {var['name']} ({var['label']}) cuts {_q(-b['min_nm'], 'nm')} below the "
                f"design (residual min {_q(b['min_nm'], 'nm')}, at x = {x:.4g} mm, "
                f"y = {y:.4g} mm): simulated again around that point, the "
                f"commanded geometry alone (machine and material ideal) leaves "
                f"{_q(b['geometry_nm'], 'nm')}")
        g = b["geometry_nm"]
        text += (" (the tool path itself does not overcut)" if g > -0.5 else
                 " (the nose of the tool path itself overcuts)")
        parts = []
        for key, label in (b.get("labels") or {}).items():
            facts = {"lathe": _lathe_facts, "material": _material_facts}.get(key, lambda _: [])(v)
            parts.append(f"{label} alone {_q(b['alone_nm'].get(key), 'nm')}"
                         + (": " + ", ".join(facts) if facts else ""))
        if parts:
            text += "; " + "; ".join(parts)
        text += (f"; all together {_q(b['min_nm'], 'nm')} (a minimum: the contributions do not "
                 f"simply add)." if len(parts) > 1 else ".")
        out.append(text)
    return out


def _res(unit):
    return {"um": 1e-4, "mm": 1e-7}.get(unit)


def _micro_light_words(mic: dict) -> str:
    light = mic.get("light")
    if light == "brightfield":
        return ("in a microscope's brightfield: the objective illuminates through its own "
                "aperture and takes back what the surface returns into it, so flat areas are "
                "bright and slopes darken")
    return f"under the {light} light whose camera port is around the line of sight"


def _macro_light_words(mac: dict) -> str:
    words = []
    if mac.get("light") == "studio":
        words.append("Staged as in a photo studio: a softbox behind the part (its mirror image "
                     "on the face), a strip light in front (the chamfer's bright line), a small "
                     "lamp, a dim room; the chamfer and the side wall of a turned disc are "
                     "staging too.")
    if mac.get("iridescence"):
        words.append("The colours are the diffraction of the lights by the feed marks (period "
                     "= feed per revolution), rendered spectrally.")
    return " ".join(words)


def _diffuse_value(k, v, view: dict):
    """A value of the diffuse settings table, with its unit or why it has none."""
    if v is None:
        if k == "lamp":
            return ("in the studio's light" if view.get("light") == "studio"
                    else "no lamp in this view")
        return "not used in this view"
    if k == "mm_per_px":
        return fmt_quantity(v * MM_TO_UM, "um")
    if k == "vertical_exaggeration":
        return f"{v:g}x"
    if k == "resolution":
        return " x ".join(str(x) for x in v) + " px"
    if k == "spp":
        return f"{v} samples per pixel"
    if k == "lamp":
        return (f"directional, zenith {fmt_number(v.get('zenith_deg'))} deg, irradiance "
                f"{fmt_number(v.get('irradiance'))} (radiance units)")
    if k == "orders":
        return f"{v} diffraction orders" if v else "none: the marks are in the mesh"
    if k == "first_order_efficiency_550nm":
        return fmt_quantity(100.0 * v, "%") if v else "0 % (no grating in this view)"
    if k in ("sigma_u", "sigma_v"):
        return f"{fmt_number(v)} (rms, direction cosine)"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return fmt_number(v)
    return v


def _process_facts(c: dict, u: dict) -> list:
    rows = []

    def add(label, path, unit="", scale=1.0):
        x, y = _get(c, path), _get(u, path)
        if x is None and y is None:
            return
        f = (lambda v: _q(None if v is None else v * scale, unit))
        rows.append([label, f(x), f(y)])

    add("feed scallop: height", "scallop.height_nm", "nm")
    add("feed scallop: Sq", "scallop.Sq_nm", "nm")
    add("servo: effective lag", "servo.effective_lag_s", "ms", 1e3)
    add("servo: FTS lag against the slide", "servo.relative_lag_s", "ms", 1e3)
    add("servo: lag angle omega tau", "servo.effective_lag_angle_rad", "mrad", 1e3)
    add("servo: largest circumferential shift", "servo.max_circumferential_shift_um", "um")
    add("servo: FTS stroke", "servo.fts_stroke_um", "um")
    add("servo: FTS following error rms", "servo.fts_following_error.rms_um", "um")
    add("sculpturing: vibration overcut", "sculpt.vibration_overcut_um", "um")
    add("sculpturing: tool-edge overcut", "sculpt.tool_edge_overcut_um", "um")
    add("vibration: peak velocity", "vibration.peak_velocity_mm_s", "mm/s")
    add("burrs: height", "burrs.height_um", "um")
    add("RCSE path: X velocity max", "rcse.comparison.rcse.x_velocity_max_mm_s", "mm/s")
    add("conventional path: X velocity max", "rcse.comparison.conventional.x_velocity_max_mm_s",
        "mm/s")
    add("RCSE path: X reversals", "rcse.comparison.rcse.x_reversals")
    add("conventional path: X reversals", "rcse.comparison.conventional.x_reversals")
    add("RCSE path: profile error rms", "rcse.comparison.rcse.profile_error_rms_nm", "nm")
    add("conventional path: profile error rms",
        "rcse.comparison.conventional.profile_error_rms_nm", "nm")
    add("tool path: Z velocity max", "toolpath.z_velocity_max_mm_s", "mm/s")
    add("tool path: Z acceleration max", "toolpath.z_acceleration_max_mm_s2", "mm/s^2")
    add("tool path: cut time", "toolpath.cut_time_s", "s")
    return rows
