"""Material response of diamond cutting: minimum uncut chip thickness, elastic recovery,
side flow, adhesion, and what intermittent (ultrasonic vibration) cutting changes.

The model (sources and approximations in docs/machine_and_material.md)
----------------------------------------------------------------------
* **Minimum uncut chip thickness** (Son, Lim & Ahn 2005 [1]_): a round cutting edge of
  radius r_e forms a chip only where the local uncut chip thickness h reaches
  h_min = r_e (1 - cos(pi/4 - beta/2)), beta = atan(mu) the friction angle between tool
  and work.  Thinner material is ploughed.
* **Elastic recovery** of the ploughed material: a fraction kappa of the ploughed depth
  springs back.  kappa = c (H / E_r) with E_r the reduced modulus of the diamond-work
  contact and c = 0.727 (pi / 2) tan(70.3 deg) ~ 3.2, the elastic unloading depth of a
  conical contact (Sneddon; Oliver & Pharr 1992 [2]_) for the Berkovich-equivalent cone.
  For metals kappa ~ 0.02-0.1: ploughed material is mostly displaced plastically.
* **Side flow** (Liu & Melkote 2006 [3]_): the plastically displaced part (1 - kappa) of
  the ploughed material flows sideways onto the neighbouring, already machined surface,
  raising the feed-mark peaks.  With kappa = 1 (everything left uncut) the cusp height is
  Brammertz's f^2 / (8 R) + h_min / 2 (1 + R h_min / f^2) (Brammertz 1961 [4]_), which the
  envelope reproduces (tested).  Where two cuts meet at a sharp machined edge the same
  mechanism forms a burr on that edge.
* **Adhesion** (chemical affinity of the work to diamond: iron, chromium, nickel; Zhang et
  al. 2022 [5]_ saw Cr and Fe adhered to the tool after conventional sculpturing of
  steel): in continuous contact an adhered layer of thickness ``adhesion_layer`` builds on
  the edge; it blunts it (r_eff = r_e + layer) and its irregularities plough grooves
  along the cut of rms ``adhesion_roughness``.  Intermittent cutting with tool-work
  separation every vibration period stops the layer from building: both scale with the
  *contact ratio* eta, the fraction of time the tool advances into fresh material (1 in
  continuous cutting).  For 1-D vibration along the cut, y = v t + A cos(2 pi f t),
  eta ~ sqrt(v / (pi A 2 pi f)) when v << 2 pi f A (:func:`contact_ratio`, computed
  exactly).

Lengths in mm in code (``*_nm`` keys in presets and outputs); moduli and hardness in GPa.

References
----------
.. [1] S. M. Son, H. S. Lim, J. H. Ahn, "Effects of the friction coefficient on the minimum
       cutting thickness in micro cutting," International Journal of Machine Tools and
       Manufacture 45(4-5), 529-535 (2005). :DOI:`10.1016/j.ijmachtools.2004.10.001`
.. [2] W. C. Oliver, G. M. Pharr, "An improved technique for determining hardness and
       elastic modulus using load and displacement sensing indentation experiments,"
       Journal of Materials Research 7(6), 1564-1583 (1992). :DOI:`10.1557/JMR.1992.1564`
.. [3] K. Liu, S. N. Melkote, "Effect of plastic side flow on surface roughness in
       micro-turning process," International Journal of Machine Tools and Manufacture 46,
       1778-1785 (2006). :DOI:`10.1016/j.ijmachtools.2005.11.014`
.. [4] W. Brammertz, Industrie-Anzeiger 83, 525 (1961).
.. [5] C. Zhang, C.-F. Cheung, X. Liang, B. Bulla, "A theoretical and experimental
       investigation of high-frequency ultrasonic vibration-assisted sculpturing of
       optical microstructures," Applied Sciences 12(21), 10937 (2022).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..core.errors import InputError, check_range
from ..core.units import MM_TO_NM, NM_TO_MM

__all__ = ["Material", "MATERIAL_PRESETS", "material_preset", "MaterialResponse",
           "material_response", "contact_ratio", "min_chip_thickness", "elastic_recovery",
           "DIAMOND_E_GPA", "DIAMOND_NU"]

DIAMOND_E_GPA = 1141.0
DIAMOND_NU = 0.07
#: elastic unloading depth of a conical contact per unit (H / E_r) and contact depth:
#: epsilon (pi / 2) tan(70.3 deg), epsilon = 2 (pi - 2) / pi (Oliver & Pharr 1992)
_KAPPA_C = 2 * (math.pi - 2) / math.pi * (math.pi / 2) * math.tan(math.radians(70.3))


@dataclass(frozen=True)
class Material:
    """Workpiece material (see the module docstring).

    Parameters
    ----------
    name : str
    youngs_modulus_gpa, poisson : float
    hardness_gpa : float
        Indentation (Vickers) hardness.
    friction : float
        Coefficient of friction against diamond.
    adhesion_layer_nm : float
        Adhered layer on the edge in continuous cutting (0 for non-ferrous metals).
    adhesion_roughness_nm : float
        Sq of the grooves the adhered layer ploughs in continuous cutting.
    texture_nm : float
        Sq of the residual material-induced roughness that does not depend on adhesion
        (grain boundaries, inclusions, anisotropic recovery), along the cut.
    sources : dict
    """

    name: str
    youngs_modulus_gpa: float
    poisson: float
    hardness_gpa: float
    friction: float
    adhesion_layer_nm: float = 0.0
    adhesion_roughness_nm: float = 0.0
    texture_nm: float = 0.0
    sources: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        check_range("youngs_modulus_gpa", self.youngs_modulus_gpa, 0.0, 2000.0, lo_open=True)
        check_range("poisson", self.poisson, 0.0, 0.5, hi_open=True)
        check_range("hardness_gpa", self.hardness_gpa, 0.0, 100.0, lo_open=True)
        check_range("friction", self.friction, 0.0, 2.0)
        for k in ("adhesion_layer_nm", "adhesion_roughness_nm", "texture_nm"):
            check_range(k, getattr(self, k), 0.0, 1e5)

    @property
    def reduced_modulus_gpa(self) -> float:
        """E_r of the diamond-work contact: 1/E_r = (1 - nu^2)/E + (1 - nu_d^2)/E_d."""
        return 1.0 / ((1 - self.poisson ** 2) / self.youngs_modulus_gpa
                      + (1 - DIAMOND_NU ** 2) / DIAMOND_E_GPA)

    def to_dict(self) -> dict:
        return {f.name: getattr(self, f.name) for f in fields(self) if f.name != "sources"}

    def with_overrides(self, overrides: dict | None) -> "Material":
        if not overrides:
            return self
        names = {f.name for f in fields(self)} - {"sources"}
        bad = sorted(set(overrides) - names)
        if bad:
            raise InputError(f"unknown material setting(s) {bad}; allowed: {sorted(names)}")
        return replace(self, **overrides)


_HV = 9.80665e-3  # GPa per HV unit

#: Material presets.  Property values are handbook figures (ASM / manufacturers' sheets);
#: the adhesion values for the die steel are set from the conventional sculpturing of
#: Zhang et al. (2022) (see ``sources``).
MATERIAL_PRESETS = {
    "al6061": Material(
        "al6061", 68.9, 0.33, 107 * _HV, 0.15, 0.0, 0.0, 1.0,
        sources={"E, nu, hardness": "Al 6061-T6: 68.9 GPa, 0.33, 107 HV (ASM handbook)",
                 "friction": "0.1-0.2 for diamond on aluminium (assumed 0.15)",
                 "adhesion": "none: aluminium has no chemical affinity to diamond",
                 "texture_nm": "1 nm rms along the cut: precipitates and grain boundaries "
                               "(assumed; diamond-turned Al 6061 reaches Sa ~ 2-5 nm)"}),
    "al6082": Material(
        "al6082", 70.0, 0.33, 95 * _HV, 0.15, 0.0, 0.0, 1.0,
        sources={"E, nu, hardness": "Al 6082-T6: 70 GPa, 0.33, 95 HV (ASM handbook)",
                 "friction": "as al6061", "adhesion": "none", "texture_nm": "as al6061"}),
    "ofhc_copper": Material(
        "ofhc_copper", 117.0, 0.34, 60 * _HV, 0.2, 0.0, 0.0, 0.8,  # not a unit conversion
        sources={"E, nu, hardness": "OFHC copper C10100, half hard: 117 GPa, 0.34, ~60 HV",
                 "friction": "0.2 (assumed)", "adhesion": "none",
                 "texture_nm": "0.8 nm rms: grain-orientation dependent recovery (assumed)"}),
    "nip": Material(
        "nip", 170.0, 0.3, 550 * _HV, 0.1, 0.0, 0.0, 0.5,
        sources={"E, nu, hardness": "electroless nickel-phosphorus, high P (> 10 %), "
                                    "as plated: ~170 GPa, 0.3, ~550 HV",
                 "friction": "0.1 (assumed)",
                 "adhesion": "none: the amorphous high-phosphorus alloy does not wear "
                             "diamond chemically, unlike pure nickel",
                 "texture_nm": "0.5 nm rms: amorphous, no grains (assumed)"}),
    "die_steel": Material(
        "die_steel", 200.0, 0.29, 392 * _HV, 0.2, 500.0, 46.0, 1.0,
        sources={"E, nu, hardness": "Mirrax 40 (Uddeholm), pre-hardened 40 HRC ~ 392 HV, "
                                    "E ~ 200 GPa",
                 "friction": "0.2 (assumed)",
                 "adhesion_roughness_nm": "46 nm Sq: Zhang et al. (2022) measured Sa 37 nm "
                                          "(Sq ~ Sa / 0.8) "
                                          "after conventional sculpturing of Mirrax 40, "
                                          "attributed to adhered material ploughing the surface",
                 "adhesion_layer_nm": "0.5 um adhered layer on the edge in continuous cutting "
                                      "(assumed; Fig. 11 of Zhang et al. (2022) shows "
                                      "considerable Cr / Fe adhesion and a blunted edge)",
                 "texture_nm": "1 nm rms (assumed)"}),
}


def material_preset(name: str, overrides: dict | None = None) -> Material:
    """A material preset (``al6061``, ``al6082``, ``ofhc_copper``, ``nip``, ``die_steel``)
    with ``overrides`` (field name -> value)."""
    if name not in MATERIAL_PRESETS:
        raise InputError(f"material.preset must be one of {sorted(MATERIAL_PRESETS)}, received {name!r}")
    return MATERIAL_PRESETS[name].with_overrides(overrides)


def min_chip_thickness(edge_radius: float, friction: float) -> float:
    """h_min = r_e (1 - cos(pi/4 - beta/2)), beta = atan(friction) (Son et al. 2005 [1]_).

    Parameters
    ----------
    edge_radius : float, any length unit (the result has the same unit)
    friction : float, >= 0
    """
    check_range("edge_radius", edge_radius, 0.0, None)
    check_range("friction", friction, 0.0, None)
    beta = math.atan(friction)
    return float(edge_radius) * (1.0 - math.cos(math.pi / 4 - beta / 2))


def elastic_recovery(material: Material) -> float:
    """kappa = c H / E_r, capped at 1 (see the module docstring)."""
    return min(1.0, _KAPPA_C * material.hardness_gpa / material.reduced_modulus_gpa)


def contact_ratio(cutting_speed: float, amplitude: float = 0.0, frequency_hz: float = 0.0,
                  *, samples_per_period: int = 20000) -> float:
    """Fraction of time the tool advances into fresh material for y = v t + A cos(2 pi f t).

    The tool cuts fresh material while y(t) exceeds every earlier position (its running
    maximum).  With v >= 2 pi f A the tool never reverses: 1.  Computed over one period of
    the steady state on ``samples_per_period`` samples.

    Parameters
    ----------
    cutting_speed : float, mm/s (> 0)
    amplitude : float, mm (>= 0)
    frequency_hz : float, Hz (>= 0)

    Returns
    -------
    float in (0, 1]
    """
    check_range("cutting_speed", cutting_speed, 0.0, None, lo_open=True)
    check_range("amplitude", amplitude, 0.0, None)
    check_range("frequency_hz", frequency_hz, 0.0, None)
    if amplitude == 0 or frequency_hz == 0:
        return 1.0
    w = 2 * math.pi * frequency_hz
    if cutting_speed >= w * amplitude:
        return 1.0
    n = int(samples_per_period)
    # three periods: the first two set the running maximum, the third is counted
    t = np.arange(3 * n) / (n * frequency_hz)
    y = cutting_speed * t + amplitude * np.cos(w * t)
    run = np.maximum.accumulate(y)
    fresh = np.empty(y.size, dtype=bool)
    fresh[0] = True
    fresh[1:] = y[1:] >= run[:-1]
    return float(np.mean(fresh[2 * n:]))


@dataclass(frozen=True)
class MaterialResponse:
    """What the cut leaves, for one material, tool edge and contact ratio (mm).

    Attributes
    ----------
    h_min : minimum uncut chip thickness;  kappa : elastic recovery fraction;
    edge_radius_eff : r_e + adhered layer;  contact_ratio : eta;
    groove_rms : rms of the ploughed grooves along the cut (adhesion and material texture
    added in quadrature);  side_flow : True when the displaced material piles at cusps;
    burr_height : (1 - kappa) h_min, the side-flow ridge on a machined edge (mm).
    """

    h_min: float
    kappa: float
    edge_radius_eff: float
    contact_ratio: float
    groove_rms: float
    side_flow: bool
    burr_height: float
    material: str

    def to_dict(self) -> dict:
        return {"material": self.material, "h_min_nm": self.h_min * MM_TO_NM, "kappa": self.kappa,
                "edge_radius_eff_nm": self.edge_radius_eff * MM_TO_NM,
                "contact_ratio": self.contact_ratio, "groove_rms_nm": self.groove_rms * MM_TO_NM,
                "side_flow": self.side_flow, "burr_height_nm": self.burr_height * MM_TO_NM}


def material_response(material: Material, *, edge_radius: float = 50e-6,
                      contact_ratio: float = 1.0, side_flow: bool = True) -> MaterialResponse:
    """The cutting-mechanics parameters of ``material`` cut by an edge of radius
    ``edge_radius`` (mm) at contact ratio ``contact_ratio`` (1 = continuous cutting)."""
    check_range("edge_radius", edge_radius, 0.0, 1e-2)
    check_range("contact_ratio", contact_ratio, 0.0, 1.0, lo_open=True)
    eta = float(contact_ratio)
    layer = material.adhesion_layer_nm * NM_TO_MM * eta
    r_eff = float(edge_radius) + layer
    h_min = min_chip_thickness(r_eff, material.friction)
    kappa = elastic_recovery(material)
    groove = math.hypot(material.adhesion_roughness_nm * eta, material.texture_nm) * NM_TO_MM
    return MaterialResponse(h_min, kappa, r_eff, eta, groove, bool(side_flow),
                            (1.0 - kappa) * h_min if side_flow else 0.0, material.name)
