"""The memory a turning simulation needs: the spiral's points over the simulated region
(before planning, from the design's slope and the feed), the machine model's servo ticks
while it follows the path, and the peak of an in-memory cut (the figures each constant
was measured at are beside it)."""

from __future__ import annotations

from ..core.grid import grid_shape
from ..core.units import MIN_TO_S
from ..design import make_surface
from ..machining import BURR_BLOCK_BYTES, in_memory_bytes
from ..toolpath import Tool, pass_margin, region_radii
from ._contract import Plan
from ._machine import machine_of
from ._mechanics import TurningInputs
from ._program import program_path

__all__ = ["turning_points", "machine_bytes", "turning_memory"]

#: bytes per point of the commanded tool path (theta, rho, z, t and the contact points)
_PATH_BYTES = 40


def _revolutions(cfg, design) -> float:
    """Revolutions of the spiral over the simulated region, before planning: the radii the
    planner keeps (:func:`~render_inspect.toolpath.plan_turning`: the region widened by
    the passes that can reach it, 2.2 Rc m + f + 2 f for the design's largest slope m)."""
    sim, p = cfg.simulation, cfg.process
    tool = Tool.from_config(cfg.tool)
    slope = make_surface(design).max_slope(tuple(sim.region))
    f = p.feed_per_rev
    r_in, r_out = region_radii(sim.region, pass_margin(tool, slope, f))
    r_in = max(r_in, p.inner_radius)
    return max(min(r_out, p.workpiece_radius) - r_in, 0.0) / f


def turning_points(cfg: TurningInputs, plan: Plan | None = None) -> int:
    """Points of the spiral over the simulated region (estimated before planning; 0 for a
    program read from a file, not known before it is read)."""
    if plan is not None:
        return int(plan.program.points)
    if program_path(cfg):
        return 0
    return int(_revolutions(cfg, cfg.design) * cfg.process.points_per_rev) + 1


#: bytes per servo tick the machine model holds while it follows the path (commands,
#: followed positions, errors and the loops' states of every axis; measured with
#: tracemalloc: about 250), and what stays of it while the surface is cut (the followed
#: path, its commands and errors: 13 arrays, and the kernel's segments, lookup table and
#: cutting distance: 7 more)
_BYTES_PER_TICK = 8 * 32
_KEPT_BYTES_PER_TICK = 8 * 20
#: bytes per sample of the burr model's temporaries over a whole map in memory: the
#: block's figure (``BURR_BLOCK_BYTES``) less the slope angles of the whole map, which
#: the edge search no longer makes (it takes them in cells around candidate edges only:
#: the traced peak fell by 15 B a sample, 81 to 66 B measured between 1 and 9 M samples)
_BURR_MAP_BYTES = BURR_BLOCK_BYTES - 16
#: bytes per sample the texture's two factors (float64 maps) took before they were
#: computed in the cut's own maps (measured on the shipped grid scene, 1 to 9 M samples:
#: the estimate was 1.5-1.8 x the traced peak with them, 1.2-1.4 x without)
_TEXTURE_IN_PLACE_BYTES = 16
#: what stays of the machine model while the tiles of a tiled simulation run: the followed
#: path, its commands and errors (13 arrays; the cut's prepared path is counted with the
#: tiles, :func:`~render_inspect.machining.tiled_bytes`)
_TILED_KEPT_BYTES_PER_TICK = 8 * 13


def machine_bytes(cfg: TurningInputs, plan: Plan | None = None) -> int:
    """Bytes the ``[machine]`` model holds while following the path (0 on the ideal
    machine)."""
    return _ticks(cfg, plan) * _BYTES_PER_TICK


def _ticks(cfg, plan=None) -> int:
    machine = machine_of(cfg.machine)
    if machine.ideal:
        return 0
    if plan is None:
        if program_path(cfg):
            return 0
        duration = _revolutions(cfg, cfg.design) * MIN_TO_S / cfg.process.spindle_rpm
    else:
        t = plan.program.t
        duration = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    return int(duration * machine.servo_rate_hz)


def turning_memory(cfg: TurningInputs, plan: Plan | None = None) -> int:
    """Bytes an in-memory turning simulation and the writing of its outputs hold at their
    peak (:mod:`render_inspect.machining._memory`: the height arrays, the float32 channels
    of heightmap.exr, the design evaluation's temporaries and the tool path); on a
    non-ideal ``[machine]`` the servo ticks while the path is followed
    (:func:`machine_bytes`), the followed path while it is cut and the map of where each
    pass cut, with a ``[material]`` the displaced material and the machined-edge masks
    (measured with tracemalloc: within 1.5 x of the peak in every combination)."""
    shape = grid_shape(cfg.simulation.region, cfg.simulation.pixel)
    points = turning_points(cfg, plan)
    ticks = _ticks(cfg, plan)
    material = cfg.material.preset != "ideal"
    # material: pass angle, displaced material, edge masks, and then the part's texture
    # and the burr model's temporaries (smoothed map, edge masks, turns, distance transform
    # and ridge) while the cut maps are held, less the texture's two factors, which are
    # computed in the pass-angle and displaced-material maps once those are done with
    # (no maps of their own: the traced peak fell by about that); a machine alone: the
    # pass-angle map
    per_sample = ((8 * 2 + 4 + _BURR_MAP_BYTES - _TEXTURE_IN_PLACE_BYTES) if material
                  else (8 * 2 if ticks else 0))
    cutting = in_memory_bytes(shape, points, cut_sample_bytes=per_sample,
                              cut_bytes=ticks * _KEPT_BYTES_PER_TICK)
    following = ticks * _BYTES_PER_TICK + points * 2 * _PATH_BYTES
    return int(max(cutting, following))
