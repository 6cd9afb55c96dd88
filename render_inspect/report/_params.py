"""The report's parameter tables: every scene key with its value and unit, or a reason
where there is no value (a key left to its preset, to an automatic choice, or not used).

Units come from the key itself: its name (``_nm``, ``_deg``, ``_hz``, ``_mm_s2`` ...), its
schema description ("mm, grid spacing") or its type (a position or height, ``Length``,
is in mm).  A number without a unit is a ratio or a count, and the table says which
the schema says it is.
"""

from __future__ import annotations

from typing import Any
import json
import math
import re
import typing

from ..core.section import MAX_LENGTH_MM
from ..core.units import MM_TO_NM, MM_TO_UM, RAD_TO_URAD
from ._format import fmt_number

__all__ = ["key_unit", "value_text", "meaning", "section_rows", "settings_rows", "SECTION_ORDER"]

#: the scene sections the Parameters part of the report lists, in this order
SECTION_ORDER = ("design", "tool", "process", "machine", "material", "simulation", "metrology",
                 "artifacts", "rcse")

#: unit of a key by the end of its name (longest first)
_SUFFIX_UNITS = [("_nm_per_n", "nm/N"), ("_mm_s2", "mm/s^2"), ("_mm_s", "mm/s"),
                 ("_mm_per_min", "mm/min"), ("_rad_s", "rad/s"), ("_percent", "%"),
                 ("_nm", "nm"), ("_um", "um"), ("_mm", "mm"), ("_urad", "urad"),
                 ("_mrad", "mrad"), ("_rad", "rad"), ("_deg", "deg"), ("_hz", "Hz"),
                 ("_rpm", "rpm"), ("_gpa", "GPa"), ("_kg", "kg"), ("_gb", "GiB"), ("_s", "s")]
#: units a schema description may start with ("mm, grid spacing")
_DESCRIPTION_UNITS = ("mm", "um", "nm", "rad", "deg", "GiB", "electrons", "dz/dx", "Hz", "s")


def _length_bounds(metadata) -> bool:
    """The bounds of :data:`~render_inspect.core.section.Length` among ``metadata``."""
    ge = [getattr(m, "ge", None) for m in metadata or ()]
    le = [getattr(m, "le", None) for m in metadata or ()]
    return -MAX_LENGTH_MM in ge and MAX_LENGTH_MM in le


def _is_length(annotation) -> bool:
    """A ``Length`` (or a tuple of them) somewhere in the annotation."""
    if annotation is None or isinstance(annotation, (str, int, float)):
        return False
    if typing.get_origin(annotation) is typing.Annotated:
        base, *meta = typing.get_args(annotation)
        if any(_length_bounds(getattr(m, "metadata", None)) for m in meta):
            return True
        return _is_length(base)
    return any(_is_length(a) for a in typing.get_args(annotation))


def key_unit(key: str, field: Any = None) -> str:
    """The unit of scene key ``key`` ("" for a ratio, a count or a text): from the end of its
    name, from the start of its schema description, or "mm" for a position or height."""
    for suffix, unit in _SUFFIX_UNITS:
        if key.endswith(suffix):
            return unit
    desc = (getattr(field, "description", None) or "").strip()
    head = re.split(r"[,;( ]", desc, maxsplit=1)[0] if desc else ""
    if head in _DESCRIPTION_UNITS:
        return head
    m = re.search(r",\s*(mm|um|nm|electrons)\b", desc)
    if m:
        return m.group(1)
    if field is not None and (_length_bounds(getattr(field, "metadata", None))
                              or _is_length(getattr(field, "annotation", None))):
        return "mm"
    return ""


def _number(x) -> str:
    """A parameter as given: up to 6 significant figures, no trailing zeros."""
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        if math.isinf(x):
            return "infinite" if x > 0 else "-infinite"
        return f"{x:.6g}"
    return str(x)


def _none_reason(key: str, field, preset: str | None) -> str:
    """Why a key holds no value: its preset's value is used, or what the schema says None
    means (``None = ...`` / ``default ...``), or it is not used."""
    if preset:
        return f"not set: the preset {preset!r} decides"
    desc = getattr(field, "description", None) or ""
    if "limit" in key:
        return "not set: no limit"
    for pattern in (r"\bNone\s*[=:]\s*([^;)]+)", r"\b(default[^;)]*)"):
        m = re.search(pattern, desc)
        if m:
            text = m.group(1).strip()
            return f"not set: {text}{')' * (text.count('(') - text.count(')'))}"
    return "not set (not used)"


def value_text(key: str, v: Any, field: Any = None, *, preset: str | None = None) -> str:
    """One value with its unit; a reason instead of an empty value."""
    unit = key_unit(key, field)
    if v is None:
        return _none_reason(key, field, preset)
    nums = [v] if isinstance(v, (int, float)) and not isinstance(v, bool) else (
        list(v) if isinstance(v, (list, tuple)) and v
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v) else None)
    if unit == "mm" and nums and all(abs(x) < 0.1 for x in nums) and any(nums):
        # micrometre lengths (a pixel, a nose radius) read better in um
        um = [x * MM_TO_UM for x in nums]
        return ", ".join(f"{x:.6g}" for x in um) + " um"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, (list, tuple)):
        if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            if not v:
                return "empty list"
            return ", ".join(_number(x) for x in v) + (f" {unit}" if unit else "")
        return json.dumps(v) if v else "empty list"
    if isinstance(v, dict):
        return json.dumps(v)
    if isinstance(v, (int, float)):
        text = _number(v)
        if unit:
            return f"{text} {unit}"
        return text
    return str(v)


#: what a quantity is, by its unit (the meaning column of a key the schema does not describe)
_KIND_OF_UNIT = {"nm": "a length", "um": "a length", "mm": "a length",
                 "deg": "an angle", "rad": "an angle", "urad": "an angle", "mrad": "an angle",
                 "Hz": "a frequency", "s": "a time", "rpm": "a spindle speed",
                 "mm/min": "a feed rate", "mm/s": "a velocity", "mm/s^2": "an acceleration",
                 "GPa": "a modulus", "kg": "a mass", "nm/N": "a compliance", "GiB": "memory",
                 "%": "a fraction"}


def meaning(key: str, field: Any, value: Any) -> str:
    """The schema's description of the key, else what kind of quantity it is."""
    desc = (getattr(field, "description", None) or "").strip()
    unit = key_unit(key, field)
    if desc == unit:
        desc = ""
    if isinstance(value, (int, float)) and not isinstance(value, bool) and not unit:
        kind = "a count" if isinstance(value, int) else "no unit"
        return f"{desc}; {kind}" if desc else kind
    if desc:
        return desc
    if isinstance(value, bool):
        return "on or off"
    if isinstance(value, str):
        return "a choice"
    if unit:
        return f"{_KIND_OF_UNIT.get(unit, 'a quantity')}, {unit}"
    return "a list" if isinstance(value, (list, tuple)) else "not described by the schema"


def section_rows(name: str, section: Any, values: dict, *, varied: dict | None = None,
                 prefix: str = "", preset: str | None = None) -> list[tuple[str, list[list[str]]]]:
    """Tables of one scene section: ``[(title, rows)]``, one table for the section's own
    keys and one per nested section (``[machine.z]``).  Rows: key, value with unit (or
    the two variants' values when the comparison varies the key), meaning.

    Parameters
    ----------
    name : str
        The section's name (``"machine"``).
    section : pydantic model or None
        The section object of the scene (its schema gives units and meanings).
    values : dict
        The section as a dict (``scene.to_dict()[name]``).
    varied : dict, optional
        Dotted key -> ((set by variant a, its value), (set by variant b, its value)).
    """
    varied = varied or {}
    fields = type(section).model_fields if section is not None else {}
    if preset is None and name in ("machine", "material") and values.get("preset") != "ideal":
        preset = values.get("preset")
    own, nested = [], []
    for k, v in values.items():
        field = fields.get(k)
        full = f"{prefix}{name}.{k}"
        sub = getattr(section, k, None) if section is not None else None
        if isinstance(v, dict) and hasattr(type(sub), "model_fields"):
            nested.extend(section_rows(f"{name}.{k}", sub, v, varied=varied, prefix=prefix,
                                       preset=preset))
            continue
        hit = [key for key in varied if key == full or key.startswith(full + ".")]
        if hit:
            texts = []
            for tag, (given, value) in zip("ab", varied[hit[0]]):
                if not given:
                    texts.append(f"{tag}: as the scene, {value_text(k, v, field, preset=preset)}")
                elif value is None:
                    desc = getattr(field, "description", None) or ""
                    texts.append(f"{tag}: inf (ideal)" if "inf" in desc else
                                 f"{tag}: cleared, {_none_reason(k, field, preset)}")
                else:
                    texts.append(f"{tag}: {value_text(k, value, field)}")
            own.append([k, " | ".join(texts), meaning(k, field, v)])
            continue
        text = value_text(k, v, field, preset=preset)
        if isinstance(v, dict) and v and section is None:
            text = ", ".join(f"{kk} = {value_text(kk, vv)}" for kk, vv in v.items())
        own.append([k, text, meaning(k, field, v)])
    return ([(f"[{prefix}{name}]", own)] if own else []) + nested


#: units of the machine model's own settings (machining units: mm, rad, s), by key
_SETTING_UNITS = {"bandwidth_hz": ("Hz", 1.0), "delay_s": ("s", 1.0),
                  "velocity_limit": ("mm/s", 1.0), "acceleration_limit": ("mm/s^2", 1.0),
                  "servo_rate_hz": ("Hz", 1.0), "mass_kg": ("kg", 1.0), "mode_hz": ("Hz", 1.0),
                  "async_bandwidth_hz": ("Hz", 1.0), "x_straightness_length": ("mm", 1.0),
                  "z_compliance_nm_per_n": ("nm/N", 1.0), "y_compliance_nm_per_n": ("nm/N", 1.0)}

def settings_rows(settings: dict, *, path: str = "") -> list[list[str]]:
    """Rows (setting, value with unit) of a machine model's resolved settings (lengths in
    mm and angles in rad, as the machining model holds them; shown in nm and urad)."""
    rows = []
    for k, v in (settings or {}).items():
        key = f"{path}{k}"
        if isinstance(v, dict):
            rows.extend(settings_rows(v, path=key + "."))
            continue
        axis = path.rstrip(".").split(".")[-1] if path else ""
        if v is None:
            rows.append([key, "no limit" if "limit" in k else "not used"])
        elif isinstance(v, bool) or isinstance(v, str):
            rows.append([key, value_text(k, v)])
        elif k == "noise_rms" and isinstance(v, (int, float)):
            rows.append([key, f"{fmt_number(v * RAD_TO_URAD)} urad" if axis == "c"
                         else f"{fmt_number(v * MM_TO_NM)} nm"])
        elif k.endswith("_rms") and isinstance(v, (int, float)):
            rows.append([key, f"{fmt_number(v * MM_TO_NM)} nm"])
        elif isinstance(v, (list, tuple)) and k.endswith("_sync"):
            tilt = k.startswith("tilt")
            parts = [f"harmonic {int(h)}: "
                     f"{fmt_number(a * (RAD_TO_URAD if tilt else MM_TO_NM))} "
                     f"{'urad' if tilt else 'nm'} at {fmt_number(math.degrees(p))} deg"
                     for h, a, p in v]
            rows.append([key, "; ".join(parts) or "none listed"])
        elif isinstance(v, (list, tuple)):
            rows.append([key, json.dumps(v) if v else "none listed"])
        elif k in _SETTING_UNITS:
            unit, scale = _SETTING_UNITS[k]
            rows.append([key, f"{fmt_number(v * scale, sig=4)} {unit}"])
        elif k.endswith("_ff"):
            rows.append([key, f"{fmt_number(v, sig=4)} (feed-forward gain)"])
        elif k == "damping" or k.endswith("_damping"):
            rows.append([key, f"{fmt_number(v, sig=4)} (damping ratio)"])
        else:
            unit = key_unit(k)
            rows.append([key, f"{fmt_number(v, sig=4)}{' ' + unit if unit else ''}"])
    return rows
