"""Slow tool servo (STS) turning (seed 000): the Z axis follows the design along the
inward spiral; the machined surface is the envelope of the tool nose."""

from __future__ import annotations

import time
from typing import Literal

from ._mechanics import followed_program, turn
from ._registry import Cut, Plan, register_process
from ._turning import (
    TurningProcessConfig,
    compensation_variants,
    plan_spiral,
    toolpath_facts,
    turning_header,
    turning_memory,
    turning_precheck,
)

__all__ = ["StsProcessConfig"]


class StsProcessConfig(TurningProcessConfig):
    """``[process]`` of slow-tool-servo turning."""
    kind: Literal["sts"] = "sts"


def plan(scene, surface, *, region=None) -> Plan:
    t0 = time.perf_counter()
    path = plan_spiral(scene, surface, region=region)
    return Plan(path, {"toolpath": toolpath_facts(path, scene)},
                {"toolpath": time.perf_counter() - t0})


def cut(scene, surface, plan: Plan) -> Cut:
    t = turn(scene, surface, plan.program)
    return Cut(t["machined"], t["design"], t["facts"], t["timing"],
               {"process": "sts", "compensation": scene.process.compensation,
                "seed": scene.simulation.seed, "machine": scene.machine.preset,
                "material": scene.material.preset}, followed=t["followed"], plots=t["plots"])


def envelope_path(scene, surface, plan: Plan):
    """The path whose nose envelope is the machined surface (tiled simulations): the
    program as the scene's machine follows it."""
    return followed_program(scene, plan.program), {
        "process": "sts", "compensation": scene.process.compensation,
        "seed": scene.simulation.seed, "machine": scene.machine.preset, "material": "ideal"}


register_process(StsProcessConfig, plan=plan, cut=cut, estimate_memory=turning_memory,
                 precheck=turning_precheck,
                 program_header=turning_header, variants=compensation_variants,
                 envelope_path=envelope_path)
