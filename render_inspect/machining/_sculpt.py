"""Vibration-assisted diamond sculpturing (HFUVAS) of a quadrilateral lenslet array, after
Zhang et al. (2022) [1]_.

Linear X-Y-Z cutting, not turning.  The tool moves along target lines x = x_k (the
lenslets' symmetry lines, one per column of cells) in the cutting direction y.  Its round
edge (radius R, in the x-z plane, rake 0) is swept along the line; the machined surface is
the lower envelope of every position the edge passes through.

Kinematics (Zhang et al. 2022, eq. 2-9)::

    u(t) = y_start + v_c t                      nominal position along the line
    y(t) = u(t) + A cos(2 pi f t)               ultrasonic vibration along the cut
    z(t) = z_cmd(u(t))                          Z follows the *nominal* position

``z_cmd`` is the target line sampled every ``step`` (the paper's 2.5 um) with a sample at
every sharp edge (segment cutting), linearly interpolated between samples.  The edge at
time t removes material below ``z(t) + R - sqrt(R^2 - (x - x_k)^2)`` in the plane y = y(t).

Two theoretical form errors come out of this geometry, without being put in:

* vibration overcut: a point y is passed by the edge carrying the Z commands of every
  nominal position in [y - A, y + A]; the cut keeps the lowest, so the overcut is about
  A |dz/dy| (largest at the sharp edges between lenslets; < 0.1 um for the paper's data);
* tool-edge overcut: the section of a lenslet across the cut has radius
  sqrt(r^2 - (y - y_c)^2) <= r = R, so a round edge of radius R cuts below it away from
  the line (largest at the four-lenslet cusp, 0.025 um for the paper's data).

References
----------
.. [1] C. Zhang, C.-F. Cheung, X. Liang, B. Bulla, "A theoretical and experimental
       investigation of high-frequency ultrasonic vibration-assisted sculpturing of
       optical microstructures," Applied Sciences 12(21), 10937 (2022).
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Any

import numpy as np
from ..core.lazy import njit  # numba, imported on first use

from ..core.errors import InputError, check_range

__all__ = ["sculpt_line_profile", "sculpt_surface", "target_line", "vibration_phases"]


@njit(cache=True)
def _sweep_segment(ya, za, yb, zb, y0, dy, out):  # pragma: no cover - numba
    """Lower the rows between ya and yb to the straight edge-tip segment (ya, za)-(yb, zb)."""
    ny = out.shape[0]
    if yb < ya:
        ya, yb, za, zb = yb, ya, zb, za
    ja = int(math.ceil((ya - y0) / dy - 1e-9))
    jb = int(math.floor((yb - y0) / dy + 1e-9))
    if ja < 0:
        ja = 0
    if jb > ny - 1:
        jb = ny - 1
    for j in range(ja, jb + 1):
        f = 0.0
        if yb > ya:
            f = (y0 + j * dy - ya) / (yb - ya)
            if f < 0.0:
                f = 0.0
            elif f > 1.0:
                f = 1.0
        zj = za + f * (zb - za)
        if zj < out[j]:
            out[j] = zj


@njit(cache=True)
def _sweep_line(ys, zs, t_start, vc, amp, freq, phases, y0, dy, out):  # pragma: no cover - numba
    """Lower envelope along one target line of the swept edge's lowest point.

    The tool tip is followed through a merged sequence of events: the command's
    breakpoints ``ys`` (at their own times) and, with vibration, the sample ``phases``
    (rad, sorted in [0, 2 pi)) of every vibration period counted from t = 0 (so a part of a
    line gives the same samples as the whole line).  Between consecutive events the tip
    moves on a straight segment; ``out[j]`` (row j at y0 + j dy) keeps the lowest z
    passing it.  The tool is at ``ys[0]`` at time ``t_start``."""
    m = ys.shape[0]
    y_start = ys[0]
    two_pi = 2.0 * math.pi
    vib = amp > 0.0 and freq > 0.0
    npha = phases.shape[0]
    # first vibration sample after t_start
    p = 0
    jph = 0
    t_vib = 1e300
    if vib:
        p = int(math.floor(t_start * freq))
        jph = 0
        t_vib = (p + phases[0] / two_pi) / freq
        while t_vib <= t_start:
            jph += 1
            if jph == npha:
                jph = 0
                p += 1
            t_vib = (p + phases[jph] / two_pi) / freq
    kb = 1                                   # next breakpoint
    y_prev = y_start + amp * math.cos(two_pi * freq * t_start)
    z_prev = zs[0]
    while True:
        t_bp = t_start + (ys[kb] - y_start) / vc
        if t_bp <= t_vib:
            t = t_bp
            z = zs[kb]
            is_bp = True
        else:
            t = t_vib
            u = y_start + vc * (t - t_start)
            w = (u - ys[kb - 1]) / (ys[kb] - ys[kb - 1])
            z = zs[kb - 1] + w * (zs[kb] - zs[kb - 1])
            is_bp = False
        y = (ys[kb] if is_bp else u) + amp * math.cos(two_pi * freq * t)
        _sweep_segment(y_prev, z_prev, y, z, y0, dy, out)
        y_prev = y
        z_prev = z
        if is_bp:
            if kb == m - 1:
                break
            kb += 1
        else:
            jph += 1
            if jph == npha:
                jph = 0
                p += 1
            t_vib = (p + phases[jph] / two_pi) / freq


def target_line(surface: Any, x_line: float, edges: np.ndarray, *,
                step: float) -> tuple[np.ndarray, np.ndarray]:
    """Target line (Zhang et al. 2022, eq. 2): the design along x = ``x_line``, sampled every
    ``step`` mm inside each segment between consecutive ``edges`` (mm, increasing), with a
    sample on every edge (segment cutting keeps the sharp edges).

    Returns
    -------
    ys, zs : (m,) float64, mm
    """
    edges = np.asarray(edges, dtype=np.float64)
    if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
        raise InputError(f"edges must be >= 2 increasing positions (mm), received {edges!r}")
    check_range("step", step, 0.0, None, lo_open=True)
    parts = []
    for a, b in zip(edges[:-1], edges[1:]):
        n = max(1, int(math.ceil((b - a) / step - 1e-9)))
        parts.append(np.linspace(a, b, n + 1)[:-1])
    parts.append(edges[-1:])
    ys = np.concatenate(parts)
    zs = np.asarray(surface.height(np.full_like(ys, x_line), ys), dtype=np.float64)
    return ys, zs


def vibration_phases(cutting_speed: float, amplitude: float, frequency_hz: float,
                     samples_per_period: int = 16) -> np.ndarray:
    """Phases (rad, sorted in [0, 2 pi)) at which each vibration period is sampled:
    ``samples_per_period`` uniform phases plus the front- and back-cut limits, where the
    tool stops along the cut, y'(t) = v_c - 2 pi f A sin(2 pi f t) = 0 (Zhang et al. 2022,
    eq. 6), so the envelope's extreme points are exact.  Without reversal
    (v_c >= 2 pi f A) only the uniform phases."""
    ph = list(2 * math.pi * np.arange(samples_per_period) / samples_per_period)
    eps = cutting_speed / (2 * math.pi * frequency_hz * amplitude)
    if eps < 1:
        a = math.asin(eps)
        ph += [a, math.pi - a]
    return np.unique(np.mod(np.array(ph), 2 * math.pi))


def sculpt_line_profile(ys: np.ndarray, zs: np.ndarray, y_grid: np.ndarray, *,
                        cutting_speed: float, amplitude: float = 0.0,
                        frequency_hz: float = 0.0, samples_per_period: int = 16,
                        t_start: float = 0.0) -> np.ndarray:
    """Lowest tool-tip height reached above each y of ``y_grid`` along one target line.

    Parameters
    ----------
    ys, zs : (m,) arrays, mm
        Commanded target line (increasing ``ys``); Z follows it at the nominal position.
    y_grid : (ny,) array, mm
        Uniformly spaced row positions.
    cutting_speed : float
        v_c, mm/s (> 0).
    amplitude : float
        A, mm (>= 0): vibration along the cutting direction, y = v_c t + A cos(2 pi f t).
    frequency_hz : float
        f, Hz (>= 0); 0 or ``amplitude`` 0 means no vibration.
    samples_per_period : int
        Uniform time samples per vibration period (>= 4), plus the front- and back-cut
        limits (:func:`vibration_phases`).  Without vibration the tip moves straight
        between the command's breakpoints, which are the only samples needed.
    t_start : float
        Time (s) at which the tool is at ``ys[0]``: sets the vibration's phase, so a line
        cut in part gives the same result as the whole line.

    Returns
    -------
    (ny,) float64, mm; NaN where the tool never passes.
    """
    ys = np.ascontiguousarray(ys, dtype=np.float64)
    zs = np.ascontiguousarray(zs, dtype=np.float64)
    y_grid = np.asarray(y_grid, dtype=np.float64)
    if ys.size < 2 or ys.shape != zs.shape or np.any(np.diff(ys) <= 0):
        raise InputError("ys must hold >= 2 increasing positions and zs the same number of heights")
    check_range("cutting_speed", cutting_speed, 0.0, None, lo_open=True)
    check_range("amplitude", amplitude, 0.0, None)
    check_range("frequency_hz", frequency_hz, 0.0, None)
    check_range("samples_per_period", samples_per_period, 4, 10_000)
    dy = float(y_grid[1] - y_grid[0]) if y_grid.size > 1 else 1.0
    vib = amplitude > 0 and frequency_hz > 0
    phases = vibration_phases(cutting_speed, amplitude, frequency_hz, samples_per_period) if vib \
        else np.zeros(1)
    out = np.full(y_grid.size, np.inf)
    _sweep_line(ys, zs, float(t_start), float(cutting_speed), float(amplitude if vib else 0.0),
                float(frequency_hz if vib else 0.0), phases, float(y_grid[0]), dy, out)
    out[~np.isfinite(out)] = np.nan
    return out


def sculpt_surface(profiles: Sequence[np.ndarray] | np.ndarray, x_lines: np.ndarray,
                   x_grid: np.ndarray, *, tool_radius: float,
                   half_width: float | None = None) -> np.ndarray:
    """Machined heights from the per-line profiles: the envelope over lines of the round
    edge, min_k [profile_k(y) + R - sqrt(R^2 - (x - x_k)^2)], |x - x_k| <= half_width.

    Parameters
    ----------
    profiles : (n_lines, ny) array, mm (from :func:`sculpt_line_profile`)
    x_lines : (n_lines,) array, mm
    x_grid : (nx,) array, mm
    tool_radius : float, mm
    half_width : float, optional
        Half-width of the edge arc in x (mm), R sin(included / 2); default R.

    Returns
    -------
    (ny, nx) float64, mm; NaN where no edge reaches.
    """
    R = float(check_range("tool_radius", tool_radius, 0.0, None, lo_open=True))
    hw = R if half_width is None else min(float(half_width), R)
    x_grid = np.asarray(x_grid, dtype=np.float64)
    profiles = np.asarray(profiles, dtype=np.float64)
    out = np.full((profiles.shape[1], x_grid.size), np.inf)
    for prof, xk in zip(profiles, np.asarray(x_lines, dtype=np.float64)):
        dx = x_grid - xk
        reach = np.abs(dx) <= hw + 1e-12
        if not reach.any():
            continue
        arc = R - np.sqrt(R * R - np.minimum(dx[reach] ** 2, R * R))
        cand = np.where(np.isnan(prof), np.inf, prof)[:, None] + arc[None, :]
        sub = out[:, reach]
        np.minimum(sub, cand, out=sub)
        out[:, reach] = sub
    out[~np.isfinite(out)] = np.nan
    return out
