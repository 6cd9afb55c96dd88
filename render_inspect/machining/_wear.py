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

The rates (:data:`WEAR_RATES`) are assumed, each with the range it may take: the sources
searched for this model (docs/references.md) describe the mechanisms and say that diamond
wears orders of magnitude faster on iron-bearing alloys than on aluminium, copper or
electroless nickel, but give no rate this model could take as measured.  ``tool.wear_scale``
multiplies them (a key ``fit --free`` can fit).  The speed dependence of the rates is not
modelled (rates per cutting distance).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import ToolPath
from ..core.units import KM_TO_MM, MM_TO_NM, NM_TO_MM, UM_TO_MM

__all__ = ["WearRate", "WEAR_RATES", "wear_rate", "wear_state", "spiral_distance_km", "worn_path",
           "MM_PER_KM"]

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
                          "non-ferrous rates; scales with the contact duty cycle; assumed within the "
                          "range"),
}


def wear_rate(material: str) -> WearRate:
    """The wear rates of the material preset ``material``."""
    if material not in WEAR_RATES:
        raise InputError(f"tool.wear needs a material.preset with wear rates (one of "
                         f"{', '.join(sorted(WEAR_RATES))}), received {material!r}")
    return WEAR_RATES[material]


def wear_state(rate: WearRate, distance_km, *, duty: float = 1.0, scale: float = 1.0,
               edge_radius_nm: float = 50.0, clearance_deg: float = 10.0) -> dict:
    """The worn edge after ``distance_km`` of cutting (arrays allowed): ``contact_km`` (the
    distance that wears it), ``flank_um``, ``edge_radius_nm``, ``recession_nm``."""
    L = np.asarray(distance_km, dtype=np.float64)
    Lc = L * (float(duty) if rate.chemical else 1.0)
    vb = float(scale) * rate.flank_um_per_km * Lc
    re = float(edge_radius_nm) + float(scale) * rate.edge_nm_per_km * Lc
    rec = vb * UM_TO_MM * math.tan(math.radians(clearance_deg)) * MM_TO_NM
    return {"contact_km": Lc, "flank_um": vb, "edge_radius_nm": re, "recession_nm": rec}


def spiral_distance_km(r, workpiece_radius: float, feed_per_rev: float):
    """Cutting distance (km) of a facing spiral from ``workpiece_radius`` in to radius r
    (mm): the area turned over the feed, pi (Rw^2 - r^2) / f."""
    r = np.minimum(np.abs(np.asarray(r, dtype=np.float64)), workpiece_radius)
    return math.pi * (workpiece_radius ** 2 - r ** 2) / float(feed_per_rev) / MM_PER_KM


def worn_path(path, rate: WearRate, *, workpiece_radius: float, feed_per_rev: float, duty: float = 1.0,
              scale: float = 1.0, edge_radius_nm: float = 50.0, clearance_deg: float = 10.0):
    """(The path the worn edge cuts: each point lifted by the recession of the edge worn
    over the cutting distance to that point, the recession (mm) at the points)."""
    L = spiral_distance_km(path.rho, workpiece_radius, feed_per_rev)
    st = wear_state(rate, L, duty=duty, scale=scale, edge_radius_nm=edge_radius_nm, clearance_deg=clearance_deg)
    lift = st["recession_nm"] * NM_TO_MM
    meta = dict(getattr(path, "meta", {}) or {})
    return ToolPath(path.theta, path.rho, np.asarray(path.z) + lift, path.t, meta), lift
