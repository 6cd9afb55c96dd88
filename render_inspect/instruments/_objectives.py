"""Interference objectives: magnification, numerical aperture, working pixel, field.

The presets are typical of CCI / Nexview-class interference microscopes with a
1024 x 1024 camera: Michelson objectives at low magnification, Mirau from 10x up.  The
working pixel is the camera pixel projected onto the part (mm), the field of view the
square it covers.  Every value can be overridden (:func:`objective`).  A preset of
another objective is registered with :func:`register_objective`; the scene key
``render.interferometer.objective`` and the command line's ``--objective`` take the
registered names (:func:`objective_names`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from typing import Any

from ..core.errors import InputError, check_range
from ..core.plugins import Registry

__all__ = ["OBJECTIVES", "Objective", "objective", "objective_names", "register_objective"]

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


_OBJECTIVES = Registry("objective")

#: The registered objective presets, name -> :class:`Objective` (read only; it follows
#: :func:`register_objective`).  Built in: typical Michelson / Mirau values, 1024 x 1024
#: camera.
OBJECTIVES: Mapping[str, Objective] = _OBJECTIVES.view()


def register_objective(preset: Objective) -> Objective:
    """Register an objective preset under its ``name`` (registering a name again replaces
    its preset); return it.  The scene key ``render.interferometer.objective`` and
    ``characterise --objective`` / ``fit --objective`` then take the name.

    Parameters
    ----------
    preset : Objective
        Its values are checked as :func:`objective` checks overrides (NA in (0, 0.95],
        positive magnification, pixel in (0, 1] mm, positive field, obscuration 0 .. 0.9,
        one of the designs).
    """
    if not isinstance(preset, Objective):
        raise InputError(f"an objective preset must be an Objective, received "
                         f"{type(preset).__name__}")
    if not isinstance(preset.name, str) or not preset.name.strip():
        raise InputError(f"objective name must be a non-empty text, received {preset.name!r}")
    _check(preset)
    _OBJECTIVES.add((preset.name,), preset)
    return preset


def objective_names() -> list[str]:
    """The registered objective names, lowest magnification first."""
    return sorted(OBJECTIVES, key=lambda n: (OBJECTIVES[n].magnification, n))


def objective(name: str = "20x", **overrides: Any) -> Objective:
    """An objective preset with optional overrides.

    Parameters
    ----------
    name : str
        One of :data:`OBJECTIVES` (``"2.5x"`` .. ``"100x"`` and those registered with
        :func:`register_objective`).
    **overrides
        ``magnification``, ``numerical_aperture``, ``pixel`` (mm), ``field_of_view``
        (mm), ``design``, ``central_obscuration``; ``None`` keeps the preset's value.

    Returns
    -------
    Objective
    """
    if name not in OBJECTIVES:
        raise InputError(f"objective must be one of {objective_names()}, got {name!r}")
    allowed = {"magnification", "numerical_aperture", "pixel", "field_of_view", "design",
               "central_obscuration"}
    unknown = set(overrides) - allowed
    if unknown:
        raise InputError(f"objective overrides must be among {sorted(allowed)}, got {sorted(unknown)}")
    ov = {k: v for k, v in overrides.items() if v is not None}
    o = replace(OBJECTIVES[name], **ov)
    _check(o)
    return o


def _check(o: Objective) -> None:
    check_range("numerical_aperture", o.numerical_aperture, 0, 0.95, lo_open=True)
    check_range("magnification", o.magnification, 0, None, lo_open=True)
    check_range("pixel", o.pixel, 0, 1.0, lo_open=True)
    check_range("field_of_view", o.field_of_view, 0, None, lo_open=True)
    check_range("central_obscuration", o.central_obscuration, 0, 0.9)
    if o.design not in _DESIGNS:
        raise InputError(f"design must be one of {_DESIGNS}, got {o.design!r}")


# the built-in presets
for _o in (
    _preset("2.5x", 2.5, 0.075, 7.2, "michelson"),
    _preset("5x", 5, 0.13, 3.6, "michelson"),
    _preset("10x", 10, 0.30, 1.8, "mirau"),
    _preset("20x", 20, 0.40, 0.9, "mirau"),
    _preset("50x", 50, 0.55, 0.36, "mirau"),
    _preset("100x", 100, 0.70, 0.18, "mirau"),
):
    register_objective(_o)
del _o
