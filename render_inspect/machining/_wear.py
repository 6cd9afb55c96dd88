"""Wear of the diamond along the cut: flank wear and edge radius against the cutting
distance, and the worn edge at each point of a turning path.

Model (steady-state wear, the running-in of a fresh edge left out):

- the flank wear land grows linearly with the cutting distance the edge spends in contact,
  VB = k_VB L_c, and the cutting-edge radius with it, r_e = r_e0 + k_r L_c;
- L_c is the cutting distance L for mechanical (abrasive) wear, and D L for the chemical
  wear of diamond by iron-bearing alloys, which grows with the time the edge spends in hot
  contact (Paul et al. 1996): vibration cutting cuts that time to the contact duty cycle D
  (Shamoto & Moriwaki 1994);
- a flank wear land VB on a tool of clearance angle alpha moves the cutting edge back from
  the part by VB tan(alpha) (the geometry of the land): the nose recedes, the part is left
  that much high along the normal (in Z: divided by cos(theta) at the contact angle theta;
  the path here is lifted by the recession itself, exact on flat sections and within
  1 - cos(theta) of it on slopes);
- on a facing spiral of feed f per revolution from the outer radius Rw inwards, the
  cutting distance to radius r is the area turned over the feed, L = pi (Rw^2 - r^2) / f.

Chemical wear and the cutting speed (:class:`SpeedLaw`, :func:`speed_factor`): the chemical
wear per unit time in contact is taken as Arrhenius in the contact temperature (Evans 1991:
the rate of the chemical reactions that wear diamond on iron grows exponentially with the
temperature; Zhou & Zou 2013 measured the graphitised fraction of diamond rubbed on steel
rising to 83 % for a 15 % rise in temperature), the temperature rise over ambient grows as
the square root of the cutting speed (a fast-moving heat source), and the time in contact
per unit cutting distance is D / v.  The rates per km hold at the reference speed v_ref;
at the speed v they are multiplied by

    g(v) = (v_ref / v) exp(-(Q / R) (1 / T(v) - 1 / T(v_ref))),  T(v) = T0 + dT_ref sqrt(v / v_ref).

On a facing spiral at n rpm the speed falls with the radius (v = 2 pi r n): the distance that
wears the edge to radius r is the integral of g(v(r')) over the cut from the outside in
(:func:`chemical_distance_km`).  The vibration's duty cycle D still divides the time in
contact; the contact temperature is set by the nominal cutting speed with and without the
vibration (an upper bound: the short contacts of vibration cutting heat the edge less).

The rates (:data:`WEAR_RATES`) and the speed law's constants (:data:`SPEED_LAW`) are
assumed, each with the range it may take (:data:`SOURCES` lists what the sources searched
for this model give): they describe the mechanisms, the temperature dependence and the
reduction of the wear by vibration cutting, but no source at hand gives a measured rate per
cutting distance for diamond on any of the material presets.  ``tool.wear_scale``
multiplies them (a key ``fit --free`` can fit).
"""

from __future__ import annotations

from typing import Any
import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import ToolPath
from ..core.units import KM_TO_MM, M_TO_MM, MM_TO_M, MM_TO_NM, NM_TO_MM, UM_TO_MM

__all__ = ["WearRate", "WEAR_RATES", "wear_rate", "wear_state", "spiral_distance_km", "worn_path",
           "MM_PER_KM", "SpeedLaw", "SPEED_LAW", "speed_factor", "chemical_distance_km", "SOURCES"]

#: millimetres per kilometre
MM_PER_KM = KM_TO_MM


@dataclass(frozen=True)
class WearRate:
    """Wear rates of a diamond on one material (per km of cutting in contact).

    Attributes
    ----------
    flank_um_per_km, edge_nm_per_km : float
        Growth of the flank wear land VB (um) and of the edge radius (nm).
    flank_range, edge_range : (lo, hi)
        The range each may take (the rates are assumed).
    chemical : bool
        Chemical wear (iron-bearing alloys): it scales with the contact duty cycle.
    basis : str
        "A" (assumed, with its range) or "S" (sourced).
    note : str
    """

    flank_um_per_km: float
    flank_range: tuple
    edge_nm_per_km: float
    edge_range: tuple
    chemical: bool
    basis: str
    note: str

    def to_dict(self) -> dict:
        return {"flank_um_per_km": self.flank_um_per_km, "flank_range_um_per_km": list(self.flank_range),
                "edge_nm_per_km": self.edge_nm_per_km, "edge_range_nm_per_km": list(self.edge_range),
                "chemical": self.chemical, "basis": self.basis, "note": self.note}


_MECH = "mechanical (abrasive) wear; assumed within the range (no measured rate in the sources searched)"
#: the rates by material preset (docs/machine_and_material.md, "Tool wear along the cut")
WEAR_RATES = {
    "al6061": WearRate(0.05, (0.005, 0.5), 0.5, (0.05, 5.0), False, "A", _MECH),
    "al6082": WearRate(0.05, (0.005, 0.5), 0.5, (0.05, 5.0), False, "A", _MECH),
    "ofhc_copper": WearRate(0.05, (0.005, 0.5), 0.5, (0.05, 5.0), False, "A", _MECH),
    "nip": WearRate(0.2, (0.02, 2.0), 2.0, (0.2, 20.0), False, "A",
                    "abrasive wear, faster than on aluminium and copper; assumed within the range"),
    "die_steel": WearRate(50.0, (5.0, 500.0), 200.0, (20.0, 2000.0), True, "A",
                          "chemical wear by iron (Paul et al. 1996), orders of magnitude above the "
                          "non-ferrous rates; at 100 m/min (the speed law's reference), scaled by the "
                          "contact duty cycle and the speed law; assumed within the range"),
}


#: what the sources searched for this model give on diamond wear (docs/machine_and_material.md,
#: "Tool wear along the cut", lists the search): none reachable gives a rate per cutting
#: distance, or a wear land or edge radius after a stated distance, on a material preset
SOURCES = {
    "evans1991": "C. Evans, Cryogenic diamond turning of stainless steel, CIRP Annals (1991): "
                 "diamond wear on ferrous metals is extremely rapid, by fracture and chemical "
                 "mechanisms; the rate of the chemical reactions grows exponentially with the "
                 "temperature; 35 mm 400-series stainless flats turned at cryogenic temperature "
                 "to Ra < 25 nm (no wear rate in the text read)",
    "zhou2013": "Zhou M., Zou L., Tool wear mechanism of diamond cutting of ferrous metals in "
                "frictional wear experiments, Optics and Precision Engineering 21(7) (2013) 1786, "
                "doi:10.3788/OPE.20132107.1786: diamond rubbed on steel wears mainly by "
                "graphitisation; the wear depends strongly on the force and the temperature, "
                "less on the sliding speed; the graphitised fraction rises to 83 % with a 15 % "
                "rise in temperature",
    "zhang2022": "the sculpturing paper (docs/sculpturing.md), Mirrax 40 at 100 mm/min: after "
                 "conventional sculpturing the edge shows Fe and Cr adhered and a considerable "
                 "wear land, after 104 kHz vibration sculpturing no apparent wear or adhesion; "
                 "the first conventional lenslet was already rough ('tool wear was not the main "
                 "reason'); no wear land width is given",
    "mild_steel": "The wear of diamond tools turning mild steel (abstract): the wear arises from "
                  "the degeneration of diamond to graphite, and different diamonds wear at much "
                  "different rates (the scatter between tools is large)",
    "d_electrons": "Proc. IMechE B (2022), doi:10.1177/09544054221099268 (abstract): the unpaired "
                   "d electrons of iron are regarded as the main cause of the catastrophic wear "
                   "of diamond on ferrous metals; a magnetic field reduced the flank wear of "
                   "PCD tools by 30.6 %",
    "uevt_4140": "Proc. IMechE B (2020), doi:10.1177/0954405420929782, AISI 4140 hardened steel "
                 "(the tool is not named in the abstract): ultrasonic vibration at 13 um, "
                 "180 mm/s, 0.09 mm/rev reduced the maximum flank wear by 30.3 % (1-D) and "
                 "54.3 % (elliptical), 39.3 % at 5 um (elliptical)",
    "lane2010": "B. M. Lane, M. Shi, T. A. Dow, R. Scattergood, Diamond tool wear when machining "
                "Al6061 and 1215 steel, Wear 268 (2010) 1434-1441, doi:10.1016/j.wear.2010.02.019 "
                "(abstract): the edge radius and the wear land were measured against the cutting "
                "distance in orthogonal cutting of 6061 aluminium (abrasive wear) and 1215 steel "
                "(abrasive plus chemical wear); the numbers are in the paper's figures, not in "
                "the abstract, and the text was not reachable: the one source found that would "
                "calibrate al6061 and the chemical rate",
    "al_mirror1985": "Research on diamond turning of large optical metal mirrors: characteristics "
                     "of single crystal diamond tools (1985, abstract): aluminium alloy, 2 mm and "
                     "10 mm nose radius; the thrust force rises as the edge blunts, and the "
                     "roughness is 'still good even after the cutting distance has reached "
                     "900 km'; no wear width or edge radius given",
    "al_mg_jspe": "J. JSPE 55(9), natural diamonds of five colours turning an Al-Mg alloy "
                 "(abstract): 'the tool wear increases with cutting distance'; the wear rates of "
                 "brown and yellow tools are 'almost same in the stationary state after some "
                 "primary tool wear' (the steady-state linear law of this model, the running-in "
                 "left out); no rate given",
    "rsa905": "K. Abou-El-Hossein, O. Olufayo, Z. Mkoko, Diamond tool wear during ultra-high "
              "precision machining of rapidly solidified aluminium RSA 905 (2013; a fine-grained "
              "6061) at 2000 rpm and 25 um "
              "depth (abstract): 'tool wear is absolutely low even after relatively high "
              "cutting distances', most intensive at the middle feed; no number in the abstract",
    "nitrided_steel": "Tool wear study in diamond turning of steels, J. Vac. Sci. Technol. B "
                      "27(3) (2009) 1335 (abstract): nitriding the steel reduced the tool wear "
                      "'by two to three orders of magnitudes', Ra 4.2-20 nm; a ratio against "
                      "untreated steel, not a rate",
    "henry2002": "S. W. Henry, Instrumentation for tool wear evaluation, MS thesis, Pennsylvania "
                 "State University (2002): two stylus instruments that profile the edge of a "
                 "round-nosed diamond tool before and after machining; only the title pages "
                 "and the start of the abstract were reachable, no wear numbers",
}


@dataclass(frozen=True)
class SpeedLaw:
    """The cutting-speed dependence of the chemical wear (assumed constants, each with its
    range): the rates hold at ``v_ref_m_min``; the contact temperature is ``ambient_K`` +
    ``rise_ref_K`` sqrt(v / v_ref); the wear per unit time in contact is Arrhenius with the
    activation energy ``activation_kj_mol``."""

    v_ref_m_min: float = 100.0
    rise_ref_K: float = 300.0
    rise_range_K: tuple = (100.0, 600.0)
    activation_kj_mol: float = 100.0
    activation_range_kj_mol: tuple = (50.0, 200.0)
    ambient_K: float = 293.15

    def to_dict(self) -> dict:
        return {"v_ref_m_min": self.v_ref_m_min, "rise_ref_K": self.rise_ref_K,
                "rise_range_K": list(self.rise_range_K), "activation_kj_mol": self.activation_kj_mol,
                "activation_range_kj_mol": list(self.activation_range_kj_mol),
                "ambient_K": self.ambient_K, "basis": "A"}


#: the speed law of the chemical wear (all assumed)
SPEED_LAW = SpeedLaw()
_R_GAS = 8.314462618e-3  # kJ / (mol K)


def _arrhenius(v_m_min, law: SpeedLaw):
    v = np.maximum(np.asarray(v_m_min, dtype=np.float64), 0.0)
    T = law.ambient_K + law.rise_ref_K * np.sqrt(v / law.v_ref_m_min)
    T_ref = law.ambient_K + law.rise_ref_K
    return np.exp(-(law.activation_kj_mol / _R_GAS) * (1.0 / T - 1.0 / T_ref))


def speed_factor(v_m_min: np.ndarray | float, law: SpeedLaw = SPEED_LAW) -> np.ndarray | float:
    """The factor on the chemical wear per km at the cutting speed ``v_m_min`` (m/min)
    against the reference speed: (v_ref / v) exp(-(Q/R) (1/T(v) - 1/T(v_ref))), the time in
    contact per km times the Arrhenius rate at the contact temperature; 1 at v_ref."""
    v = np.asarray(v_m_min, dtype=np.float64)
    if np.any(~np.isfinite(v)) or np.any(v <= 0):
        raise InputError(f"the cutting speed for the chemical wear must be > 0 m/min, received "
                         f"{np.min(v) if v.size else v!r}")
    return law.v_ref_m_min / v * _arrhenius(v, law)


def chemical_distance_km(r: np.ndarray | float, workpiece_radius: float, feed_per_rev: float,
                         spindle_rpm: float,
                         law: SpeedLaw = SPEED_LAW, samples: int = 4097) -> Any:
    """The cutting distance (km, at the reference speed) that wears the edge chemically to
    radius r (mm) of a facing spiral from ``workpiece_radius`` inwards at ``spindle_rpm``:
    the integral of speed_factor(2 pi r' n) over the cut, (v_ref / (n f)) times the Arrhenius
    factor integrated over the radius (finite at the axis, where the speed vanishes)."""
    if not spindle_rpm > 0:
        raise InputError(f"process.spindle_rpm must be > 0 for the chemical wear, received {spindle_rpm!r}")
    Rw = float(workpiece_radius)
    rr = np.linspace(0.0, Rw, int(samples))
    v = 2 * math.pi * rr * float(spindle_rpm) * MM_TO_M  # m/min
    dens = law.v_ref_m_min * M_TO_MM / (float(spindle_rpm) * float(feed_per_rev)) * _arrhenius(v, law)
    # cumulative from the outside in: C(r) = int_r^Rw dens dr'
    seg = 0.5 * (dens[1:] + dens[:-1]) * np.diff(rr)
    C = np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])
    r = np.minimum(np.abs(np.asarray(r, dtype=np.float64)), Rw)
    return np.interp(r, rr, C) / MM_PER_KM


def wear_rate(material: str) -> WearRate:
    """The wear rates of the material preset ``material``."""
    if material not in WEAR_RATES:
        raise InputError(f"tool.wear needs a material.preset with wear rates (one of "
                         f"{', '.join(sorted(WEAR_RATES))}), received {material!r}")
    return WEAR_RATES[material]


def wear_state(rate: WearRate, distance_km: np.ndarray | float, *, duty: float = 1.0,
               scale: float = 1.0,
               edge_radius_nm: float = 50.0, clearance_deg: float = 10.0,
               speed_m_min: np.ndarray | float | None = None,
               chemical_km: np.ndarray | float | None = None, law: SpeedLaw = SPEED_LAW) -> dict:
    """The worn edge after ``distance_km`` of cutting (arrays allowed): ``contact_km`` (the
    distance that wears it), ``flank_um``, ``edge_radius_nm``, ``recession_nm``.

    Chemical wear (iron-bearing alloys) takes the duty cycle and the cutting speed: at the
    constant speed ``speed_m_min`` the distance is multiplied by :func:`speed_factor`;
    ``chemical_km`` gives the speed-weighted distance itself (a spiral whose speed varies,
    :func:`chemical_distance_km`); with neither the rates hold as at the reference speed."""
    L = np.asarray(distance_km, dtype=np.float64)
    if rate.chemical:
        if chemical_km is not None:
            L = np.asarray(chemical_km, dtype=np.float64)
        elif speed_m_min is not None:
            L = L * speed_factor(speed_m_min, law)
        Lc = L * float(duty)
    else:
        Lc = L
    vb = float(scale) * rate.flank_um_per_km * Lc
    re = float(edge_radius_nm) + float(scale) * rate.edge_nm_per_km * Lc
    rec = vb * UM_TO_MM * math.tan(math.radians(clearance_deg)) * MM_TO_NM
    return {"contact_km": Lc, "flank_um": vb, "edge_radius_nm": re, "recession_nm": rec}


def spiral_distance_km(r: np.ndarray | float, workpiece_radius: float, feed_per_rev: float) -> Any:
    """Cutting distance (km) of a facing spiral from ``workpiece_radius`` in to radius r
    (mm): the area turned over the feed, pi (Rw^2 - r^2) / f."""
    r = np.minimum(np.abs(np.asarray(r, dtype=np.float64)), workpiece_radius)
    return math.pi * (workpiece_radius ** 2 - r ** 2) / float(feed_per_rev) / MM_PER_KM


def worn_path(path: ToolPath, rate: WearRate, *, workpiece_radius: float, feed_per_rev: float,
              duty: float = 1.0,
              scale: float = 1.0, edge_radius_nm: float = 50.0, clearance_deg: float = 10.0,
              spindle_rpm: float | None = None,
              law: SpeedLaw = SPEED_LAW) -> tuple[ToolPath, np.ndarray]:
    """(The path the worn edge cuts: each point lifted by the recession of the edge worn
    over the cutting distance to that point, the recession (mm) at the points).  With
    ``spindle_rpm`` the chemical wear follows the cutting speed along the spiral."""
    L = spiral_distance_km(path.rho, workpiece_radius, feed_per_rev)
    chem = (chemical_distance_km(path.rho, workpiece_radius, feed_per_rev, spindle_rpm, law)
            if rate.chemical and spindle_rpm is not None else None)
    st = wear_state(rate, L, duty=duty, scale=scale, edge_radius_nm=edge_radius_nm, clearance_deg=clearance_deg,
                    chemical_km=chem, law=law)
    lift = st["recession_nm"] * NM_TO_MM
    meta = dict(getattr(path, "meta", {}) or {})
    return ToolPath(path.theta, path.rho, np.asarray(path.z) + lift, path.t, meta), lift
