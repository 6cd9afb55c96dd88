"""Machine presets: the lathes a scene's ``machine.preset`` names, with where each number
comes from (``Machine.sources``; docs/machine_and_material.md)."""

from __future__ import annotations

from dataclasses import replace

from ..core.errors import InputError
from ..core.units import STANDARD_GRAVITY_MM_S2, UM_TO_MM
from ._axes import Axis, Coupling, Machine
from ._errmotion import ErrorMotions

__all__ = ["MACHINE_PRESETS", "MACHINE_PRESET_NAMES", "machine_preset"]


def _um(v):
    return v * UM_TO_MM


#: Machine presets.  The numbers and where they come from are in ``sources`` and in
#: docs/machine_and_material.md; every one can be overridden.
MACHINE_PRESETS: dict = {}


def _register_presets():
    g = STANDARD_GRAVITY_MM_S2
    MACHINE_PRESETS["ideal"] = Machine(
        name="ideal", sources={"all": "no dynamics, no error motions: the commanded path"})
    # A Nanoform 250 / Nanotech 350FG class slow-tool-servo lathe (hydrostatic or air-bearing
    # slides with linear motors, air-bearing spindle).  The X slide carries the headstock
    # (the RCSE study, Optica 2024: "the X-axis is connected to the heavier headstock"), hence a lower
    # bandwidth than Z.
    sts_errors = ErrorMotions(
        radial_sync=((2, _um(0.005), 0.3), (3, _um(0.003), 1.1)),
        radial_async_rms=_um(0.002), axial_sync=((2, _um(0.003), 0.7), (3, _um(0.002), 2.0)),
        axial_async_rms=_um(0.002), async_bandwidth_hz=200.0,
        x_straightness_rms=_um(0.05), x_straightness_length=50.0)
    MACHINE_PRESETS["sts_lathe"] = Machine(
        name="sts_lathe", servo_rate_hz=5000.0, interpolation="pvt",
        c=Axis(bandwidth_hz=60.0, damping=0.7, velocity_ff=1.0, acceleration_ff=0.9,
               noise_rms=1.0e-6),
        x=Axis(bandwidth_hz=40.0, damping=0.7, velocity_ff=0.95, acceleration_ff=0.5,
               acceleration_limit=0.2 * g, velocity_limit=50.0, noise_rms=_um(0.003)),
        z=Axis(bandwidth_hz=100.0, damping=0.7, velocity_ff=0.95, acceleration_ff=0.5,
               acceleration_limit=0.2 * g, velocity_limit=50.0, noise_rms=_um(0.003)),
        errors=sts_errors,
        coupling=Coupling(mass_kg=150.0, z_compliance_nm_per_n=0.3, y_compliance_nm_per_n=0.3,
                          mode_hz=120.0, mode_damping=0.05),
        sources={
            "servo_rate_hz": "5 kHz: PMAC-class motion controllers of diamond-turning "
                             "lathes run their servo loops at 2-10 kHz (assumed)",
            "interpolation": "PVT, as in the compound sinusoidal grid study (Table 3)",
            "acceleration_limit": "0.2 g slide acceleration, the compound sinusoidal grid "
                                  "study's Table 3 (Nanoform 250)",
            "x.bandwidth_hz": "40 Hz: the X slide carries the spindle headstock (the RCSE study), "
                              "hence the heavier, slower axis (assumed)",
            "z.bandwidth_hz": "100 Hz: tool-side Z slide, lighter (assumed)",
            "feed_forward": "slides: velocity feed-forward 0.95, acceleration feed-forward "
                            "0.5 (feed-forward gains are tuned to 90-100 %; assumed); "
                            "C: 1.0 / 0.9",
            "noise_rms": "3 nm following-error floor per slide: the RCSE study measured a "
                         "16 nm maximum X following error on a smooth path, and Li et al. 2018's measured "
                         "Sq (7.1 +- 0.3 nm) leaves ~2-3 nm rms for everything beyond the feed "
                         "scallop (6.7-7.2 nm)",
            "coupling": "X carriage with the headstock 150 kg; cross-compliance from the X "
                        "drive force to the tool-part loop 0.3 nm/N along Z and Y, about 5 % "
                        "of the 5-10 nm/N direct loop compliance of such lathes; frame mode "
                        "120 Hz, damping 0.05 (all assumed)",
            "x_straightness": "0.05 um rms, 50 mm correlation: the compound sinusoidal grid study's Table 1 gives "
                              "0.2 um straightness over the 220 mm travel (a long-wave bow)",
            "spindle": "radial / axial synchronous error motion 5 / 3 nm at 2 upr, 3 / 2 nm "
                       "at 3 upr, 2 nm asynchronous: within the <= 25-50 nm motion accuracy "
                       "quoted for air-bearing spindles of such lathes and small enough for "
                       "the measured Sq of Li et al. 2018 (assumed)"})
    MACHINE_PRESETS["fts"] = replace(
        MACHINE_PRESETS["sts_lathe"], name="fts", servo_rate_hz=20000.0,
        fts=Axis(bandwidth_hz=2000.0, damping=0.6, velocity_ff=1.0, acceleration_ff=0.9,
                 noise_rms=_um(0.002)),
        fts_sync="position",
        sources={**MACHINE_PRESETS["sts_lathe"].sources,
                 "servo_rate_hz": "20 kHz: fast-tool-servo controllers sample at 10-50 kHz "
                                  "(assumed)",
                 "fts.bandwidth_hz": "2 kHz closed-loop bandwidth of a piezo FTS with a "
                                     "stroke of tens of um (typical 1-3 kHz; assumed)",
                 "fts.feed_forward": "velocity 1.0, acceleration 0.9: FTS controllers feed "
                                     "the stroke's derivatives forward (inverse model) to "
                                     "track within a small fraction of the stroke (assumed)",
                 "fts_sync": "position: the FTS reads the spindle encoder (Kong et al. 2020 "
                             "name position and time synchronisation)"})


_register_presets()
#: the names ``machine.preset`` takes
MACHINE_PRESET_NAMES = tuple(MACHINE_PRESETS)


def machine_preset(name: str = "ideal", overrides: dict | None = None) -> Machine:
    """A machine preset (``"ideal"``, ``"sts_lathe"``, ``"fts"``) with ``overrides``
    (see :meth:`Machine.with_overrides`)."""
    if name not in MACHINE_PRESETS:
        raise InputError(f"machine.preset must be one of {sorted(MACHINE_PRESETS)}, received {name!r}")
    return MACHINE_PRESETS[name].with_overrides(overrides)
