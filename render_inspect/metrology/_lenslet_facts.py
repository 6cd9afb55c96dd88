"""The lenslet facts of a simulated map: the ``lenslets`` table of a lenslet design, and
Kong et al. 2020's characterisation of a microstructure array on a base.  What the design
is made of is read from the design surface itself (its ``centers``, ``base``,
``feature``)."""

from __future__ import annotations

from typing import Any
import warnings

import numpy as np

from ._msa import characterise_msa, lenslet_table
from ..core.heightmap import HeightMap

__all__ = ["lenslet_metrics", "msa_metrics", "lenslet_facts"]


def _base_grid(base, heightmap) -> np.ndarray:
    """The base surface on the map's grid (row 0 = smallest y)."""
    x = np.asarray(heightmap.x, dtype=np.float64)
    y = np.asarray(heightmap.y, dtype=np.float64)
    return np.asarray(base.height(x[None, :], y[:, None]), dtype=np.float64)


def lenslet_metrics(surface: Any, heightmap: HeightMap) -> list | None:
    """The ``lenslets`` table (fitted centres, dislocations, form errors) of a lenslet
    design, or None when the design has no lenslets.

    A compound design whose feature is the lenslet array (a microstructure on a freeform
    base, Kong et al. 2020) is evaluated on the machined map minus the base; a plain array
    or lenslet rings on the machined map.  Lenslets cut by the simulated window are left
    out.
    """
    feature = getattr(surface, "feature", None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # lenslets cut by the window's border are left out
        if feature is not None and hasattr(surface, "base"):
            if not hasattr(feature, "centers"):
                return None
            base = _base_grid(surface.base, heightmap)
            return lenslet_table((heightmap.machined - base, heightmap.pixel,
                                  tuple(heightmap.origin)), feature,
                                 aperture_radius=getattr(feature, "aperture_radius", None))
        if hasattr(surface, "centers"):
            return lenslet_table(heightmap, surface, which="machined")
    return None


def msa_metrics(surface: Any, heightmap: HeightMap,
                metrology: Any = None) -> tuple[list, dict] | None:
    """Kong et al. 2020's characterisation of a lenslet array on a base (a compound design
    whose feature is the array): outliers, 6-DOF registration of the design to the
    machined map (base first, then all data), separation, per-lenslet fits against the
    registered design, base form error (:func:`characterise_msa`, with the scene's
    ``[metrology]`` settings).  Returns (``lenslets`` table, ``msa`` facts: registration,
    base form error, outlier count, summary), or None for other designs.  What a rigid
    set-up (or a constant servo lag) does is registered away; what is left are the
    dislocations that survive registration."""
    feature = getattr(surface, "feature", None)
    if feature is None or not hasattr(surface, "base") or not hasattr(feature, "centers"):
        return None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # lenslets cut by the window's border are left out
        res = characterise_msa(heightmap.machined, surface, pixel=heightmap.pixel,
                               origin=tuple(heightmap.origin),
                               aperture_radius=getattr(feature, "aperture_radius", None),
                               metrology=metrology)
    reg = res["registration"]
    msa = {"registration": None if reg is None else
           {k: reg[k] for k in ("tx_mm", "ty_mm", "tz_mm", "alpha_rad", "beta_rad", "gamma_rad",
                                "rms_mm", "n_points") if k in reg},
           "base_form_error": res["base"], "outliers": res["outliers"], "summary": res["summary"]}
    return res["lenslets"], msa


def lenslet_facts(surface: Any, heightmap: HeightMap,
                  metrology: Any) -> tuple[list | None, dict | None]:
    """(``lenslets``, ``msa``) of a simulated map: the registered characterisation of an
    array on a base when ``metrology.registration`` asks for one, else the plain table."""
    if metrology.registration != "none":
        res = msa_metrics(surface, heightmap, metrology)
        if res is not None:
            return res
    return lenslet_metrics(surface, heightmap), None
