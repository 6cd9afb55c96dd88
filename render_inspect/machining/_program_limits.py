"""What a machine lets a program do: the largest programmed feed and the axes' travel of
each ``machine.preset``, the limits every written program is checked against.

These are properties of the machine, never of the program or of the scene's process
keys: a program that sets its own plunge feed or depth of cut cannot raise them.

The travel is each slide's stroke.  Where the part's zero lies within the stroke is a
matter of the set-up, not known to the program, so the check is the one that holds for
every set-up: no programmed position lies farther from the part's zero than the whole
stroke (``|X|``, ``|Y|``, ``|Z|`` at most the stroke).

Sources (docs/machine_and_material.md lists them with the presets):

* ``sts_lathe`` / ``fts``: a Nanoform 250 class lathe.  X travel 220 mm (the compound
  sinusoidal grid study, Table 1: straightness 0.2 um over 220 mm); Z travel 150 mm
  (assumed, 100-300 mm); the largest programmed feed the slides' 50 mm/s velocity limit
  (3000 mm/min, assumed 15-100 mm/s: the preset's ``velocity_limit``).
* ``ideal``: the commanded path, no dynamics; its programs are checked against a linear
  X-Y-Z ultra-precision machine of the Nanotech 350FG class (assumed: X 350 mm, Y 150
  mm, Z 300 mm travel, 3000 mm/min largest feed, range 1000-6000 mm/min).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ProgramLimits", "PROGRAM_LIMITS", "program_limits_of"]


@dataclass(frozen=True)
class ProgramLimits:
    """The largest programmed feed (mm/min) and each axis's stroke (mm) of a machine."""

    feed_mm_per_min: float
    stroke_mm: dict
    source: str

    def travel(self) -> dict:
        """Axis -> (lowest, highest) programmed position, mm (see the module docstring)."""
        return {a: (-s, s) for a, s in self.stroke_mm.items()}


_LATHE = ProgramLimits(feed_mm_per_min=3000.0, stroke_mm={"X": 220.0, "Z": 150.0},
                       source="a Nanoform 250 class lathe")
#: ``machine.preset`` -> its program limits
PROGRAM_LIMITS = {
    "ideal": ProgramLimits(feed_mm_per_min=3000.0,
                           stroke_mm={"X": 350.0, "Y": 150.0, "Z": 300.0},
                           source="a Nanotech 350FG class machine"),
    "sts_lathe": _LATHE,
    "fts": _LATHE,
}


def program_limits_of(preset: str) -> ProgramLimits:
    """The program limits of ``machine.preset`` (a preset without its own: the ideal
    machine's)."""
    return PROGRAM_LIMITS.get(preset, PROGRAM_LIMITS["ideal"])
