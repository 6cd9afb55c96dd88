"""Fast and hybrid tool servo turning (Kong et al. 2020): slow slide servo (S3) + fast tool
servo (FTS).

Both servos cut along the same inward spiral as STS.  The compensated Z program of the
whole design is split into the slow slide's share and the FTS stroke
(:func:`~render_inspect.machining.split_commands`: ``hts`` puts the design's base on the
slow slide, ``fts`` its rotationally symmetric part); the machine follows each share with
its own axis (``[machine.z]``, ``[machine.fts]``: the package's one servo model,
:mod:`render_inspect.machining._axes`), and the machined surface is the envelope of the
tool nose along the followed path.

The retired ``[artifacts.servo]`` keys (a plain second-order servo on the ideal machine)
are accepted with a warning and become the same keys of ``[machine.fts]`` and
``[machine.z]``: a servo with no feed-forward is that second-order low-pass.
"""

from __future__ import annotations

from collections.abc import Sequence
import math
import time
from typing import Literal, cast

import numpy as np

from ..core.deprecation import warn_deprecated
from ..core.errors import SceneError
from ..core.toolpath import LinearProgram, ToolPath
from ..design import Surface
from ..core.units import MIN_TO_S, MM_TO_UM, S_TO_MS
from ..machining import FollowedPath, Machine, loop_lag, loop_response, split_commands
from ..toolpath import Tool
from ._contract import Cut, Envelope, Plan, Traits, Variant, VariantPair
from ._machine import ProcessScene, machine_of
from ._mechanics import TurningInputs, follow, turn
from ._spindle import MirroredSurface, spindle_meta, turns_m04
from ._registry import register_migration, register_process, register_retired_key
from ._program import program_path
from ._turning import imported_facts
from ._turning import (
    TiledTurningProcess,
    TurningProcessConfig,
    compensation_variants,
    toolpath_facts,
    turning_traits,
)

#: samples per second the cut runs at on 2 cores (the progress bar's estimate)
CUT_RATE = 2e6

__all__ = ["ServoProcessConfig", "ServoProcess", "RETIRED_SERVO_KEYS", "servo_lags"]


class ServoProcessConfig(TurningProcessConfig):
    """``[process]`` of fast (``fts``) or hybrid slow + fast (``hts``) tool servo turning.
    ``hts`` needs ``design.type = "compound"`` (base on the slow slide, feature on the
    FTS)."""
    kind: Literal["fts", "hts"]

    def check_with(self, scene: ProcessScene) -> None:
        super().check_with(scene)
        if self.kind == "hts" and scene.design.type != "compound":
            raise ValueError(
                "process.kind = 'hts' needs design.type = 'compound' ([design.base] on the slow slide, "
                f"[design.feature] on the fast tool servo), received design.type = "
                f"{scene.design.type!r}; use process.kind = 'fts' for a single surface")


#: retired ``artifacts.servo.<key>`` -> its successor
RETIRED_SERVO_KEYS = {"delay_s": "machine.fts.delay_s", "bandwidth_hz": "machine.fts.bandwidth_hz",
                      "damping": "machine.fts.damping",
                      "slow_bandwidth_hz": "machine.z.bandwidth_hz",
                      "slow_damping": "machine.z.damping"}


for _old, _new in RETIRED_SERVO_KEYS.items():
    register_retired_key(f"artifacts.servo.{_old}", _new,
                         "process.kind 'fts' / 'hts' on machine.preset 'ideal'")


@register_migration
def _retired_servo_keys(data: dict) -> dict:
    """``[artifacts.servo]`` -> ``[machine.fts]`` / ``[machine.z]`` (with a warning per
    key); it applied to the ideal machine of an ``fts`` / ``hts`` scene only, and is
    ignored (with a warning) for the other kinds, as it always was."""
    art = data.get("artifacts") if isinstance(data, dict) else None
    if not isinstance(art, dict) or "servo" not in art:
        return data
    servo = art["servo"]
    if not isinstance(servo, dict):
        raise ValueError(f"artifacts.servo must be a table of {sorted(RETIRED_SERVO_KEYS)} (retired: "
                         f"use [machine.fts] and [machine.z]), received {servo!r}")
    unknown = sorted(set(servo) - set(RETIRED_SERVO_KEYS))
    if unknown:
        raise ValueError(f"artifacts.servo.{unknown[0]}: unknown key (the retired [artifacts.servo] "
                         f"had {', '.join(RETIRED_SERVO_KEYS)}; use [machine.fts] and [machine.z])")
    data = dict(data)
    data["artifacts"] = {k: v for k, v in art.items() if k != "servo"}
    process = cast(dict, data.get("process")) if isinstance(data.get("process"), dict) else {}
    if process.get("kind") not in ("fts", "hts"):
        for key in servo:
            warn_deprecated(f"artifacts.servo.{key}", RETIRED_SERVO_KEYS[key],
                            "it applies to process.kind 'fts' and 'hts' only and is ignored here")
        return data
    machine = dict(data.get("machine") or {}) if isinstance(data.get("machine", {}), dict) else None
    if machine is None:
        return data  # [machine] is not a table: the schema says so
    preset = machine.get("preset", "ideal")
    active = (servo.get("delay_s", 0) != 0 or servo.get("bandwidth_hz") is not None
              or servo.get("slow_bandwidth_hz") is not None)
    if active and preset != "ideal":
        raise ValueError(
            f"artifacts.servo applies to machine.preset = 'ideal' only; with machine.preset = "
            f"{preset!r} set the fast tool servo in [machine.fts] (bandwidth_hz, damping, "
            f"delay_s) and the slow slide in [machine.z]")
    for key, value in servo.items():
        new = RETIRED_SERVO_KEYS[key]
        warn_deprecated(f"artifacts.servo.{key}", new,
                        "a machine axis without feed-forward is the same second-order servo")
        if value is None or preset != "ideal":
            continue
        _, axis, name = new.split(".")
        table = machine.get(axis)
        table = dict(table) if isinstance(table, dict) else {}
        if name in table and table[name] != value:
            raise ValueError(f"artifacts.servo.{key} = {value!r} and {new} = {table[name]!r} "
                             f"disagree: set {new} only")
        table[name] = value
        machine[axis] = table
    data["machine"] = machine
    return data


def _error_stats(err) -> dict:
    err = np.asarray(err)
    err = err[np.isfinite(err)]  # (a windowed plan's errors: the window's sectors only)
    if not err.size:
        return {"rms_um": 0.0, "max_um": 0.0}
    return {"rms_um": float(np.sqrt(np.mean(err * err)) * MM_TO_UM),
            "max_um": float(np.max(np.abs(err)) * MM_TO_UM)}


def _stroke_frequency(z_fts, t) -> float | None:
    """The FTS stroke's dominant frequency (Hz): the peak of its spectrum over the program's
    uniform-time resampling (None when the stroke is flat)."""
    z = np.asarray(z_fts, dtype=np.float64)
    t = np.asarray(t, dtype=np.float64)
    if z.size < 16 or np.ptp(z) == 0 or t[-1] <= t[0]:
        return None
    n = min(z.size, 1_000_000)
    tu = np.linspace(t[0], t[-1], n)
    zu = np.interp(tu, t, z)
    spec = np.abs(np.fft.rfft((zu - zu.mean()) * np.hanning(n)))
    k = int(np.argmax(spec[1:])) + 1
    return float(k / (tu[-1] - tu[0]))


def servo_lags(machine: Machine, *, omega: float, r_max: float, z_fts: np.ndarray | None = None,
               t: np.ndarray | None = None) -> dict:
    """The lags of a tool-servo machine (``metrics["servo"]``): ``effective_lag_s``, the FTS
    stroke's lag behind the spindle angle it belongs to at low frequency (its loop's group
    delay 2 zeta (1 - kv) / wn, its output delay and ``fts_sync_delay_s``; with full velocity
    feed-forward the loop adds none), ``slow_lag_s`` (the slow slide's, likewise),
    ``relative_lag_s`` (FTS minus slide: what turns the features against the base), the
    angles omega tau and the largest circumferential shift r omega tau they give, and at
    the stroke's dominant frequency the FTS loop's amplitude ratio and lag
    (``stroke_frequency_hz``, ``fts_amplitude_ratio``, ``fts_lag_at_stroke_s``): with full
    velocity feed-forward what is left is an amplitude error, not a lag."""
    tau_f = loop_lag(machine.fts) + float(machine.fts_sync_delay_s)
    tau_s = loop_lag(machine.z)
    out = {"effective_lag_s": tau_f, "effective_lag_angle_rad": omega * tau_f,
           "slow_lag_s": tau_s, "relative_lag_s": tau_f - tau_s,
           "relative_lag_angle_rad": omega * (tau_f - tau_s),
           "max_circumferential_shift_um": r_max * omega * abs(tau_f) * MM_TO_UM,
           "max_relative_shift_um": r_max * omega * abs(tau_f - tau_s) * MM_TO_UM}
    f = _stroke_frequency(z_fts, t) if z_fts is not None and t is not None else None
    if f:
        amp, lag = loop_response(machine.fts, f)
        out.update(stroke_frequency_hz=f, fts_amplitude_ratio=float(amp),
                   fts_lag_at_stroke_s=float(lag) + float(machine.fts_sync_delay_s))
    return out


def _servo_facts(cfg, plan: Plan, fp) -> tuple[dict, dict]:
    """(``metrics["servo"]``, the height map's ``servo`` provenance) of the followed path
    ``fp`` of the plan: the servos' settings, their lags (:func:`servo_lags`) and strokes,
    their following errors."""
    kind = cfg.process.kind
    path = cast(ToolPath, plan.program)  # (a turning program)
    z_slow, z_fts = plan.data["z_slow"], plan.data["z_fts"]
    omega = 2 * math.pi * cfg.process.spindle_rpm / MIN_TO_S
    r_max = float(np.max(path.rho)) if path.points else 0.0
    machine = machine_of(cfg.machine)
    if fp.ideal:
        fts_err, slow_err = np.zeros_like(z_fts), np.zeros_like(z_slow)
    else:
        fts_err = -np.interp(path.t, fp.t, fp.errors["fts"])
        slow_err = -np.interp(path.t, fp.t, fp.errors["z"])
    settings = {"delay_s": machine.fts.delay_s, "bandwidth_hz": machine.fts.bandwidth_hz,
                "damping": machine.fts.damping, "velocity_ff": machine.fts.velocity_ff,
                "acceleration_ff": machine.fts.acceleration_ff,
                "slow_bandwidth_hz": machine.z.bandwidth_hz,
                "slow_damping": machine.z.damping, "slow_velocity_ff": machine.z.velocity_ff,
                "fts_sync": machine.fts_sync, "fts_sync_delay_s": machine.fts_sync_delay_s}
    servo_m = {"kind": kind, **settings, "omega_rad_s": omega,
               "lag_angle_rad": omega * settings["delay_s"],
               **servo_lags(machine, omega=omega, r_max=r_max, z_fts=z_fts, t=path.t),
               "fts_stroke_um": float(np.ptp(z_fts) * MM_TO_UM) if z_fts.size else 0.0,
               "slow_stroke_um": float(np.ptp(z_slow) * MM_TO_UM) if z_slow.size else 0.0,
               "fts_following_error": _error_stats(fts_err),
               "slow_following_error": _error_stats(slow_err)}
    meta = {"servo": {k: servo_m[k] for k in ("delay_s", "bandwidth_hz", "damping",
                                               "slow_bandwidth_hz", "slow_damping")}}
    return servo_m, meta


class ServoProcess(TiledTurningProcess):
    """Tool-servo turning: the spiral's Z program split between the slow slide and the FTS,
    each followed by its axis of the machine; tiled when large."""

    config = ServoProcessConfig

    def plan(self, cfg: TurningInputs, surface: Surface, *,
             region: Sequence[float] | None = None, sectors: bool = False) -> Plan:
        t0 = time.perf_counter()
        # the fts split takes the mean over whole revolutions: it needs them all
        sectors = sectors and cfg.process.kind == "hts"
        plan = self.program_plan(cfg, surface, self.program(cfg, surface, region=region,
                                                            sectors=sectors))
        plan.timing["toolpath"] = time.perf_counter() - t0
        return plan

    def program_plan(self, cfg: TurningInputs, surface: Surface,
                     path: ToolPath | LinearProgram) -> Plan:
        """The plan of a program (planned, or read back from its file): its Z commands
        split between the slow slide and the fast tool servo."""
        path = cast(ToolPath, path)  # (a turning program)
        kind = cfg.process.kind
        base = getattr(surface, "base", None)
        if base is not None and turns_m04(path):  # the base as the path turns over it
            base = MirroredSurface(base)
        if kind == "hts" and base is None:
            raise SceneError("process.kind = 'hts' needs design.type = 'compound'")
        t0 = time.perf_counter()
        tool = Tool.from_config(cfg.tool)
        z_slow, z_fts = split_commands(path, kind, base=base if kind == "hts" else None,
                                       nose_radius=tool.nose_radius,
                                       compensation=cfg.process.compensation,
                                       half_width=tool.half_width)
        data = {"z_slow": z_slow, "z_fts": z_fts}
        facts = {"toolpath": toolpath_facts(path, cfg.process)}
        if program_path(cfg):  # a program read from a file: its checks and findings
            facts["program"] = imported_facts(cfg, surface, path)
        return Plan(path, facts, {"toolpath": time.perf_counter() - t0}, data,
                    plots=self.program_plots(cfg, path, data))

    def cut(self, cfg: TurningInputs, surface: Surface, plan: Plan) -> Cut:
        kind = cfg.process.kind
        t = turn(cfg, surface, plan.program, z_fts=plan.data["z_fts"])
        servo_m, servo_meta = _servo_facts(cfg, plan, t["followed_path"])
        facts = {"servo": servo_m, **t["facts"]}
        meta = {"process": kind, "compensation": cfg.process.compensation,
                "seed": cfg.simulation.seed, "machine": cfg.machine.preset,
                "material": cfg.material.preset, **servo_meta, **spindle_meta(plan.program)}
        return Cut(t["machined"], t["design"], facts, t["timing"], meta, followed=t["followed"],
                   plots=t["plots"])

    def follow_program(self, cfg: TurningInputs,
                       plan: Plan) -> tuple[ToolPath, FollowedPath, dict]:
        return follow(cfg, plan.program, z_fts=plan.data["z_fts"])

    def envelope(self, cfg: TurningInputs, surface: Surface, plan: Plan) -> Envelope:
        cut_path, fp, facts = self.follow_program(cfg, plan)
        servo_m, servo_meta = _servo_facts(cfg, plan, fp)
        return self.envelope_of(cfg, cut_path, fp, {"servo": servo_m, **facts}, meta=servo_meta)

    def variants(self, cfg: TurningInputs) -> VariantPair:
        """The servos as the machine has them (``[machine.z]``, ``[machine.fts]``: the lag
        that rotates every feature by ``omega tau`` and shifts it by ``r omega tau``,
        Kong et al. 2020's spiral dislocations) against ideal servos that follow their
        commands exactly.  A machine without servo dynamics gets the turning pair
        (compensation on/off) instead."""
        machine = machine_of(cfg.machine)
        if machine.z.ideal and machine.fts.ideal and machine.fts_sync_delay_s == 0:
            return compensation_variants(cfg)
        # the slow slide (Z) and FTS: ideal = no loop (inf bandwidth), no latency, no
        # disturbance; the spindle, X and the error motions stay as set
        parts = []
        for name, ax in (("FTS", machine.fts), ("slide", machine.z)):
            if ax.bandwidth_hz is not None:
                parts.append(f"{name} {ax.bandwidth_hz:.4g} Hz, velocity feed-forward "
                             f"{ax.velocity_ff:.3g}")
            if ax.delay_s > 0:
                parts.append(f"{name} delay {ax.delay_s * S_TO_MS:.3g} ms")
        if machine.fts_sync_delay_s != 0:
            parts.append(f"FTS {machine.fts_sync_delay_s * S_TO_MS:+.3g} ms against the spindle")
        ideal = {"machine.fts_sync_delay_s": 0.0}
        for key in ("fts", "z"):
            ideal.update({f"machine.{key}.bandwidth_hz": math.inf, f"machine.{key}.delay_s": 0.0,
                          f"machine.{key}.noise_nm": 0.0})
        preset = cfg.machine.preset
        return VariantPair(
            Variant("servo_lag", f"servos of the {preset} machine (" + "; ".join(parts) + ")", {}),
            Variant("ideal_servo", "ideal slow slide and FTS (no lag, no disturbance, FTS in "
                                   "time with the spindle)", ideal),
            key="machine.fts, machine.z",
            about=("Servo lag on against off: the slow slide and the fast tool servo as the "
                   f"{preset} machine has them, against servos that follow their commands "
                   f"exactly (spindle, X and error motions unchanged); at "
                   f"{cfg.process.spindle_rpm:g} rpm a lag tau turns every feature by "
                   f"omega tau about the spindle axis and shifts it by r omega tau along the "
                   f"circumference (the spiral dislocations of Kong et al. 2020)."))

    def program_region(self, cfg: TurningInputs) -> tuple[float, ...]:
        return tuple(cfg.simulation.region)

    def traits(self, cfg: TurningInputs) -> Traits:
        return turning_traits(cfg, cut_rate=CUT_RATE)


register_process(ServoProcess())
