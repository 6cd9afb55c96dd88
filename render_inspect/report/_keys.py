"""Scene keys and metrics in words, with their units (figure axes, report tables).

Lengths in the scene are millimetres; a key whose name ends in a unit (``_nm``,
``_deg``, ``_hz``, ...) carries it.
"""

from __future__ import annotations

__all__ = ["key_label", "key_unit"]

#: Units of scene keys whose names do not carry one (lengths are mm).
_UNITS = {"tool.nose_radius": "mm", "process.workpiece_radius": "mm", "simulation.pixel": "mm",
          "process.depth_of_cut": "mm", "process.arc_length": "mm", "process.feed_per_rev": "mm/rev",
          "tool.edge_radius": "mm", "process.step_over": "mm", "process.pitch": "mm",
          "machining.time_min": "min"}
#: unit suffixes of key names (longest first) and the unit they name
_SUFFIXES = (("_mm_per_min", "mm/min"), ("_mm_per_rev", "mm/rev"), ("_per_rev", "mm/rev"),
             ("_nm", "nm"), ("_um", "um"), ("_mm", "mm"), ("_deg", "deg"), ("_rad", "rad"),
             ("_hz", "Hz"), ("_rpm", "rpm"), ("_s", "s"), ("_gb", "GB"), ("_percent", "%"),
             ("_pct", "%"))
#: words of key names that read better otherwise
_WORDS = {"spindle_rpm": "spindle speed", "feed_mm_per_min": "feed rate",
          "feed_per_rev": "feed per revolution", "time_min": "time"}


def key_label(key: str) -> str:
    """A sweep key or metric in words with its unit: ``tool.nose_radius`` -> "tool nose
    radius (mm)", ``residual.Sq_nm`` -> "residual Sq (nm)", ``process.spindle_rpm`` ->
    "process spindle speed (rpm)"; a key already in words is kept."""
    parts = str(key).split(".")
    last, unit = parts[-1], _UNITS.get(key)
    if last in _WORDS:
        word = _WORDS[last]
        unit = unit or next((u for suf, u in _SUFFIXES if last.endswith(suf)), None)
    else:
        word = last
        for suf, u in _SUFFIXES:
            if last.endswith(suf) and len(last) > len(suf):
                word, unit = last[:-len(suf)], unit or u
                break
    words = " ".join(p.replace("_", " ") for p in [*parts[:-1], word] if p)
    return f"{words} ({unit})" if unit else words


def key_unit(key: str) -> str:
    """The unit of a scene key or metric ("" where it has none or it is not known)."""
    label = key_label(key)
    return label[label.rindex("(") + 1:-1] if label.endswith(")") else ""
