"""Material response of diamond cutting: minimum uncut chip thickness, elastic recovery,
side flow, burrs, the part's own texture, and what intermittent (ultrasonic vibration)
cutting changes.

The model (sources, ranges and approximations in docs/machine_and_material.md)
------------------------------------------------------------------------------
* **Minimum uncut chip thickness** (Son, Lim & Ahn 2005 [1]_): a round cutting edge of
  radius r_e forms a chip only where the local uncut chip thickness h reaches
  h_min = r_e (1 - cos(pi/4 - beta/2)), beta = atan(mu) the friction angle between tool
  and work.  Thinner material is ploughed.
* **Elastic recovery** of the ploughed material: the fraction kappa of the ploughed depth
  that springs back when the edge has passed, taken as the *recovered* depth of a conical
  indentation unloaded along Oliver & Pharr's [2]_ power law P ~ (h - h_f)^2:
  h_e = 2 P / S with P = H pi tan^2(theta) h_c^2 and S = 2 E_r tan(theta) h_c, so

      kappa = h_e / h_c = pi tan(theta) H / E_r  (theta = 70.3 deg, the Berkovich-equivalent
      cone; E_r the reduced modulus of the diamond-work contact),

  2 / epsilon = 2.75 times the elastic deflection at the contact perimeter ("sink-in",
  epsilon = 0.727).  Cheng & Cheng [6]_ found the elastic fraction of the indentation work
  linear in H / E_r, the form used here.  The ploughing contact of a round edge is closer
  to a cylinder than a cone: the prefactor is the cone's (an approximation).
  Metals: kappa ~ 0.07-0.3.
* **Side flow** (Liu & Melkote 2006 [3]_): the plastically displaced part (1 - kappa) of
  the ploughed material flows sideways onto the neighbouring, already machined surface,
  raising the feed-mark peaks.  With kappa = 1 (everything left uncut) the cusp height is
  Brammertz's f^2 / (8 R) + h_min / 2 (1 + R h_min / f^2) (Brammertz 1961 [4]_), which the
  envelope reproduces (tested).
* **Burrs** on the sharp edges of the cut (:func:`render_inspect.machining.material_burrs`):
  height C A h_u g(turn), with h_u the uncut chip thickness of the finishing cut, the
  exit-angle factor g and the ductility factor A of :attr:`MaterialResponse.burr_coefficient`
  (Gillespie & Blotter [7]_; Hashimura, Chang & Dornfeld [8]_).
* **Texture**: the residual roughness of the part itself (grain boundaries, precipitates,
  grain-orientation-dependent recovery), a Gaussian random field of the position on the
  part (:func:`texture_field`): it belongs to the part, so the same seed gives the same
  texture whatever the feed, the path or the grid.
* **Adhesion** (an empirical input, no model): steel and other iron-bearing alloys adhere
  to and wear diamond chemically (graphitisation and diffusion of carbon into iron;
  Paul et al. 1996 [9]_, Narulkar et al. 2008 [10]_), which roughens continuous cuts; no
  source gives that roughness as a function of the cutting conditions.  Continuous
  cutting of a ``diamond_reactive`` material is outside the model (reported in
  ``metrics.json``); ``adhesion_layer_nm`` (a blunted edge) and ``adhesion_roughness_nm``
  (grooves along the cut) take a user's own measurement, applied as given.
* **Contact ratio** eta of 1-D vibration cutting, y = v t + A cos(2 pi f t): the fraction of
  time the tool advances into fresh material (:func:`contact_ratio`, exact;
  ~ sqrt(v / (pi A 2 pi f)) when v << 2 pi f A).  Reported; it scales nothing, since no
  source relates it to the surface left.

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
.. [6] Y.-T. Cheng, C.-M. Cheng, "Relationships between hardness, elastic modulus, and the
       work of indentation," Applied Physics Letters 73, 614 (1998).
.. [7] L. K. Gillespie, P. T. Blotter, "The formation and properties of machining burrs,"
       Journal of Engineering for Industry 98(1), 66 (1976).
.. [8] M. Hashimura, Y. P. Chang, D. Dornfeld, "Analysis of burr formation mechanism in
       orthogonal cutting," Journal of Manufacturing Science and Engineering 121(1), 1-7
       (1999). :DOI:`10.1115/1.2830569`
.. [9] E. Paul, C. J. Evans, A. Mangamelli, M. L. McGlauflin, R. S. Polvani, "Chemical
       aspects of tool wear in single point diamond turning," Precision Engineering 18(1),
       4-19 (1996). :DOI:`10.1016/0141-6359(95)00019-4`
.. [10] V. Narulkar, S. Bukkapatnam, L. M. Raff, R. Komanduri, Philosophical Magazine 88,
       1259 (2008): molecular dynamics of the graphitisation and wear of diamond cutting
       iron.
.. [11] Material property sheets: Aluminum 6061-T6 (Aluminum Association typical values,
       https://www.glemco.com/capabilities/material-expertise/aluminum-6061-t6/); EN AW-6082
       extruded, T6 (Hydro technical datasheet, EN 755-2); copper C12700 1/2 hard H02
       (Copper Development Association, https://alloys.copper.org/alloy/C12700) and the
       copper tempers H040-H110 (Copper Alliance UK, https://copperalliance.org.uk/
       copper-and-its-alloys/properties/mechanical-properties); OFHC copper C10200
       (https://www.lfa-wire.com/copper-wire-oxygen-free-high-conductivity_c10200.htm);
       electroless nickel (MacDermid Enthone, https://industrial.macdermidenthone.com/
       products-and-applications/electroless-nickel/properties); Uddeholm Mirrax 40
       brochure (edition 1, 11.2011).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

import numpy as np

from ..core.errors import InputError, check_range
from ..core.units import MM_TO_NM, MM_TO_UM, NM_TO_MM, UM_TO_MM

__all__ = ["Material", "MATERIAL_PRESETS", "material_preset", "MaterialResponse",
           "material_response", "contact_ratio", "min_chip_thickness", "elastic_recovery",
           "uncut_chip_thickness", "DIAMOND_E_GPA", "DIAMOND_NU",
           "INDENTER_HALF_ANGLE_DEG", "DUCTILITY_REFERENCE_PERCENT"]

#: diamond's Young's modulus and Poisson's ratio (Oliver & Pharr 1992)
DIAMOND_E_GPA = 1141.0
DIAMOND_NU = 0.07
#: half-angle of the cone with the Berkovich indenter's area function (Oliver & Pharr 1992)
INDENTER_HALF_ANGLE_DEG = 70.3
#: recovered depth of a conical contact per unit (H / E_r) and contact depth: pi tan(theta)
_KAPPA_C = math.pi * math.tan(math.radians(INDENTER_HALF_ANGLE_DEG))
#: elongation at break (%) above which a material counts as fully ductile for burrs
#: (assumed: the 10-17 % of the wrought aluminium alloys, where burrs are fully formed)
DUCTILITY_REFERENCE_PERCENT = 10.0


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
    elongation_percent : float
        Elongation at break (ductility), %: scales the burrs (0 = brittle, no burr).
    burr_coefficient : float
        Burr height per unit uncut chip thickness on a square exit edge of a fully ductile
        material (assumed 1, range 0.5-1.5).
    texture_nm : float
        Sq of the part's own residual roughness (grain boundaries, precipitates).
    texture_length_um : float
        Correlation length of that texture (of the order of the grain size).
    diamond_reactive : bool
        The material wears diamond chemically (iron-bearing alloys): continuous cutting is
        outside the model.
    adhesion_layer_nm, adhesion_roughness_nm : float
        Empirical inputs, 0 in every preset: an adhered layer that blunts the edge, and
        the Sq of the grooves it ploughs along the cut, as a user measured them.
    sources : dict
    """

    name: str
    youngs_modulus_gpa: float
    poisson: float
    hardness_gpa: float
    friction: float
    elongation_percent: float = 10.0
    burr_coefficient: float = 1.0
    texture_nm: float = 0.0
    texture_length_um: float = 30.0
    diamond_reactive: bool = False
    adhesion_layer_nm: float = 0.0
    adhesion_roughness_nm: float = 0.0
    sources: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        check_range("youngs_modulus_gpa", self.youngs_modulus_gpa, 0.0, 2000.0, lo_open=True)
        check_range("poisson", self.poisson, 0.0, 0.5, hi_open=True)
        check_range("hardness_gpa", self.hardness_gpa, 0.0, 100.0, lo_open=True)
        check_range("friction", self.friction, 0.0, 2.0)
        check_range("elongation_percent", self.elongation_percent, 0.0, 100.0)
        check_range("burr_coefficient", self.burr_coefficient, 0.0, 10.0)
        check_range("texture_length_um", self.texture_length_um, 0.0, 1e5, lo_open=True)
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


#: GPa per Vickers (or Knoop) hardness number (kgf/mm^2 -> GPa)
_HV = 9.80665e-3

_FRICTION = ("0.1-0.2 for diamond on metals in ultra-precision cutting (assumed; it enters "
             "h_min only through atan(mu) / 2: 0.1 -> 0.2 changes h_min by 10 %)")
_BURR = ("1 (assumed, range 0.5-1.5): the burr height per unit uncut chip thickness on a "
         "square exit edge; Gillespie & Blotter (1976) and Hashimura, Chang & Dornfeld (1999) "
         "give the proportionality to the uncut chip thickness, no coefficient for diamond "
         "cutting")
_TEXTURE = ("1 nm Sq (assumed, range 0.5-2 nm), correlation 30 um (assumed, 10-100 um, of "
            "the order of the grain size of wrought alloys)")

#: Material presets.  Every number has its source or its assumed range in ``sources``
#: (docs/machine_and_material.md lists them).
MATERIAL_PRESETS = {
    "al6061": Material(
        "al6061", 68.9, 0.33, 107 * _HV, 0.15, elongation_percent=12.0, texture_nm=1.0,
        sources={"youngs_modulus_gpa, hardness_gpa, elongation_percent":
                 "Al 6061-T6, Aluminum Association typical values: E 68.9 GPa, 107 HV "
                 "(converted from 95 HB), elongation at break 12 % (1.6 mm sheet)",
                 "poisson": "0.33 (the same sheet: 'estimated from trends in similar Al "
                            "alloys')",
                 "friction": _FRICTION, "burr_coefficient": _BURR, "texture": _TEXTURE}),
    "al6082": Material(
        "al6082", 70.0, 0.33, 100 * _HV, 0.15, elongation_percent=10.0, texture_nm=1.0,
        sources={"youngs_modulus_gpa": "70 GPa: Li et al. (2018), Table 1",
                 "hardness_gpa, elongation_percent": "EN AW-6082 T6 extruded (Hydro "
                                                     "datasheet after EN 755-2): 100 HV "
                                                     "typical, elongation A 10 %",
                 "poisson": "0.33 (as Al 6061; assumed, 0.32-0.34)",
                 "friction": _FRICTION, "burr_coefficient": _BURR, "texture": _TEXTURE}),
    "ofhc_copper": Material(
        "ofhc_copper", 117.0, 0.34, 95 * _HV, 0.2, elongation_percent=14.0, texture_nm=0.8,
        sources={"youngs_modulus_gpa": "OFHC copper C10200: 17,000 ksi = 117 GPa",
                 "poisson": "0.34 (copper property sheets)",
                 "hardness_gpa": "95 HV, half hard (range 65-110 HV): annealed copper is "
                                 "40-65 HV (H040), fully cold worked >= 110 HV (H110) "
                                 "(Copper Alliance); 1/2 hard H02 high-conductivity copper "
                                 "C12700: Rockwell F 84, 290 MPa (CDA)",
                 "elongation_percent": "14 %: C12700 1/2 hard H02, typical (CDA)",
                 "friction": "0.2 (assumed, 0.1-0.3)", "burr_coefficient": _BURR,
                 "texture": "0.8 nm Sq (assumed, 0.5-2 nm): grain-orientation dependent "
                            "recovery; correlation 30 um (assumed, 10-100 um)"}),
    "nip": Material(
        "nip", 62.0, 0.3, 460 * _HV, 0.1, elongation_percent=1.1, texture_nm=0.5,
        texture_length_um=10.0,
        sources={"youngs_modulus_gpa, hardness_gpa, elongation_percent":
                 "electroless nickel, high phosphorus (10-13 %), as plated: E 55-70 GPa, "
                 "hardness 400-525 HK100, elongation 1-1.25 % (MacDermid Enthone); "
                 "indentation moduli up to ~200 GPa are also reported (not read): a range",
                 "poisson": "0.3 (assumed, 0.28-0.33)",
                 "friction": "0.1 (assumed, 0.05-0.2)", "burr_coefficient": _BURR,
                 "texture": "0.5 nm Sq (assumed, 0.2-1 nm): amorphous, no grains; "
                            "correlation 10 um (assumed)"}),
    "die_steel": Material(
        "die_steel", 200.0, 0.29, 392 * _HV, 0.2, elongation_percent=10.0, texture_nm=1.0,
        diamond_reactive=True,
        sources={"hardness_gpa": "Uddeholm Mirrax 40 (Zhang et al. 2022), pre-hardened to "
                                 "40 HRC (360-400 HB, Uddeholm brochure) ~ 392 HV",
                 "youngs_modulus_gpa, poisson": "200 GPa, 0.29: martensitic stainless "
                                                "(AISI 420 modified; assumed, 190-210 GPa)",
                 "elongation_percent": "10 % (assumed, 5-15 %: the brochure states "
                                       "'excellent ductility and toughness', no number read)",
                 "diamond_reactive": "iron and chromium adhere to and wear diamond "
                                     "chemically (Paul et al. 1996; Zhang et al. 2022 saw Cr "
                                     "and Fe on the tool after conventional sculpturing): "
                                     "continuous cutting is outside the model",
                 "friction": "0.2 (assumed, 0.1-0.3)", "burr_coefficient": _BURR,
                 "texture": _TEXTURE}),
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
    """kappa = pi tan(theta) H / E_r, the recovered depth of a conical contact per unit
    contact depth (see the module docstring), capped at 1."""
    return min(1.0, _KAPPA_C * material.hardness_gpa / material.reduced_modulus_gpa)


def uncut_chip_thickness(feed: float, depth: float, nose_radius: float) -> float:
    """Largest uncut chip thickness of a round-nosed tool turning with ``feed`` per
    revolution at ``depth`` of cut (any one length unit): the chip is a crescent whose
    thickness, measured normal to the edge, peaks at f sin(psi), psi = acos(1 - d / R) the
    angle of the nose in contact, and cannot exceed the depth itself.

    Parameters
    ----------
    feed, depth, nose_radius : float (>= 0, > 0 for the radius)
    """
    check_range("feed", feed, 0.0, None)
    check_range("depth", depth, 0.0, None)
    check_range("nose_radius", nose_radius, 0.0, None, lo_open=True)
    if depth == 0 or feed == 0:
        return 0.0
    c = max(1.0 - depth / nose_radius, -1.0)
    return float(min(feed * math.sqrt(max(1.0 - c * c, 0.0)), depth))


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
    edge_radius_eff : r_e + adhered layer (an empirical input);  contact_ratio : eta;
    groove_rms : rms of the grooves an adhered layer ploughs along the cut (an empirical
    input, 0 in every preset);  texture_rms, texture_length : the part's texture;
    side_flow : True when the displaced material piles at cusps;  burr_height : (1 -
    kappa) h_min, the side-flow ridge where two cuts meet;  burr_coefficient : burr height
    per unit uncut chip thickness on a square exit edge, C min(1, A / A_ref) with A the
    elongation at break;  validity : None, or why the case is outside the model.
    """

    h_min: float
    kappa: float
    edge_radius_eff: float
    contact_ratio: float
    groove_rms: float
    side_flow: bool
    burr_height: float
    material: str
    texture_rms: float = 0.0
    texture_length: float = 0.03
    burr_coefficient: float = 0.0
    validity: str | None = None

    def to_dict(self) -> dict:
        return {"material": self.material, "h_min_nm": self.h_min * MM_TO_NM, "kappa": self.kappa,
                "edge_radius_eff_nm": self.edge_radius_eff * MM_TO_NM,
                "contact_ratio": self.contact_ratio, "groove_rms_nm": self.groove_rms * MM_TO_NM,
                "texture_rms_nm": self.texture_rms * MM_TO_NM,
                "texture_length_um": self.texture_length * MM_TO_UM,
                "side_flow": self.side_flow, "burr_height_nm": self.burr_height * MM_TO_NM,
                "burr_coefficient": self.burr_coefficient, "validity": self.validity}


def material_response(material: Material, *, edge_radius: float = 50e-6,
                      contact_ratio: float = 1.0, side_flow: bool = True) -> MaterialResponse:
    """The cutting-mechanics parameters of ``material`` cut by an edge of radius
    ``edge_radius`` (mm) at contact ratio ``contact_ratio`` (1 = continuous cutting)."""
    check_range("edge_radius", edge_radius, 0.0, 1e-2)
    check_range("contact_ratio", contact_ratio, 0.0, 1.0, lo_open=True)
    eta = float(contact_ratio)
    r_eff = float(edge_radius) + material.adhesion_layer_nm * NM_TO_MM
    h_min = min_chip_thickness(r_eff, material.friction)
    kappa = elastic_recovery(material)
    ductility = min(1.0, material.elongation_percent / DUCTILITY_REFERENCE_PERCENT)
    validity = None
    if material.diamond_reactive and eta >= 1.0:
        validity = (f"continuous cutting of {material.name}, which wears diamond chemically "
                    "(adhesion, graphitisation): the roughness this leaves is outside the model "
                    "(no source relates it to the cutting conditions); the result shows the "
                    "geometry, the edge and the texture only")
    return MaterialResponse(h_min, kappa, r_eff, eta, material.adhesion_roughness_nm * NM_TO_MM,
                            bool(side_flow), (1.0 - kappa) * h_min if side_flow else 0.0,
                            material.name, texture_rms=material.texture_nm * NM_TO_MM,
                            texture_length=material.texture_length_um * UM_TO_MM,
                            burr_coefficient=material.burr_coefficient * ductility,
                            validity=validity)
