"""Error motions of a turning machine and tool-part vibration.

All are written as the displacement of the *tool relative to the part*, in machine axes
(X radial, Z axial, Y the cutting direction), added to the followed path:

* spindle **radial** error motion in the sensitive direction X (the tool's radius changes
  by e_x): synchronous part ``sum a_n cos(n C + p_n)`` (repeats every revolution: harmonics
  n of the spindle angle C) plus an asynchronous part (seeded band-limited noise of rms
  ``radial_async_rms`` that does not repeat);
* spindle **axial** error motion (face motion, Z): synchronous harmonics and asynchronous
  noise likewise; on a face it prints n radial *spokes* per harmonic n;
* spindle **tilt** error motion (rad): e_z = X * sum t_n cos(n C + p_n) (a wobble whose
  print grows with the radius);
* X-slide **straightness** in Z: e_z = s(X) - s(0), s a seeded smooth random profile of
  rms ``x_straightness_rms`` and correlation length ``x_straightness_length`` (mm of X
  travel); zero at the spindle axis, where the tool height is set;
* tool-part **vibration** at fixed frequencies: ``(frequency_hz, amplitude, direction,
  phase)`` with direction "x", "y" or "z"; along Y it moves the cut along the
  circumference (the spindle angle changes by e_y / X).

A once-per-revolution radial error a cos C moves the tool to X + a cos C; the program's
height for radius rho is then cut at rho + a cos(phi), so the machined surface is
F(r - a cos(phi)) (F the programmed radial profile): the analytic pattern tested.
Vibration at f Hz appears on the part at f * 60 / rpm cycles per revolution.
Asynchronous noise is white noise at the tick rate, low-passed by a second-order
Butterworth at ``async_bandwidth_hz`` and scaled to its rms, from the seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from ..core import trig
from ..core.errors import InputError, check_range
from ._iir import butter2_sos, sosfilt

__all__ = ["ErrorMotions", "apply_error_motions", "error_motion_offsets"]

TWO_PI = 2.0 * math.pi


def _harmonics(name, val) -> tuple:
    out = []
    for item in val or ():
        if isinstance(item, dict):
            item = (item.get("harmonic"), item.get("amplitude"), item.get("phase", 0.0))
        if len(item) not in (2, 3):
            raise InputError(f"{name} entries must be (harmonic, amplitude[, phase_rad]), received {item!r}")
        n, a = int(item[0]), float(item[1])
        p = float(item[2]) if len(item) == 3 else 0.0
        if n < 1 or n != item[0]:
            raise InputError(f"{name}: harmonic must be an integer >= 1, received {item[0]!r}")
        check_range(f"{name} amplitude", a, 0.0, 1.0)
        out.append((n, a, p))
    return tuple(out)


@dataclass(frozen=True)
class ErrorMotions:
    """Spindle and slide error motions and tool-part vibration (lengths in mm, angles in
    rad, frequencies in Hz).  See the module docstring for the model."""

    radial_sync: tuple = ()
    radial_async_rms: float = 0.0
    axial_sync: tuple = ()
    axial_async_rms: float = 0.0
    tilt_sync: tuple = ()
    async_bandwidth_hz: float = 200.0
    x_straightness_rms: float = 0.0
    x_straightness_length: float = 5.0
    vibration: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "radial_sync", _harmonics("radial_sync", self.radial_sync))
        object.__setattr__(self, "axial_sync", _harmonics("axial_sync", self.axial_sync))
        object.__setattr__(self, "tilt_sync", _harmonics("tilt_sync", self.tilt_sync))
        for k in ("radial_async_rms", "axial_async_rms", "x_straightness_rms"):
            check_range(k, getattr(self, k), 0.0, 1.0)
        check_range("async_bandwidth_hz", self.async_bandwidth_hz, 0.0, 1e6, lo_open=True)
        check_range("x_straightness_length", self.x_straightness_length, 0.0, 1e4, lo_open=True)
        vib = []
        for item in self.vibration or ():
            if isinstance(item, dict):
                item = (item.get("frequency_hz"), item.get("amplitude"), item.get("direction", "z"),
                        item.get("phase", 0.0))
            if len(item) not in (3, 4):
                raise InputError("vibration entries must be (frequency_hz, amplitude, direction[, "
                                 f"phase_rad]), received {item!r}")
            f, a, d = float(item[0]), float(item[1]), str(item[2])
            check_range("vibration frequency_hz", f, 0.0, 1e7, lo_open=True)
            check_range("vibration amplitude", a, 0.0, 1.0)
            if d not in ("x", "y", "z"):
                raise InputError(f"vibration direction must be 'x', 'y' or 'z', received {d!r}")
            vib.append((f, a, d, float(item[3]) if len(item) == 4 else 0.0))
        object.__setattr__(self, "vibration", tuple(vib))

    @property
    def none(self) -> bool:
        """True when no error motion is set."""
        return (not self.radial_sync and not self.axial_sync and not self.tilt_sync
                and self.radial_async_rms == 0 and self.axial_async_rms == 0
                and self.x_straightness_rms == 0 and not self.vibration)

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def with_overrides(self, overrides: dict) -> "ErrorMotions":
        names = {f.name for f in fields(self)}
        bad = sorted(set(overrides) - names)
        if bad:
            raise InputError(f"unknown machine.errors setting(s) {bad}; allowed: {sorted(names)}")
        return replace(self, **overrides)


def _band_noise(n: int, rate_hz: float, bandwidth_hz: float, rms: float, rng) -> np.ndarray:
    if rms == 0 or n == 0:
        return np.zeros(n)
    w = rng.normal(size=n)
    wc = min(bandwidth_hz / (0.5 * rate_hz), 0.99)
    sos = butter2_sos(wc)    # (scipy.signal.butter and sosfilt, to the last bit)
    y = sosfilt(sos, w, overwrite_x=True)
    # drop the filter's start-up by scaling on the settled part
    settle = min(n // 2, int(5 * rate_hz / bandwidth_hz) + 1)
    s = np.std(y[settle:]) if n - settle > 10 else np.std(y)
    if s > 0:
        y *= rms / s
    return y


def _straightness(x, rms: float, length: float, rng, modes: int = 64, *, at=None) -> np.ndarray:
    """Smooth random profile of the position x (mm), unit-variance Gaussian covariance of
    correlation length ``length``, times ``rms``: positional, so the same seed gives the
    same slide on any path.  ``at``: evaluate it there only (the table over ``x``'s
    range, as for all of ``x``)."""
    if rms == 0:
        return np.zeros_like(x if at is None else at)
    k = rng.normal(0.0, 1.0 / length, size=modes)
    ph = rng.uniform(0.0, TWO_PI, size=modes)
    x = np.asarray(x, dtype=np.float64)
    # the tool height is set at the spindle axis (X = 0): the deviation is zero there
    s0 = rms * math.sqrt(2.0 / modes) * float(np.cos(ph).sum())
    lo, hi = float(np.min(x)), float(np.max(x))
    # the profile is smooth on the scale length / max|k|: tabulate it and interpolate
    step = min(length, 1.0 / max(float(np.max(np.abs(k))), 1e-12)) / 200.0
    n = int((hi - lo) / step) + 2
    if n < x.size:
        xs = np.linspace(lo, hi, max(n, 2))
        prof = rms * math.sqrt(2.0 / modes) * np.cos(np.multiply.outer(xs, k) + ph).sum(axis=-1)
        out = np.interp(x if at is None else at, xs, prof)
        out -= s0
        return out
    if at is not None:  # (rows of the outer product are independent: the same numbers)
        x = np.asarray(at, dtype=np.float64)
    return rms * math.sqrt(2.0 / modes) * np.cos(np.multiply.outer(x, k) + ph).sum(axis=-1) - s0


def error_motion_offsets(t: np.ndarray, theta: np.ndarray, rho: np.ndarray, errors: ErrorMotions,
                         *, seed: int = 0, mask: np.ndarray | None = None) -> dict:
    """Tool-relative-to-part displacements (mm) at the ticks: ``x``, ``y``, ``z``.

    Parameters
    ----------
    t : (m,) s (uniform ticks);  theta : (m,) spindle angle C, rad;  rho : (m,) X, mm
    errors : ErrorMotions
    seed : int
    mask : (m,) bool array, optional
        The ticks the offsets are wanted at (the rest come back 0).  The asynchronous
        noise is drawn and scaled over every tick and the straightness tabulated over
        the whole range of ``rho``, so the offsets at these ticks are those of all ticks.

    Returns
    -------
    dict of (m,) float64 arrays
    """
    t = np.asarray(t, dtype=np.float64)
    theta = np.asarray(theta, dtype=np.float64)
    rho = np.asarray(rho, dtype=np.float64)
    n = t.size
    rate = 1.0 / float(t[1] - t[0]) if n > 1 else 1.0
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(int(seed)).spawn(3)]
    sel = slice(None) if mask is None else np.asarray(mask, dtype=bool)
    tt, th, rr = t[sel], theta[sel], rho[sel]
    m = tt.size
    ex = np.zeros(m)
    ey = np.zeros(m)
    ez = np.zeros(m)
    # each term is made in one buffer, in place (the same operations, in the same order,
    # as ``a * np.cos(h * th + p)``)
    term = np.empty(m)
    for target, terms, scale in ((ex, errors.radial_sync, None), (ez, errors.axial_sync, None),
                                 (ez, errors.tilt_sync, rr)):
        for h, a, p in terms:
            np.multiply(h, th, out=term)
            term += p
            trig.cos(term, out=term)
            if scale is None:
                term *= a
            else:  # rr * a * cos(...)
                term *= scale * a
            target += term
    ex += _band_noise(n, rate, errors.async_bandwidth_hz, errors.radial_async_rms, rngs[0])[sel]
    ez += _band_noise(n, rate, errors.async_bandwidth_hz, errors.axial_async_rms, rngs[1])[sel]
    ez += _straightness(rho, errors.x_straightness_rms, errors.x_straightness_length, rngs[2],
                        at=None if mask is None else rr)
    for f, a, d, p in errors.vibration:  # a * sin(2 pi f t + p)
        np.multiply(TWO_PI * f, tt, out=term)
        term += p
        trig.sin(term, out=term)
        term *= a
        {"x": ex, "y": ey, "z": ez}[d][:] += term
    if mask is None:
        return {"x": ex, "y": ey, "z": ez}
    out = {}
    for k, v in (("x", ex), ("y", ey), ("z", ez)):
        full = np.zeros(n)
        full[sel] = v
        out[k] = full
    return out


def apply_error_motions(t: np.ndarray, theta: np.ndarray, rho: np.ndarray, z: np.ndarray,
                        errors: ErrorMotions, *, seed: int = 0,
                        mask: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The tool position relative to the part after the error motions.

    The tool, at (X, 0) in the machine frame, is displaced by (e_x, e_y, e_z); in the
    part's polar frame it is then at radius sqrt((X + e_x)^2 + e_y^2) and angle
    C + atan2(e_y, X + e_x) (kept non-decreasing), height z + e_z.  ``mask``: the ticks
    that need them (:func:`error_motion_offsets`); elsewhere the path is unchanged.

    Returns
    -------
    theta, rho, z : (m,) float64 arrays
    """
    off = error_motion_offsets(t, theta, rho, errors, seed=seed, mask=mask)
    # (in the offsets' own arrays: the sums are those of rho + e_x, theta + atan2, z + e_z)
    xr = off["x"]
    xr += np.asarray(rho, dtype=np.float64)
    if not any(d == "y" for _, _, d, _ in errors.vibration) and np.isfinite(xr).all():
        # no displacement along Y (e_y = +0 at every tick): hypot(x, +0) = |x| and
        # atan2(+0, x) = +0 (x >= +0) or +pi (x <= -0) exactly (C99 Annex F), for finite x
        rho2 = np.abs(xr)
        th2 = off["y"]
        behind = np.signbit(xr)
        if behind.any():
            th2[behind] = np.pi
    else:
        rho2 = np.hypot(xr, off["y"])
        th2 = np.arctan2(off["y"], xr, out=off["y"])
    th2 += np.asarray(theta, dtype=np.float64)
    np.maximum.accumulate(th2, out=th2)
    z2 = off["z"]
    z2 += np.asarray(z, dtype=np.float64)
    return th2, rho2, z2
