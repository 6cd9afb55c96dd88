"""The one metrics builder: every command's ``metrics.json`` content comes from here, so
the contract keys (docs/formats.md) are the same whichever way the pipeline was run."""

from __future__ import annotations

import warnings

from .. import __version__
from ..core.toolpath import ToolPath
from ..machining import design_grid, residual_metrics
from ..metrology import characterise_msa, lenslet_table

__all__ = ["simulation_metrics", "lenslet_metrics", "msa_metrics", "tiled_metrics"]


def lenslet_metrics(surface, heightmap) -> list | None:
    """The ``lenslets`` table (fitted centres, dislocations, form errors) of a lenslet
    design, or None when the design has no lenslets.

    A compound design whose feature is the lenslet array (a microstructure on a freeform
    base, seed 002) is evaluated on the machined map minus the base; a plain array or
    lenslet rings on the machined map.  Lenslets cut by the simulated window are left out.
    """
    feature = getattr(surface, "feature", None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # lenslets cut by the window's border are left out
        if feature is not None and hasattr(surface, "base"):
            if not hasattr(feature, "centers"):
                return None
            region = (heightmap.x[0], heightmap.y[0], heightmap.x[-1], heightmap.y[-1])
            base = design_grid(surface.base, region, heightmap.pixel)
            return lenslet_table((heightmap.machined - base, heightmap.pixel,
                                  tuple(heightmap.origin)), feature,
                                 aperture_radius=getattr(feature, "aperture_radius", None))
        if hasattr(surface, "centers"):
            return lenslet_table(heightmap, surface, which="machined")
    return None


def msa_metrics(surface, heightmap, metrology=None) -> tuple[list, dict] | None:
    """Seed 002's characterisation of a lenslet array on a base (a compound design whose
    feature is the array): outliers, 6-DOF registration of the design to the machined map
    (base first, then all data), separation, per-lenslet fits against the registered
    design, base form error (:func:`~render_inspect.metrology.characterise_msa`, with the
    scene's ``[metrology]`` settings).  Returns (``lenslets`` table, ``msa`` facts:
    registration, base form error, outlier count, summary), or None for other designs.
    What a rigid set-up (or a constant servo lag) does is registered away; what is left
    are the dislocations that survive registration."""
    feature = getattr(surface, "feature", None)
    if feature is None or not hasattr(surface, "base") or not hasattr(feature, "centers"):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # lenslets cut by the window's border are left out
        res = characterise_msa(heightmap.machined, surface, pixel=heightmap.pixel,
                               origin=tuple(heightmap.origin),
                               aperture_radius=getattr(feature, "aperture_radius", None),
                               metrology=metrology)
    reg = res["registration"]
    msa = {"registration": None if reg is None else
           {k: reg[k] for k in ("tx_mm", "ty_mm", "tz_mm", "alpha_rad", "beta_rad", "gamma_rad",
                                "rms_mm", "n_points") if k in reg},
           "base_form_error": res["base"], "outliers": res["outliers"], "summary": res["summary"]}
    return res["lenslets"], msa


def _merge(dst: dict, src: dict) -> None:
    for k, v in src.items():
        if isinstance(v, dict) and isinstance(dst.get(k), dict):
            dst[k].update(v)
        else:
            dst[k] = v


def simulation_metrics(scene, sim) -> dict:
    """``metrics.json`` of one simulation (:class:`~render_inspect.pipeline.Simulation`):
    ``software_version``, ``scene_name``, ``process``, ``compensation``, ``seed``,
    ``samples``, ``grid``, ``timing_s`` (``toolpath``, ``simulate``, ...), ``residual``
    (``Sa_nm, Sq_nm, Sz_nm, Sp_nm, Sv_nm, min_nm``, ...), ``toolpath`` (``points``,
    ``revolutions``, ``feed_per_rev_mm``, kinematics), the process's own facts and, for
    lenslet designs, ``lenslets``."""
    hm = sim.heightmap
    m = {"software_version": __version__, "scene_name": scene.name,
         "process": scene.process.kind, "compensation": scene.process.compensation,
         "seed": scene.simulation.seed, "samples": int(hm.design.size),
         "grid": {"shape": list(hm.shape), "pixel_mm": hm.pixel, "origin_mm": list(hm.origin)},
         "timing_s": dict(sim.timing_s),
         "residual": residual_metrics(hm)}
    _merge(m, sim.plan.facts)
    _merge(m, sim.cut.facts)
    prog = sim.program
    if isinstance(prog, ToolPath):
        tp = m.setdefault("toolpath", {})
        tp.setdefault("points", int(prog.points))
        tp.setdefault("revolutions", prog.revolutions)
        tp.setdefault("feed_per_rev_mm", scene.process.feed_per_rev)
    if sim.lenslets is not None:
        m["lenslets"] = sim.lenslets
    if getattr(sim, "msa", None) is not None:
        m["msa"] = sim.msa
    return m


def tiled_metrics(scene, plan, residual: dict, shape, origin, timing: dict) -> dict:
    """``metrics.json`` of a tiled simulation: the keys of :func:`simulation_metrics`, with
    ``residual`` reduced across tiles (``render_inspect.machining._metrics``)."""
    m = {"software_version": __version__, "scene_name": scene.name,
         "process": scene.process.kind, "compensation": scene.process.compensation,
         "seed": scene.simulation.seed, "samples": int(shape[0] * shape[1]),
         "grid": {"shape": [int(shape[0]), int(shape[1])], "pixel_mm": float(scene.simulation.pixel),
                  "origin_mm": [float(origin[0]), float(origin[1])]},
         "timing_s": dict(timing), "residual": residual}
    _merge(m, plan.facts)
    prog = plan.program
    if isinstance(prog, ToolPath):
        tp = m.setdefault("toolpath", {})
        tp.setdefault("points", int(prog.points))
        tp.setdefault("revolutions", prog.revolutions)
        tp.setdefault("feed_per_rev_mm", scene.process.feed_per_rev)
    return m
