"""Machine presets: the lathes a scene's ``machine.preset`` names, with where each number
comes from (``Machine.sources``; docs/machine_and_material.md), or its assumed range.

``sts_lathe`` stands for a Nanoform 250 / Nanotech 350FG class slow-tool-servo lathe
(hydrostatic or air-bearing slides driven by linear motors, an air-bearing spindle, a
PMAC-class controller); ``fts`` adds a piezo fast tool servo.  No datasheet of these
lathes' drives or loops is available: such numbers are assumed, with the ranges in
``sources``, and derived from each other where physics links them (the drive limit from
the motor force and the moving mass; the Z slide's noise from the X slide's through one
force-noise spectrum).

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566` (Nanoform 250 Ultra Grind: straightness < 0.2 um over the
       travel, spindle axial and radial error motion < 15 nm)
.. [2] "Rotary-coordinate and shuttling-element cutting strategy for ultra-precision
       diamond turning of optical microstructures," Optica Publishing Group (2024) (the X
       axis carries the headstock; 16 nm maximum X following error on a smooth path)
.. [3] The compound sinusoidal grid study (STS, hybrid sampling; Nanoform 250): Table 1
       (C positioning +-2 arcsec, straightness 0.2 um over 220 mm), Table 3 (PVT
       interpolation; 0.2 g programmed slide acceleration).
.. [4] L. Kong, Y. Ma, M. Ren, M. Xu, C.-F. Cheung, "Generation and characterization of
       ultra-precision compound freeform surfaces," Science Progress 103(1), 1-12 (2020).
       :DOI:`10.1177/0036850419880112` (position and time synchronisation of the FTS)
.. [5] D. S. Grejda, E. R. Marsh, R. R. Vallance, "Techniques for calibrating spindles
       with nanometer error motion," Precision Engineering 29, 113-123 (2005).
.. [6] Y. Altintas, A. Verl, C. Brecher, L. Uriarte, G. Pritschow, "Machine tool feed
       drives," CIRP Annals 60(2), 779-796 (2011) (feed-forward in CNC feed drives).
.. [7] Air-bearing spindle error motion, Lion Precision white paper
       (https://projects.peterpolidoro.net/seagull/whitepaper/whitepaper2.htm): "most air
       bearings easily measure less than one micro-inch [25 nm] asynchronous error motion".
"""

from __future__ import annotations

from dataclasses import replace

from ..core.errors import InputError
from ..core.units import M_TO_MM, NM_TO_MM, STANDARD_GRAVITY_MM_S2, UM_TO_MM
from ._axes import Axis, Coupling, force_noise_rms
from ._machine import Machine
from ._errmotion import ErrorMotions

__all__ = ["MACHINE_PRESETS", "MACHINE_PRESET_NAMES", "machine_preset"]


def _um(v):
    return v * UM_TO_MM


#: Machine presets.  The numbers and where they come from are in ``sources`` and in
#: docs/machine_and_material.md; every one can be overridden.
MACHINE_PRESETS: dict = {}


#: assumed moving masses (kg): the X slide carries the headstock (the RCSE study), the Z
#: slide the tool post; ranges 80-300 kg (X), 30-100 kg (Z)
X_MASS_KG = 150.0
Z_MASS_KG = 75.0
#: assumed peak force of each slide's linear motor (N), range 0.5-3 kN
PEAK_FORCE_N = 1500.0
#: X following-error floor (mm rms): the RCSE study's 16 nm maximum X following error on a
#: smooth path over ~7e6 servo ticks is ~5 standard deviations of Gaussian noise
X_NOISE_MM = 3.0 * NM_TO_MM


def _register_presets():
    g = STANDARD_GRAVITY_MM_S2
    MACHINE_PRESETS["ideal"] = Machine(
        name="ideal", sources={"all": "no dynamics, no error motions: the commanded path"})
    x_bw, z_bw, zeta = 40.0, 100.0, 0.7
    # one force-noise spectrum for both slides (amplifiers, bearings, floor): X sets it,
    # Z follows from its mass and loop
    psd = (X_NOISE_MM / force_noise_rms(1.0, X_MASS_KG, x_bw, zeta) / M_TO_MM) ** 2
    z_noise = force_noise_rms(psd, Z_MASS_KG, z_bw, zeta) * M_TO_MM
    # drive limits: peak force over moving mass (mm/s^2)
    x_amax = PEAK_FORCE_N / X_MASS_KG * M_TO_MM
    z_amax = PEAK_FORCE_N / Z_MASS_KG * M_TO_MM
    sts_errors = ErrorMotions(
        radial_sync=((2, _um(0.005), 0.3), (3, _um(0.003), 1.1)),
        radial_async_rms=_um(0.001), axial_sync=((2, _um(0.003), 0.7), (3, _um(0.002), 2.0)),
        axial_async_rms=_um(0.001), async_bandwidth_hz=200.0,
        x_straightness_rms=_um(0.05), x_straightness_length=50.0)
    MACHINE_PRESETS["sts_lathe"] = Machine(
        name="sts_lathe", servo_rate_hz=5000.0, interpolation="pvt",
        c=Axis(bandwidth_hz=60.0, damping=0.7, velocity_ff=1.0, acceleration_ff=0.9,
               noise_rms=1.0e-6),
        x=Axis(bandwidth_hz=x_bw, damping=zeta, velocity_ff=0.95, acceleration_ff=0.5,
               acceleration_limit=x_amax, velocity_limit=50.0, noise_rms=X_NOISE_MM),
        z=Axis(bandwidth_hz=z_bw, damping=zeta, velocity_ff=0.95, acceleration_ff=0.5,
               acceleration_limit=z_amax, velocity_limit=50.0, noise_rms=z_noise),
        errors=sts_errors,
        coupling=Coupling(mass_kg=X_MASS_KG, z_compliance_nm_per_n=0.1, y_compliance_nm_per_n=0.1,
                          mode_hz=120.0, mode_damping=0.05),
        sources={
            "servo_rate_hz": "5 kHz (assumed, 2-10 kHz: PMAC-class motion controllers of "
                             "diamond-turning lathes)",
            "interpolation": "PVT, as in the compound sinusoidal grid study (Table 3)",
            "c": "C loop 60 Hz, zeta 0.7, feed-forward 1.0 / 0.9 (assumed, 20-100 Hz); noise "
                 "1 urad rms (within the +-2 arcsec = 9.7 urad C positioning accuracy of the "
                 "compound sinusoidal grid study's Table 1; assumed, 0.2-5 urad)",
            "x.bandwidth_hz": "40 Hz (assumed, 20-80 Hz): the X slide carries the spindle "
                              "headstock (the RCSE study), the heavier, slower axis",
            "z.bandwidth_hz": "100 Hz (assumed, 50-200 Hz): the lighter tool-side slide",
            "damping": "0.7 (assumed, 0.5-1)",
            "feed_forward": "velocity 0.95, acceleration 0.5 (assumed, kv 0.9-1.0, ka 0.5-1.0; "
                            "feed-forward is standard in CNC feed drives, Altintas et al. 2011)",
            "acceleration_limit": f"drive limit = peak motor force / moving mass: "
                                  f"{PEAK_FORCE_N:g} N / {X_MASS_KG:g} kg = {x_amax / g:.2f} g "
                                  f"(X), / {Z_MASS_KG:g} kg = {z_amax / g:.2f} g (Z) (assumed: "
                                  "0.5-3 kN, X 80-300 kg, Z 30-100 kg).  The 0.2 g of the "
                                  "compound sinusoidal grid study is the acceleration one job "
                                  "was programmed with, a kinematics limit "
                                  "(process.x_acceleration_limit_mm_s2), not the drive's",
            "velocity_limit": "50 mm/s (assumed, 15-100 mm/s)",
            "x.noise": "3 nm rms: the RCSE study measured a 16 nm maximum X following error "
                       "on a smooth path; over ~7e6 servo ticks the maximum of Gaussian noise "
                       "is ~5 standard deviations (an upper bound: it includes encoder noise; "
                       "range 1-4 nm)",
            "z.noise": f"{z_noise / _um(0.001):.2f} nm rms: the X slide's force-noise "
                       "spectrum on the Z slide, var = S_F / (4 zeta wn^3 m^2) with "
                       f"{Z_MASS_KG:g} kg and {z_bw:g} Hz against {X_MASS_KG:g} kg and "
                       f"{x_bw:g} Hz",
            "coupling": "X carriage with the headstock 150 kg (assumed, 80-300 kg); "
                        "cross-compliance from the X drive force to the tool-part loop 0.1 "
                        "nm/N along Z and Y: no source; a few per cent of the 5-20 nm/N direct "
                        "loop compliance of such lathes, range 0.02-0.5 nm/N (the RCSE result "
                        "is shown over that range in docs/machine_and_material.md); frame mode "
                        "120 Hz, damping 0.05 (assumed, 50-300 Hz, 0.02-0.1)",
            "x_straightness": "0.05 um rms, 50 mm correlation: straightness < 0.2 um over the "
                              "travel (Li et al. 2018; the compound sinusoidal grid study's "
                              "Table 1: over 220 mm), a long-wave bow",
            "spindle": "synchronous radial / axial error motion 5 / 3 nm at 2 upr, 3 / 2 nm at "
                       "3 upr (assumed, 1-7 nm per harmonic): within the < 15 nm axial and "
                       "radial error motion of the Nanoform 250 (Li et al. 2018); spindles "
                       "with < 5 nm radial error motion are measured (Grejda et al. 2005)",
            "spindle_async": "1 nm rms radial and axial (assumed, 0.5-3 nm): air-bearing "
                             "spindles measure below 25 nm asynchronous error motion (Lion "
                             "Precision white paper) and below 15 nm in all (Li et al. 2018); "
                             "bandwidth 200 Hz (assumed, 50-500 Hz)"})
    MACHINE_PRESETS["fts"] = replace(
        MACHINE_PRESETS["sts_lathe"], name="fts", servo_rate_hz=20000.0,
        fts=Axis(bandwidth_hz=2000.0, damping=0.6, velocity_ff=1.0, acceleration_ff=0.9,
                 noise_rms=_um(0.002)),
        fts_sync="position",
        sources={**MACHINE_PRESETS["sts_lathe"].sources,
                 "servo_rate_hz": "20 kHz (assumed, 10-50 kHz: fast-tool-servo controllers)",
                 "fts.bandwidth_hz": "2 kHz, zeta 0.6 (assumed, 0.5-3 kHz: the closed-loop "
                                     "bandwidth of piezo FTS of tens of um stroke; it falls "
                                     "with the stroke)",
                 "fts.feed_forward": "velocity 1.0, acceleration 0.9 (assumed): FTS "
                                     "controllers feed the stroke's derivatives forward "
                                     "(inverse model)",
                 "fts.noise": "2 nm rms (assumed, 0.5-3 nm)",
                 "fts_sync": "position: the spindle angle and X are fed to the FTS (Kong et al. "
                             "2020 name position and time synchronisation)",
                 "fts_sync_delay_s": "0 (a property of one set-up: Kong et al.'s (2020) "
                                     "dislocations imply 1.2-1.5 ms, set in their scene)"})


_register_presets()
#: the names ``machine.preset`` takes
MACHINE_PRESET_NAMES = tuple(MACHINE_PRESETS)


def machine_preset(name: str = "ideal", overrides: dict | None = None) -> Machine:
    """A machine preset (``"ideal"``, ``"sts_lathe"``, ``"fts"``) with ``overrides``
    (see :meth:`Machine.with_overrides`)."""
    if name not in MACHINE_PRESETS:
        raise InputError(f"machine.preset must be one of {sorted(MACHINE_PRESETS)}, received {name!r}")
    return MACHINE_PRESETS[name].with_overrides(overrides)
