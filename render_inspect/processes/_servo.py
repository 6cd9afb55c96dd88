"""Hybrid tool servo turning (seed 002): slow slide servo (S3) + fast tool servo (FTS).

Both servos cut along the same inward spiral as STS.  The compensated Z program of the
whole design is split into the slow slide's share and the FTS stroke
(:func:`~render_inspect.machining.split_commands`: ``hts`` puts the design's base on the
slow slide, ``fts`` its rotationally symmetric part); each share goes through its servo
(:func:`~render_inspect.machining.followed_path`, ``[artifacts.servo]``), and the machined
surface is the envelope of the tool nose along the followed path.
"""

from __future__ import annotations

import math
import time
from typing import Literal

import numpy as np

from ..core.errors import SceneError
from ..machining import followed_path, split_commands
from ._mechanics import machine_of, turn
from ._registry import Cut, Plan, register_process
from ._turning import (
    TurningProcessConfig,
    compensation_variants,
    plan_spiral,
    tool_of,
    toolpath_facts,
    turning_header,
    turning_memory,
    turning_precheck,
)

__all__ = ["ServoProcessConfig"]


class ServoProcessConfig(TurningProcessConfig):
    """``[process]`` of fast (``fts``) or hybrid slow + fast (``hts``) tool servo turning.
    ``hts`` needs ``design.type = "compound"`` (base on the slow slide, feature on the
    FTS)."""
    kind: Literal["fts", "hts"]

    def check_with(self, scene) -> None:
        super().check_with(scene)
        if self.kind == "hts" and scene.design.type != "compound":
            raise ValueError(
                "process.kind = 'hts' needs design.type = 'compound' ([design.base] on the slow slide, "
                f"[design.feature] on the fast tool servo), received design.type = "
                f"{scene.design.type!r}; use process.kind = 'fts' for a single surface")


def _error_stats(err) -> dict:
    err = np.asarray(err)
    return {"rms_um": float(np.sqrt(np.mean(err * err)) * 1e3),
            "max_um": float(np.max(np.abs(err)) * 1e3)}


def plan(scene, surface, *, region=None) -> Plan:
    kind = scene.process.kind
    if kind == "hts" and not hasattr(surface, "base"):
        raise SceneError("process.kind = 'hts' needs design.type = 'compound'")
    t0 = time.perf_counter()
    path = plan_spiral(scene, surface, region=region)
    tool = tool_of(scene)
    z_slow, z_fts = split_commands(path, kind, base=surface.base if kind == "hts" else None,
                                   nose_radius=tool.nose_radius,
                                   compensation=scene.process.compensation,
                                   half_width=tool.half_width)
    return Plan(path, {"toolpath": toolpath_facts(path, scene)},
                {"toolpath": time.perf_counter() - t0}, {"z_slow": z_slow, "z_fts": z_fts})


def _legacy_servo_set(servo) -> bool:
    return (servo.delay_s != 0 or servo.bandwidth_hz is not None
            or servo.slow_bandwidth_hz is not None)


def cut(scene, surface, plan: Plan) -> Cut:
    kind = scene.process.kind
    servo = scene.artifacts.servo
    path = plan.program
    z_slow, z_fts = plan.data["z_slow"], plan.data["z_fts"]
    omega = 2 * math.pi * scene.process.spindle_rpm / 60.0
    r_max = float(np.max(path.rho)) if path.points else 0.0
    machine = machine_of(scene)
    timing = {}
    if machine.ideal:
        # [artifacts.servo]: the slow slide and the FTS as plain second-order servos
        t0 = time.perf_counter()
        fpath, zs_f, zf_f = followed_path(path, z_slow, z_fts,
                                          slow_bandwidth_hz=servo.slow_bandwidth_hz,
                                          slow_damping=servo.slow_damping,
                                          fts_bandwidth_hz=servo.bandwidth_hz,
                                          fts_damping=servo.damping, fts_delay_s=servo.delay_s)
        timing["servo"] = time.perf_counter() - t0
        t = turn(scene, surface, path, followed=fpath)
        fts_err, slow_err = zf_f - z_fts, zs_f - z_slow
        settings = {"delay_s": servo.delay_s, "bandwidth_hz": servo.bandwidth_hz,
                    "damping": servo.damping, "slow_bandwidth_hz": servo.slow_bandwidth_hz,
                    "slow_damping": servo.slow_damping}
    else:
        if _legacy_servo_set(servo):
            raise SceneError("artifacts.servo applies to machine.preset = 'ideal' only; with "
                             f"machine.preset = {scene.machine.preset!r} set the fast tool servo "
                             "in [machine.fts] (bandwidth_hz, damping, delay_s) and the slow slide "
                             "in [machine.z]")
        t = turn(scene, surface, path, z_fts=z_fts)
        fp = t["followed_path"]
        fts_err = -np.interp(path.t, fp.t, fp.errors["fts"])
        slow_err = -np.interp(path.t, fp.t, fp.errors["z"])
        settings = {"delay_s": machine.fts.delay_s, "bandwidth_hz": machine.fts.bandwidth_hz,
                    "damping": machine.fts.damping, "slow_bandwidth_hz": machine.z.bandwidth_hz,
                    "slow_damping": machine.z.damping, "fts_sync": machine.fts_sync}
    timing.update(t["timing"])
    bw = settings["bandwidth_hz"]
    lag = settings["delay_s"] + (2 * settings["damping"] / (2 * math.pi * bw) if bw else 0.0)
    servo_m = {"kind": kind, **settings, "omega_rad_s": omega,
               "lag_angle_rad": omega * settings["delay_s"],
               "effective_lag_s": lag, "effective_lag_angle_rad": omega * lag,
               "max_circumferential_shift_um": r_max * omega * lag * 1e3,
               "fts_stroke_um": float(np.ptp(z_fts) * 1e3) if z_fts.size else 0.0,
               "slow_stroke_um": float(np.ptp(z_slow) * 1e3) if z_slow.size else 0.0,
               "fts_following_error": _error_stats(fts_err),
               "slow_following_error": _error_stats(slow_err)}
    facts = {"servo": servo_m, **t["facts"]}
    meta = {"process": kind, "compensation": scene.process.compensation,
            "seed": scene.simulation.seed, "machine": scene.machine.preset,
            "material": scene.material.preset,
            "servo": {k: servo_m[k] for k in ("delay_s", "bandwidth_hz", "damping",
                                               "slow_bandwidth_hz", "slow_damping")}}
    return Cut(t["machined"], t["design"], facts, timing, meta, followed=t["followed"],
               plots=t["plots"])


def program_region(scene):
    return tuple(scene.simulation.region)


register_process(ServoProcessConfig, plan=plan, cut=cut, estimate_memory=turning_memory,
                 precheck=turning_precheck,
                 program_region=program_region, program_header=turning_header,
                 variants=compensation_variants)
