"""A turning program followed by a machine: every axis through its servo
(:mod:`render_inspect.machining._axes`), the fast tool servo timed by the spindle angle or
the clock, the X slide's reaction force and the error motions, and the following error
that is left."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.units import MM_TO_NM, NM_TO_MM, RAD_TO_URAD
from ._axes import follow_axis, servo_ticks, settle_time
from ._machine import Machine
from ._errmotion import apply_error_motions
from ._interpolate import check_program, linear_command, pvt_checked

__all__ = ["FollowedPath", "follow_turning", "following_error_stats", "window_margins",
           "mask_outside_sector"]


@dataclass
class FollowedPath:
    """The path a turning machine really follows.

    Attributes
    ----------
    t, theta, rho, z : (m,) arrays
        Tick times (s) and the tool-tip position relative to the part (rad cumulative,
        mm, mm) after the servos and the error motions: what the envelope cuts.
    commanded : dict
        The interpolated commands at the ticks: ``theta, rho, z, z_slow, z_fts``.
    errors : dict
        Following errors (command - followed) at the ticks: ``c`` (rad), ``x``, ``z``
        (Z slide), ``fts`` (mm).
    ideal : bool
        True when the program was returned unchanged (ideal machine).
    machine : Machine
    sector_ticks : int or None
        For a program planned in full over a sector of each revolution (``sector`` of
        :func:`follow_turning`): the ticks in the sector, over which the Z slide and the
        fast tool servo were followed; None otherwise.
    """

    t: np.ndarray
    theta: np.ndarray
    rho: np.ndarray
    z: np.ndarray
    commanded: dict
    errors: dict
    ideal: bool
    machine: Machine
    sector_ticks: int | None = None

    def following_error(self) -> dict:
        """:func:`following_error_stats` of this path."""
        return following_error_stats(self.errors)


def following_error_stats(errors: dict) -> dict:
    """``{x_rms_nm, x_max_nm, z_rms_nm, z_max_nm, c_rms_urad, c_max_urad, fts_rms_nm,
    fts_max_nm}`` of following-error arrays (mm; rad for ``c``)."""
    out = {}
    for k, unit, scale in (("x", "nm", MM_TO_NM), ("z", "nm", MM_TO_NM), ("c", "urad", RAD_TO_URAD),
                           ("fts", "nm", MM_TO_NM)):
        e = np.asarray(errors.get(k, np.zeros(1)), dtype=np.float64).ravel()
        finite = np.isfinite(e)
        if not finite.all():  # (no copy when every value counts)
            e = e[finite]
        out[f"{k}_rms_{unit}"] = float(np.sqrt(np.mean(e * e)) * scale) if e.size else 0.0
        out[f"{k}_max_{unit}"] = float(np.max(np.abs(e)) * scale) if e.size else 0.0
    return out


def window_margins(machine: Machine) -> tuple[float, float]:
    """(lead_s, lag_s): how long before and after the part of a program that cuts a window
    ``machine`` must be given the program's every point for the followed path there to be
    the same, to rounding, as with the whole program.

    A windowed plan keeps every point only in the angular sector that reaches the window
    and a few points per revolution between the sectors (the tool-tip Z differs there;
    C and X, straight in time along the spiral, are the same lines).  What the Z slide
    and the fast tool servo are commanded between the sectors reaches the window through
    their loops' state only: a transient that :func:`settle_time` lets decay by
    :data:`~render_inspect.machining._axes.SETTLE_DECAY`.  The servo ticks, the seeded
    disturbances and error motions (drawn per tick over the whole program) and the C and
    X axes (and with them the reaction-force coupling) are those of the whole program.
    A stroke played late (``fts_sync_delay_s`` > 0) needs that much more before, an
    early one after; and two servo ticks after the sector for the interpolation."""
    lead = max((settle_time(ax) for ax in (machine.z, machine.fts)), default=0.0)
    tau = float(machine.fts_sync_delay_s)
    return lead + max(tau, 0.0), max(-tau, 0.0) + 2.0 / float(machine.servo_rate_hz)


def mask_outside_sector(theta: np.ndarray, errors: dict,
                        sector_rad: Sequence[float]) -> dict:
    """``errors`` with NaN at the ticks whose commanded angle ``theta`` (rad, cumulative)
    lies outside the angular sector ``sector_rad`` (a0, a1): the following errors of a
    windowed plan are those of the passes over the window."""
    a0, a1 = float(sector_rad[0]), float(sector_rad[1])
    d = np.asarray(theta, dtype=np.float64) - a0
    out = np.mod(d, 2 * np.pi, out=d) > (a1 - a0)
    return {k: np.where(out, np.nan, np.asarray(v, dtype=np.float64)) for k, v in errors.items()}


#: servo ticks up to which the three axes are followed side by side in threads (about
#: 110 B a tick more at the peak than one after another; a 1 M-sample window: 0.1-0.25 M
#: ticks)
SIDE_BY_SIDE_TICKS = 1 << 18


def _side_by_side(*axes: tuple) -> list:
    """:func:`follow_axis` of each ``(t, q, axis, seed, kwargs)`` in a thread of its own;
    the responses in order (an axis's error raised here).  The threads are daemons: an
    interruption of the waiting thread ends the command without waiting for them."""
    out: list[Any] = [None] * len(axes)
    errors: list[BaseException] = []

    def run(i: int, t: np.ndarray, q: np.ndarray, axis: Any, seed: int, kw: dict) -> None:
        try:
            out[i] = follow_axis(t, q, axis, seed=seed, **kw)
        except BaseException as err:  # (raised in the waiting thread)
            errors.append(err)

    threads = [threading.Thread(target=run, args=(i, *a), daemon=True,
                                name="render_inspect-axis") for i, a in enumerate(axes)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    if errors:
        raise errors[0]
    return out


def follow_turning(t: np.ndarray, theta: np.ndarray, rho: np.ndarray, z: np.ndarray,
                   machine: Machine, *, z_fts: np.ndarray | None = None, seed: int = 0,
                   fts_theta: np.ndarray | None = None,
                   sector: Sequence[float] | None = None) -> FollowedPath:
    """The path a turning program is cut along on ``machine``.

    Parameters
    ----------
    t, theta, rho, z : (n,) arrays
        The program: times (s, increasing), spindle angle C (rad, cumulative), X (mm) and
        the tool-tip Z (mm, slow slide + FTS).
    machine : Machine
    z_fts : (n,) array, optional
        The fast tool servo's share of ``z`` (mm); the Z slide gets ``z - z_fts``.  None:
        everything on the Z slide.
    seed : int
        Seed of the disturbances and the asynchronous error motions (each axis and error
        source draws from its own stream derived from it).
    fts_theta : (n,) array, optional
        The spindle angle each FTS stroke belongs to (default ``theta``), for
        position synchronisation.  ``machine.fts_sync_delay_s`` shifts the stroke in time
        against the spindle (late > 0).
    sector : (a0, span), rad, optional
        A program planned in full only over this sector of each revolution (from the
        angle a0 over ``span``, the settle lead included; :func:`window_margins`): the Z
        slide and the FTS are followed over the ticks in it only (elsewhere they are
        their program, with no error), and the error motions are added there only (drawn
        and scaled over every tick); the spindle, X and the coupling over every tick.

    Returns
    -------
    FollowedPath
        With the program unchanged when ``machine.ideal``.
    """
    t, theta = check_program(t, theta)
    rho = np.asarray(rho, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    if rho.shape != t.shape or z.shape != t.shape:
        raise InputError(f"theta, rho, z and t must have one length, received {theta.shape}, "
                         f"{rho.shape}, {z.shape}, {t.shape}")
    zf_prog = np.zeros(z.shape) if z_fts is None else np.asarray(z_fts, dtype=np.float64)
    if zf_prog.shape != z.shape:
        raise InputError(f"z_fts must have the path's length {z.size}, received {zf_prog.shape}")
    zs_prog = z - zf_prog
    if machine.ideal:
        zero = np.zeros_like(z)
        return FollowedPath(t.copy(), theta.copy(), rho.copy(), z.copy(),
                            {"theta": theta, "rho": rho, "z": z, "z_slow": zs_prog, "z_fts": zf_prog},
                            {"c": zero, "x": zero, "z": zero, "fts": zero}, True, machine)
    ss = np.random.SeedSequence(int(seed))
    s_c, s_x, s_z, s_f, s_e = (int(s.generate_state(1)[0]) for s in ss.spawn(5))
    rate = machine.servo_rate_hz
    tk = servo_ticks(float(t[0]), float(t[-1]), rate)
    kw: dict[str, Any] = {"rate_hz": rate, "interpolation": machine.interpolation, "ticks": tk}
    mask = None
    kw_z = dict(kw)
    if sector is not None:
        # the program's angle at each tick (C is omega t along the spiral)
        th_k = np.interp(tk, t, theta)
        mask = np.mod(th_k - float(sector[0]), 2 * np.pi) <= float(sector[1])
        edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.view(np.int8), [0]])))
        kw_z["runs"] = edges.reshape(-1, 2)
    kws = [dict(kw), dict(kw), dict(kw_z)]
    if machine.interpolation == "pvt":
        # C, X and (over every tick) Z are programmed at the same times: their commands
        # in one pass (each tick's segment and Hermite basis found once)
        shared = [theta, rho] if sector is not None else [theta, rho, zs_prog]
        cq, cv, ca = pvt_checked(t, np.stack(shared), tk)
        for i in range(len(shared)):
            kws[i]["command"] = (cq[i], cv[i], ca[i])
        del cq, cv, ca
    # the three axes are independent (each its own program and its own noise stream):
    # followed side by side, in threads (their noise and servo loops leave the
    # interpreter free), where their temporaries side by side are small; one after
    # another on longer programs (a whole part), whose memory they would triple
    axes = ((t, theta, machine.c, s_c, kws[0]), (t, rho, machine.x, s_x, kws[1]),
            (t, zs_prog, machine.z, s_z, kws[2]))
    if tk.size <= SIDE_BY_SIDE_TICKS:
        rc, rx, rz = _side_by_side(*axes)
    else:
        rc, rx, rz = (follow_axis(a, q, ax, seed=sd, **k) for a, q, ax, sd, k in axes)
    del axes, kws
    kw = kw_z
    theta_f = np.maximum.accumulate(rc.followed)
    if z_fts is None:
        zf_cmd = np.zeros(tk.size)
        zf: np.ndarray | float = 0.0  # (the FTS's share: +0 at every tick, as a scalar)
    else:
        tau = float(machine.fts_sync_delay_s)
        if machine.fts_sync == "position":
            # the FTS evaluates its stroke table at the measured spindle angle
            th_ref = theta if fts_theta is None else np.asarray(fts_theta, dtype=np.float64)
            th_meas = theta_f
            # time at which the program meant that angle (tau earlier when the stroke comes
            # late), then the PVT stroke there
            t_equiv = np.interp(th_meas, th_ref, t) - tau
        else:
            t_equiv = tk - tau
        if machine.fts_sync == "position" or tau != 0:
            t_equiv = np.clip(t_equiv, t[0], t[-1])
            if mask is not None:
                t_equiv = t_equiv[mask]
            cmd = pvt_checked(t, zf_prog, t_equiv) if machine.interpolation == "pvt" else \
                linear_command(t, zf_prog, t_equiv)
            rf = follow_axis(t, zf_prog, machine.fts, seed=s_f, command=cmd, **kw)
            del cmd, t_equiv
        else:
            rf = follow_axis(t, zf_prog, machine.fts, seed=s_f, **kw)
        zf_cmd, zf = rf.command, rf.followed
        del rf  # (its velocity and acceleration are not kept)
    rho_f = rx.followed
    z_f = rz.followed + zf
    errors = {"c": rc.error, "x": rx.error, "z": rz.error,
              "fts": (zf_cmd - zf) if z_fts is not None else np.zeros(tk.size)}
    commanded = {"theta": rc.command, "rho": rx.command,
                 "z": rz.command + (zf_cmd if z_fts is not None else 0.0),
                 "z_slow": rz.command, "z_fts": zf_cmd}
    # (the axes' command velocities and accelerations are not kept: their memory is free
    # for the error motions)
    del rc, rx, rz, zf
    if not machine.coupling.none:
        dz, dy = machine.coupling.deflection(tk, rho_f)
        z_f += dz
        # theta_f + dy / max(|rho_f|, 1 nm), in dy's array
        r = np.abs(rho_f)
        np.maximum(r, NM_TO_MM, out=r)
        dy /= r
        dy += theta_f
        theta_f = np.maximum.accumulate(dy, out=dy)
    if machine.errors is not None and not machine.errors.none:
        theta_f, rho_f, z_f = apply_error_motions(tk, theta_f, rho_f, z_f, machine.errors, seed=s_e,
                                                  mask=mask)
    return FollowedPath(tk, theta_f, rho_f, z_f, commanded, errors, False, machine,
                        None if mask is None else int(np.count_nonzero(mask)))
