"""The machine: its axes, error motions and coupling together (:class:`Machine`)."""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

from ..core.errors import InputError, check_range
from ._axes import Axis, Coupling
from ._errmotion import ErrorMotions


# ---------------------------------------------------------------------------------------
# the machine
# ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Machine:
    """A C-X-Z turning machine with an optional fast tool servo.

    Parameters
    ----------
    name : str
    servo_rate_hz : float
        Rate at which the interpolator evaluates the commands and the loops run.
    interpolation : {"pvt", "linear"}
    c, x, z, fts : Axis
        Spindle angle (rad), radial slide X (mm), axial slide Z (mm), fast tool servo (mm,
        along Z).
    fts_sync : {"position", "time"}
        How the FTS stroke is timed: ``"position"`` evaluates the stroke at the measured
        (followed) spindle angle, ``"time"`` plays it against the clock.
    fts_sync_delay_s : float
        Signed timing of the FTS stroke relative to the spindle position (or clock) it is
        synchronised to, s: > 0 the stroke comes late (it is evaluated for where the
        spindle was that long ago), < 0 early.  Communication between the FTS controller
        and the motion controller ("two processes controlled separately"); 0 in the
        presets.
    errors : ErrorMotions or None
        Spindle and slide error motions and tool-part vibration
        (:class:`~render_inspect.machining._errmotion.ErrorMotions`).
    coupling : Coupling
        Reaction-force coupling of the X slide into the tool-part loop.
    sources : dict
        Where each preset value comes from (text).
    """

    name: str = "custom"
    servo_rate_hz: float = 10_000.0
    interpolation: str = "pvt"
    c: Axis = field(default_factory=Axis)
    x: Axis = field(default_factory=Axis)
    z: Axis = field(default_factory=Axis)
    fts: Axis = field(default_factory=Axis)
    fts_sync: str = "position"
    fts_sync_delay_s: float = 0.0
    errors: ErrorMotions | None = None
    coupling: Coupling = field(default_factory=Coupling)
    sources: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        check_range("servo_rate_hz", self.servo_rate_hz, 0.0, 1e7, lo_open=True)
        if self.interpolation not in ("pvt", "linear"):
            raise InputError(f"machine.interpolation must be 'pvt' or 'linear', received "
                             f"{self.interpolation!r}")
        if self.fts_sync not in ("position", "time"):
            raise InputError(f"machine.fts_sync must be 'position' or 'time', received {self.fts_sync!r}")
        check_range("machine.fts_sync_delay_s", self.fts_sync_delay_s, -1.0, 1.0)
        for k in ("c", "x", "z", "fts"):
            if not isinstance(getattr(self, k), Axis):
                raise InputError(f"machine.{k} must be an Axis, received {type(getattr(self, k)).__name__}")

    @property
    def ideal(self) -> bool:
        """All axes ideal and no error motions: the program is followed exactly."""
        no_err = self.errors is None or getattr(self.errors, "none", True)
        return (all(getattr(self, k).ideal for k in ("c", "x", "z", "fts")) and no_err
                and self.coupling.none and self.fts_sync_delay_s == 0)

    def to_dict(self) -> dict:
        d = {"name": self.name, "servo_rate_hz": self.servo_rate_hz,
             "interpolation": self.interpolation, "fts_sync": self.fts_sync,
             "fts_sync_delay_s": self.fts_sync_delay_s}
        for k in ("c", "x", "z", "fts"):
            d[k] = getattr(self, k).to_dict()
        d["errors"] = None if self.errors is None else self.errors.to_dict()
        d["coupling"] = self.coupling.to_dict()
        return d

    def with_overrides(self, overrides: dict | None) -> "Machine":
        """A copy with ``overrides`` applied: ``{"x": {"bandwidth_hz": 80}, "servo_rate_hz":
        5000}`` or dotted keys ``{"x.bandwidth_hz": 80}``; ``errors`` takes an
        ErrorMotions or a dict of its fields."""
        if not overrides:
            return self
        nested: dict = {}
        for key, val in overrides.items():
            parts = key.split(".")
            d = nested
            for p in parts[:-1]:
                d = d.setdefault(p, {})
            if isinstance(val, dict) and parts[-1] in d and isinstance(d[parts[-1]], dict):
                d[parts[-1]].update(val)
            else:
                d[parts[-1]] = val
        kw: dict[str, Any] = {}
        for key, val in nested.items():
            if key in ("c", "x", "z", "fts"):
                if isinstance(val, Axis):
                    kw[key] = val
                    continue
                if not isinstance(val, dict):
                    raise InputError(f"machine.{key} overrides must be a table of axis settings, "
                                     f"received {val!r}")
                names = {f.name for f in fields(Axis)}
                bad = sorted(set(val) - names)
                if bad:
                    raise InputError(f"unknown machine.{key} setting(s) {bad}; allowed: {sorted(names)}")
                kw[key] = replace(getattr(self, key), **val)
            elif key == "coupling":
                if isinstance(val, Coupling):
                    kw[key] = val
                else:
                    names = {f.name for f in fields(Coupling)}
                    bad = sorted(set(val) - names)
                    if bad:
                        raise InputError(f"unknown machine.coupling setting(s) {bad}; allowed: "
                                         f"{sorted(names)}")
                    kw[key] = replace(self.coupling, **val)
            elif key == "errors":
                if val is None or isinstance(val, ErrorMotions):
                    kw[key] = val
                else:
                    base = self.errors if self.errors is not None else ErrorMotions()
                    kw[key] = base.with_overrides(val)
            elif key in ("name", "servo_rate_hz", "interpolation", "fts_sync", "fts_sync_delay_s"):
                kw[key] = val
            else:
                raise InputError(f"unknown machine setting {key!r}; allowed: name, servo_rate_hz, "
                                 "interpolation, fts_sync, fts_sync_delay_s, c, x, z, fts, "
                                 "errors, coupling")
        return replace(self, **kw)
