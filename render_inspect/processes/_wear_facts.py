"""The worn edge of a turning cut (``[tool] wear``): the followed path lifted by the
recession of the edge worn to each point, and ``metrics["tool_wear"]``: the edge at the
start and the end of the cut (and of the whole part), and the roughness against the
radius (:mod:`render_inspect.machining._wear`)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..core.toolpath import ToolPath
from ..core.units import MM_TO_M, MM_TO_NM, NM_TO_MM
from ..machining import (MM_PER_KM, SPEED_LAW, MaterialResponse, chemical_distance_km,
                         spiral_distance_km, wear_rate, wear_state, worn_path)
from ._program import cut_name

__all__ = ["wear_path", "roughness_against_radius", "wear_figure", "sculpt_wear", "worn_h_min",
           "WEAR_BANDS"]

#: radial bands of the roughness against the radius
WEAR_BANDS = 8


def _args(cfg):
    t, p = cfg.tool, cfg.process
    return dict(duty=float(t.contact_duty_cycle), scale=float(t.wear_scale),
                edge_radius_nm=float(cfg.material.edge_radius_nm),
                clearance_deg=float(t.clearance_angle_deg))


def _feed(cfg, path) -> float:
    return float(path.meta.get("feed_per_rev_mm") or cfg.process.feed_per_rev)


def _rpm(cfg):
    """The spindle speed (rpm) the chemical wear's speed law takes, None without one."""
    n = getattr(cfg.process, "spindle_rpm", None)
    return float(n) if n else None


def _at(rate, cfg, r, feed) -> tuple[float | np.ndarray, dict]:
    """The worn edge at radius r of the facing spiral (the chemical wear at the cutting
    speed along it where the spindle speed is known)."""
    p = cfg.process
    L = spiral_distance_km(r, p.workpiece_radius, feed)
    n = _rpm(cfg)
    chem = (chemical_distance_km(r, p.workpiece_radius, feed, n) if rate.chemical and n else None)
    return L, wear_state(rate, L, chemical_km=chem, **_args(cfg))


def _state(rate, cfg, r, feed) -> dict:
    L, st = _at(rate, cfg, r, feed)
    n = _rpm(cfg)
    return {"radius_mm": float(r), "cutting_distance_km": float(L), "contact_km": float(st["contact_km"]),
            "cutting_speed_m_min": 2 * math.pi * abs(float(r)) * n * MM_TO_M if n else None,
            "flank_wear_um": float(st["flank_um"]), "edge_radius_nm": float(st["edge_radius_nm"]),
            "recession_nm": float(st["recession_nm"])}


def wear_path(cfg: Any, program: ToolPath, cut_path: ToolPath) -> tuple[ToolPath, dict]:
    """(The followed path ``cut_path`` cut by the worn edge, ``metrics["tool_wear"]``)."""
    rate = wear_rate(cfg.material.preset)
    feed = _feed(cfg, program)
    worn, lift = worn_path(cut_path, rate, workpiece_radius=cfg.process.workpiece_radius,
                           feed_per_rev=feed, spindle_rpm=_rpm(cfg), **_args(cfg))
    rho = np.abs(np.asarray(cut_path.rho))
    facts = {"material": cfg.material.preset, "rates": rate.to_dict(), "wear_scale": float(cfg.tool.wear_scale),
             "contact_duty_cycle": float(cfg.tool.contact_duty_cycle),
             "speed_law": SPEED_LAW.to_dict() if rate.chemical and _rpm(cfg) else None,
             "start": _state(rate, cfg, float(rho.max()), feed) if rho.size else None,
             "end": _state(rate, cfg, float(rho.min()), feed) if rho.size else None,
             "part_start": _state(rate, cfg, float(cfg.process.workpiece_radius), feed),
             "part_end": _state(rate, cfg, float(cfg.process.inner_radius), feed),
             "lift_max_nm": float(np.max(lift)) * MM_TO_NM if lift.size else 0.0}
    return worn, facts


def roughness_against_radius(cfg: Any, machined: np.ndarray, design: np.ndarray,
                             region: Sequence[float], pixel: float,
                             bands: int = WEAR_BANDS) -> list:
    """Sa and Sq (nm, mean removed) of machined - design in ``bands`` rings of the region,
    each with the worn edge at its middle radius."""
    rate = wear_rate(cfg.material.preset)
    ny, nx = machined.shape
    x = region[0] + pixel * np.arange(nx)
    y = region[1] + pixel * np.arange(ny)
    r = np.hypot(*np.meshgrid(x, y))
    err = machined - design
    ok = np.isfinite(err)
    if not ok.any():
        return []
    edges = np.linspace(r[ok].min(), r[ok].max(), bands + 1)
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        m = ok & (r >= a) & (r <= b)
        if m.sum() < 4:
            continue
        e = err[m] - err[m].mean()
        st = _state(rate, cfg, 0.5 * (a + b), cfg.process.feed_per_rev)
        out.append({**st, "Sa_nm": float(np.mean(np.abs(e))) * MM_TO_NM,
                    "Sq_nm": float(math.sqrt(np.mean(e * e))) * MM_TO_NM, "samples": int(m.sum())})
    return out


def wear_figure(cfg: Any, wear: dict) -> dict:
    """``tool_wear.png``: the edge (radius, flank wear) over the whole part against the
    radius, and the simulated roughness in the region's rings."""
    rate = wear_rate(cfg.material.preset)
    p = cfg.process
    r = np.linspace(p.inner_radius, p.workpiece_radius, 200)
    _, st = _at(rate, cfg, r, p.feed_per_rev)
    rings = wear.get("roughness_against_radius") or []
    return {"kind": "tool_wear", "r_mm": r, "edge_radius_nm": st["edge_radius_nm"], "flank_um": st["flank_um"],
            "recession_nm": st["recession_nm"],
            "ring_r_mm": [b["radius_mm"] for b in rings], "ring_sa_nm": [b["Sa_nm"] for b in rings],
            "title": f"{cut_name(cfg)}: the edge worn along the cut ({cfg.material.preset}, rates "
                     f"{'assumed' if rate.basis == 'A' else 'sourced'})"}


def sculpt_wear(cfg: Any, lines: Sequence[tuple[np.ndarray, np.ndarray]],
                duty: float) -> tuple[Any, dict]:
    """(The ``[material]`` section with the edge radius the cut wears to on average, the
    facts ``tool_wear``) of a sculpturing cut along ``lines`` ((y, z) arrays, mm) whose edge
    is in contact for the fraction ``duty`` of the time (the vibration's contact ratio; the
    chemical wear of steel scales with it).  The edge grows linearly along the cut, so its
    mean over the cut is the edge at half the cutting distance."""
    rate = wear_rate(cfg.material.preset)
    length_km = float(sum(abs(float(ys[-1]) - float(ys[0])) for ys, _ in lines)) / MM_PER_KM
    speed = float(cfg.process.feed_mm_per_min) * MM_TO_M  # the nominal cutting speed, m/min
    args = {**_args(cfg), "duty": float(duty) * float(cfg.tool.contact_duty_cycle), "speed_m_min": speed}
    end = wear_state(rate, length_km, **args)
    mid = wear_state(rate, 0.5 * length_km, **args)
    r_mid = float(mid["edge_radius_nm"])
    facts = {"material": cfg.material.preset, "rates": rate.to_dict(), "wear_scale": float(cfg.tool.wear_scale),
             "contact_duty_cycle": args["duty"], "cutting_distance_km": length_km,
             "cutting_speed_m_min": speed, "contact_km": float(end["contact_km"]),
             "speed_law": SPEED_LAW.to_dict() if rate.chemical else None,
             "edge_radius_start_nm": float(cfg.material.edge_radius_nm),
             "edge_radius_end_nm": float(end["edge_radius_nm"]), "flank_wear_end_um": float(end["flank_um"]),
             "recession_end_nm": float(end["recession_nm"]), "edge_radius_used_nm": r_mid}
    return cfg.material.model_copy(update={"edge_radius_nm": r_mid}), facts


def worn_h_min(cfg: Any, path: ToolPath,
               resp: MaterialResponse | None) -> np.ndarray | None:
    """The minimum chip thickness (mm) at each point of ``path`` cut by the edge worn to it
    (``tool.wear``), or None without wear or a material: the material response ``resp``'s
    h_min (linear in the effective edge radius, r_e + the adhered layer) at the worn radius."""
    if resp is None or not getattr(cfg.tool, "wear", False) or resp.edge_radius_eff <= 0:
        return None
    rate = wear_rate(cfg.material.preset)
    r_e = _at(rate, cfg, path.rho, _feed(cfg, path))[1]["edge_radius_nm"] * NM_TO_MM
    layer = resp.edge_radius_eff - float(cfg.material.edge_radius_nm) * NM_TO_MM
    return resp.h_min * (r_e + layer) / resp.edge_radius_eff
