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
from ._registry import Cut, Plan, Variant, VariantPair, register_process
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


def lag_variants(scene) -> VariantPair:
    """The pair ``compare`` puts side by side for tool-servo turning: the servos as the
    scene sets them (the slow slide and the FTS of ``[machine]``, or the ``[artifacts.servo]``
    model on the ideal machine: the lag that rotates every feature by ``omega tau`` and
    shifts it by ``r omega tau``, seed 002's spiral dislocations) against ideal servos
    that follow their commands exactly.  A scene without servo dynamics gets the turning
    pair (compensation on/off) instead."""
    sv = scene.artifacts.servo
    omega = 2 * math.pi * scene.process.spindle_rpm / 60.0
    machine = machine_of(scene)
    if not machine.ideal and not (machine.z.ideal and machine.fts.ideal):
        # the machine's slow slide (Z) and FTS: ideal = no loop (inf bandwidth), no
        # latency, no disturbance; the spindle, X and the error motions stay as set
        parts = []
        for name, ax in (("FTS", machine.fts), ("slide", machine.z)):
            if ax.bandwidth_hz is not None:
                parts.append(f"{name} {ax.bandwidth_hz:.4g} Hz, velocity feed-forward "
                             f"{ax.velocity_ff:.3g}")
            if ax.delay_s > 0:
                parts.append(f"{name} delay {ax.delay_s * 1e3:.3g} ms")
        ideal = {}
        for ax in ("fts", "z"):
            ideal.update({f"machine.{ax}.bandwidth_hz": math.inf, f"machine.{ax}.delay_s": 0.0,
                          f"machine.{ax}.noise_nm": 0.0})
        return VariantPair(
            Variant("servo_lag", f"servos of the {scene.machine.preset} machine ("
                                 + "; ".join(parts) + ")", {}),
            Variant("ideal_servo", "ideal slow slide and FTS (no lag, no disturbance)", ideal),
            key="machine.fts, machine.z",
            about=("Servo lag on against off: the slow slide and the fast tool servo as the "
                   f"{scene.machine.preset} machine has them, against servos that follow "
                   f"their commands exactly (spindle, X and error motions unchanged); at "
                   f"{scene.process.spindle_rpm:g} rpm a lag tau turns every feature by "
                   f"omega tau about the spindle axis and shifts it by r omega tau along the "
                   f"circumference (seed 002's spiral dislocations)."))
    if not _legacy_servo_set(sv):
        return compensation_variants(scene)
    parts = []
    if sv.delay_s > 0:
        parts.append(f"delay {sv.delay_s * 1e3:.3g} ms")
    if sv.bandwidth_hz is not None:
        parts.append(f"FTS {sv.bandwidth_hz:.4g} Hz")
    if sv.slow_bandwidth_hz is not None:
        parts.append(f"slide {sv.slow_bandwidth_hz:.4g} Hz")
    lag = sv.delay_s + (2 * sv.damping / (2 * math.pi * sv.bandwidth_hz) if sv.bandwidth_hz else 0.0)
    return VariantPair(
        Variant("servo_lag", "servo lag as set (" + ", ".join(parts) + ")", {}),
        Variant("ideal_servo", "ideal servo (no lag)",
                {"artifacts.servo.delay_s": 0.0, "artifacts.servo.bandwidth_hz": None,
                 "artifacts.servo.slow_bandwidth_hz": None}),
        key="artifacts.servo",
        about=(f"Servo lag on against off: a lag of {lag * 1e3:.3g} ms at "
               f"{scene.process.spindle_rpm:g} rpm turns every feature by omega tau = "
               f"{omega * lag * 1e3:.3g} mrad about the spindle axis, i.e. shifts it by "
               f"r omega tau along the circumference (seed 002's spiral dislocations)."))


def program_region(scene):
    return tuple(scene.simulation.region)


register_process(ServoProcessConfig, plan=plan, cut=cut, estimate_memory=turning_memory,
                 precheck=turning_precheck,
                 program_region=program_region, program_header=turning_header,
                 variants=lag_variants)
