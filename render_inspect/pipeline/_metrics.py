"""The one metrics builder: every command's ``metrics.json`` is assembled and written here
(:func:`write_metrics`), so the contract keys (docs/formats.md) are the same whichever
way the pipeline was run.

Documents: a simulation's (:func:`simulation_metrics`, also for maps simulated tile by
tile), a compared variant's and the comparison's, a sweep point's, a measurement's, an
analysis's and an instrument characterisation's; the ``toolpath`` command's
``toolpath.json``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from pathlib import Path

from .. import __version__
from ..io import write_json
from ..machining import residual_metrics

if TYPE_CHECKING:
    from ..processes import Plan, Traits, VariantPair
    from ..scene import Scene

__all__ = ["simulation_metrics", "tiled_metrics", "variant_metrics", "comparison_metrics",
           "toolpath_metrics", "measurement_metrics", "analysis_metrics",
           "characterisation_metrics", "point_metrics", "write_metrics", "METRICS_FILE",
           "diffuse_summary"]

#: the file every command writes its metrics into
METRICS_FILE = "metrics.json"


def write_metrics(folder: str | Path, doc: dict, name: str = METRICS_FILE) -> Path:
    """Write the metrics document ``doc`` as ``folder/metrics.json`` (strict JSON, keys
    sorted, atomically)."""
    return write_json(Path(folder) / name, doc)


def _merge(dst: dict, src: dict) -> None:
    for k, v in src.items():
        if isinstance(v, dict) and isinstance(dst.get(k), dict):
            dst[k].update(v)
        else:
            dst[k] = v


def _simulation_head(scene: Scene, traits, seed, shape, pixel, origin, timing: dict,
                     residual: dict) -> dict:
    # (imported here: the commands that write no simulation, analyze, load no process)
    from ..processes import cut_name

    return {"software_version": __version__, "scene_name": scene.name,
            "run_name": cut_name(scene), "process": traits.name,
            "compensation": traits.compensation, "seed": seed,
            "samples": int(shape[0] * shape[1]),
            "grid": {"shape": [int(shape[0]), int(shape[1])], "pixel_mm": float(pixel),
                     "origin_mm": [float(origin[0]), float(origin[1])]},
            "timing_s": dict(timing), "residual": residual}


def _program_facts(m: dict, plan) -> None:
    _merge(m, plan.facts)
    m.setdefault("toolpath", {}).setdefault("points", int(plan.program.points))


def simulation_metrics(scene: Scene, sim: Any) -> dict:
    """``metrics.json`` of one simulation (:class:`~render_inspect.pipeline.Simulation`):
    ``software_version``, ``scene_name``, ``run_name`` (what the titles call the cut:
    :func:`~render_inspect.processes.cut_name`), ``process``, ``compensation``, ``seed``,
    ``samples``, ``grid``, ``timing_s`` (``toolpath``, ``simulate``, ...), ``residual``
    (``Sa_nm, Sq_nm, Sz_nm, Sp_nm, Sv_nm, min_nm``, ...), ``toolpath`` (``points``,
    ``revolutions``, ``feed_per_rev_mm``, kinematics), the process's own facts and, for
    lenslet designs, ``lenslets`` (and ``msa`` for an array on a base)."""
    hm = sim.heightmap
    m = _simulation_head(scene, sim.traits, scene.simulation.seed, hm.shape, hm.pixel,
                         hm.origin, sim.timing_s, residual_metrics(hm))
    _program_facts(m, sim.plan)
    _merge(m, sim.cut.facts)
    if sim.lenslets is not None:
        m["lenslets"] = sim.lenslets
    if sim.msa is not None:
        m["msa"] = sim.msa
    return m


def tiled_metrics(scene: Scene, plan: Plan, traits: Traits, residual: dict, shape: Sequence[int],
                  origin: Sequence[float], timing: dict,
                  facts: dict | None = None) -> dict:
    """``metrics.json`` of a tiled simulation: the keys of :func:`simulation_metrics`, with
    ``residual`` reduced across tiles (:func:`~render_inspect.machining.metrics_from_moments`)
    and the cut's ``facts`` (the machine, its following error, the material) summed over
    them."""
    m = _simulation_head(scene, traits, scene.simulation.seed, shape,
                         scene.simulation.pixel, origin, timing, residual)
    _program_facts(m, plan)
    _merge(m, facts or {})
    return m


def variant_metrics(sim_metrics: dict, *, name: str, label: str, measured: dict, filtered: dict,
                    interferometer: dict, diffuse: dict, mitsuba_variant: str,
                    timing: dict) -> dict:
    """A compared variant's ``metrics.json``: its simulation's metrics with what was
    measured (``measured``), its waviness (``filtered``), the interferometer and the
    diffuse views."""
    m = dict(sim_metrics)
    m.update({"variant": {"name": name, "label": label}, "measured": measured,
              "filtered": filtered, "interferometer": interferometer, "diffuse": diffuse,
              "mitsuba_variant": mitsuba_variant})
    m["timing_s"] = dict(timing)
    return m


def comparison_metrics(scene: Scene, *, pair: VariantPair, variants: Sequence[Any],
                       difference: dict, filters: dict,
                       windows: dict, seed: int, mitsuba_variant: str, render_settings: dict,
                       measured_file: dict | None, total_s: float, report: str) -> dict:
    """``compare``'s ``metrics.json``: the pair, both variants' metrics (under their names),
    the difference, the filters, the windows, the render settings and the measured file's
    comparison."""
    a, b = variants
    # (imported here, as in _simulation_head)
    from ..processes import cut_name

    metrics: dict[str, Any] = {
        "variants": [{"name": v.name, "label": v.label, "values": pv.values}
                     for v, pv in zip(variants, pair.variants)],
        "pair": {"key": pair.key, "about": pair.about, "identical": difference["identical"]},
        a.name: {k: x for k, x in a.metrics.items() if not k.startswith("_")},
        b.name: {k: x for k, x in b.metrics.items() if not k.startswith("_")},
        "difference": {k: v for k, v in difference.items() if k != "identical"},
        "filters": dict(filters),
        "windows": windows,
        "software_version": __version__, "seed": seed,
        "mitsuba_variant": mitsuba_variant,
        "scene": scene.to_dict(), "run_name": cut_name(scene),
        "render_settings": render_settings,
    }
    if "lenslets" in metrics[a.name]:
        metrics["lenslets"] = metrics[a.name]["lenslets"]
    edge = compared_tool_edge({v.name: metrics[v.name].get("tool_edge") for v in variants})
    if edge is not None:
        metrics["tool_edge"] = edge
    if measured_file is not None:
        metrics["measured_file"] = measured_file
    metrics["timing_s"] = {"total": total_s}
    metrics["report"] = report
    return metrics


#: what ``compare``'s ``tool_edge`` keeps of each variant's
_EDGE_KEYS = ("source", "measured_range_deg", "compensation", "contact_angle_range_deg",
              "imprint_predicted_pv_nm", "imprint_predicted_rms_nm", "form_error_pv_nm",
              "form_error_rms_nm", "warnings")


def compared_tool_edge(by_variant: dict) -> dict | None:
    """``compare``'s top-level ``tool_edge``: the measured edge's ``source`` and
    ``measured_range_deg`` (those of the variants cut with one; null where their edges
    differ) and, under ``variants``, each variant's compensation, contact angles,
    predicted imprint, form error and warnings (null for a variant cut with a circular
    nose); None when neither variant has a measured edge."""
    have = [e for e in by_variant.values() if e]
    if not have:
        return None

    def common(key: str) -> Any:
        values = [e.get(key) for e in have]
        return values[0] if all(v == values[0] for v in values) else None

    return {"source": common("source"), "measured_range_deg": common("measured_range_deg"),
            "variants": {name: None if not e else {k: e.get(k) for k in _EDGE_KEYS}
                         for name, e in by_variant.items()}}


def toolpath_metrics(scene_name: str, facts: dict) -> dict:
    """``toolpath.json`` of the ``toolpath`` command: the program's facts."""
    return {"software_version": __version__, "scene_name": scene_name, **facts}


def measurement_metrics(source: str | Path, measure: dict, timing: dict) -> dict:
    """``measure``'s ``metrics.json``."""
    return {"software_version": __version__, "source": str(source), "measure": measure,
            "timing_s": dict(timing)}


def analysis_metrics(analysis: dict, *, path: str | Path, files: dict, timing: dict) -> dict:
    """``analyze``'s ``metrics.json``: the analysis's metrics with where the map came
    from (``input``), the files written, the version and the timing."""
    metrics = dict(analysis)
    src = metrics.pop("source", {})
    metrics["input"] = {"path": str(Path(path)), "reader": src.get("reader"),
                        "format": src.get("format"), "format_name": src.get("format_name"),
                        "units_in_file": src.get("units_in_file"),
                        "units_in_file_from": src.get("units_in_file_from"),
                        "instrument": src.get("instrument") or None,
                        "instrument_fields": src.get("instrument_fields") or {},
                        "date": src.get("date") or None, "n_invalid": src.get("n_invalid"),
                        "channel": src.get("channel")}
    if src.get("library_units"):
        metrics["input"]["library_units"] = src["library_units"]
    metrics["files"] = files
    metrics["software_version"] = __version__
    metrics["command"] = "analyze"
    metrics["timing_s"] = dict(timing)
    return metrics


def characterisation_metrics(metrics: dict, settings: dict, timing: dict) -> dict:
    """``characterise``'s ``metrics.json``."""
    return {"software_version": __version__, "characterise": metrics,
            "instrument_settings": settings, "timing_s": dict(timing)}


def point_metrics(sim_metrics: dict, *, render: dict | None = None, measured: dict | None = None,
                  compare: dict | None = None) -> dict:
    """A sweep point's ``metrics.json``: its simulation's metrics and what its ``[run]``
    added (``render``, ``measured``, ``compare``)."""
    m = dict(sim_metrics)
    if render is not None:
        m.update(render)
    if measured is not None:
        m["measured"] = measured
    if compare is not None:
        m["compare"] = compare
    return m


def diffuse_summary(meta: dict) -> dict:
    """What the metrics say of a diffuse image (its settings, size, light, material)."""
    sc = meta.get("scale") or {}
    out = {k: meta[k] for k in ("view", "spp", "seed", "vertical_exaggeration", "window_mm",
                                 "mitsuba_variant")}
    out.update(resolution=[meta["camera"]["width"], meta["camera"]["height"]],
               light=meta["light"]["type"], lamp=meta.get("lamp"),
               material=meta["material"]["type"],
               iridescence=bool(meta["material"].get("grating")),
               mm_per_px=sc.get("mm_per_px") or sc.get("mm_per_px_at_target"))
    for k in ("orders", "first_order_efficiency_550nm", "sigma_u", "sigma_v"):
        if k in meta["material"]:
            out[k] = meta["material"][k]
    return out
