"""Interference objectives: magnification, numerical aperture, working pixel, field.

The presets are typical of CCI / Nexview-class interference microscopes with a
1024 x 1024 camera: Michelson objectives at low magnification, Mirau from 10x up.  The
working pixel is the camera pixel projected onto the part (mm), the field of view the
square it covers.  Every value can be overridden (:func:`objective`).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

from ..core.errors import InputError, check_range

__all__ = ["OBJECTIVES", "Objective", "objective"]

_DESIGNS = ("michelson", "mirau", "linnik")


@dataclass(frozen=True)
class Objective:
    """An interference objective and the camera field it gives.

    Attributes
    ----------
    name : str
        Preset name (e.g. ``"20x"``).
    magnification : float
    numerical_aperture : float
        Collection NA, 0 < NA < 1.
    pixel : float
        Working pixel: camera pixel pitch on the part, mm.
    field_of_view : float
        Side of the square field, mm.
    design : {"michelson", "mirau", "linnik"}
    central_obscuration : float
        Radius of the pupil's central obscuration as a fraction of the pupil radius
        (the reference mirror of a Mirau objective; 0 = clear pupil).
    """

    name: str
    magnification: float
    numerical_aperture: float
    pixel: float
    field_of_view: float
    design: str = "mirau"
    central_obscuration: float = 0.0

    @property
    def camera_pixels(self) -> int:
        """Pixels across the field."""
        return round(self.field_of_view / self.pixel)

    @property
    def slope_limit(self) -> float:
        """Largest surface slope (rad) that can return light into the pupil with a
        filled illumination aperture: ``asin(NA)``."""
        return math.asin(self.numerical_aperture)

    def describe(self) -> dict:
        """Plain numbers (recorded in the frames' settings)."""
        d = asdict(self)
        d["camera_pixels"] = self.camera_pixels
        return d


def _preset(name, mag, na, fov, design, n=1024):
    return Objective(name, float(mag), float(na), fov / n, float(fov), design)


#: Objective presets (typical Michelson / Mirau values, 1024 x 1024 camera).
OBJECTIVES: dict[str, Objective] = {o.name: o for o in (
    _preset("2.5x", 2.5, 0.075, 7.2, "michelson"),
    _preset("5x", 5, 0.13, 3.6, "michelson"),
    _preset("10x", 10, 0.30, 1.8, "mirau"),
    _preset("20x", 20, 0.40, 0.9, "mirau"),
    _preset("50x", 50, 0.55, 0.36, "mirau"),
    _preset("100x", 100, 0.70, 0.18, "mirau"),
)}


def objective(name: str = "20x", **overrides) -> Objective:
    """An objective preset with optional overrides.

    Parameters
    ----------
    name : str
        One of :data:`OBJECTIVES` (``"2.5x"`` .. ``"100x"``).
    **overrides
        ``magnification``, ``numerical_aperture``, ``pixel`` (mm), ``field_of_view``
        (mm), ``design``, ``central_obscuration``; ``None`` keeps the preset's value.

    Returns
    -------
    Objective
    """
    if name not in OBJECTIVES:
        raise InputError(f"objective must be one of {sorted(OBJECTIVES, key=lambda s: float(s[:-1]))}, "
                         f"got {name!r}")
    allowed = {"magnification", "numerical_aperture", "pixel", "field_of_view", "design",
               "central_obscuration"}
    unknown = set(overrides) - allowed
    if unknown:
        raise InputError(f"objective overrides must be among {sorted(allowed)}, got {sorted(unknown)}")
    ov = {k: v for k, v in overrides.items() if v is not None}
    o = replace(OBJECTIVES[name], **ov)
    check_range("numerical_aperture", o.numerical_aperture, 0, 0.95, lo_open=True)
    check_range("magnification", o.magnification, 0, None, lo_open=True)
    check_range("pixel", o.pixel, 0, 1.0, lo_open=True)
    check_range("field_of_view", o.field_of_view, 0, None, lo_open=True)
    check_range("central_obscuration", o.central_obscuration, 0, 0.9)
    if o.design not in _DESIGNS:
        raise InputError(f"design must be one of {_DESIGNS}, got {o.design!r}")
    return o
