"""Levelling measured maps the way instrument software does: an interferometer measures
heights relative to its own reference, so a measured map (or the difference of two
measurements, or a measurement minus the design) carries an unknown piston, and the
part's set-up an unknown tilt.  Both are fitted over the valid pixels and removed, and
what was removed is said.

Phase shifting adds one more unknown: the fringe order.  Heights are known modulo half
the effective wavelength (``lambda_eff / 2``) between regions that do not touch; the
largest region is levelled and each other region is moved by the whole number of
``lambda_eff / 2`` that brings it nearest the largest one's plane (the orders are
reported, and a map with such regions says so).  Arrays in (mm), numbers out.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from ..core.lazy import lazy_module

from ..core.errors import InputError
from ..core.units import MM_TO_NM, RAD_TO_URAD

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["FORM_TERMS", "level_map", "measured_difference"]

#: What :func:`level_map` removes: "piston" or "piston and tilt".
FORM_TERMS = ("piston", "piston and tilt")


def _regions(valid: np.ndarray, labels: np.ndarray | None) -> np.ndarray:
    if labels is None:
        lab, _ = ndimage.label(valid)
    else:
        lab = np.where(valid, np.asarray(labels), 0)
    return lab


def level_map(z: np.ndarray, *, pixel: float, labels: np.ndarray | None = None,
              terms: str = "piston and tilt",
              fringe_order_mm: float | None = None) -> tuple[np.ndarray, dict]:
    """Remove the piston (and tilt) of a map fitted over its largest region.

    Parameters
    ----------
    z : (ny, nx) array, mm (NaN = not measured)
    pixel : float, mm
    labels : (ny, nx) int, optional
        Connected regions (0 = none); default the connected valid pixels.
    terms : {"piston", "piston and tilt"}
    fringe_order_mm : float, optional
        ``lambda_eff / 2`` of a phase-shifting measurement: each region other than the
        largest is moved by the whole number of fringe orders nearest to the largest
        region's plane.

    Returns
    -------
    levelled : (ny, nx) float64, mm (NaN where ``z`` is)
    info : dict
        ``removed`` (``terms``), ``piston_nm``, ``tilt_x_urad`` and ``tilt_y_urad`` (the
        plane removed: height at the map's centre and its slopes), ``regions``,
        ``fringe_order_nm`` and ``reordered`` (per moved region: ``pixels``, ``orders``).
    """
    if terms not in FORM_TERMS:
        raise InputError(f"terms must be one of {FORM_TERMS}, got {terms!r}")
    z = np.asarray(z, dtype=np.float64)
    valid = np.isfinite(z)
    lab = _regions(valid, labels)
    info: dict[str, Any] = {"removed": terms, "piston_nm": None, "tilt_x_urad": None, "tilt_y_urad": None,
            "regions": 0, "fringe_order_nm": None if fringe_order_mm is None
            else float(fringe_order_mm) * MM_TO_NM, "reordered": []}
    out = np.full(z.shape, np.nan)
    ids, counts = np.unique(lab[lab > 0], return_counts=True)
    if ids.size == 0:
        return out, info
    info["regions"] = int(ids.size)
    main = lab == ids[np.argmax(counts)]
    ny, nx = z.shape
    y, x = np.mgrid[0:ny, 0:nx]
    xc, yc = x - (nx - 1) / 2, y - (ny - 1) / 2
    if terms == "piston" or main.sum() < 3:
        coef = np.array([float(np.mean(z[main])), 0.0, 0.0])
    else:
        a = np.stack([np.ones(int(main.sum())), xc[main], yc[main]], axis=1)
        coef = np.linalg.lstsq(a, z[main], rcond=None)[0]
    plane = coef[0] + coef[1] * xc + coef[2] * yc
    res = z - plane
    out[main] = res[main]
    for i in ids:
        sel = lab == i
        if i == ids[np.argmax(counts)]:
            continue
        shift = 0.0
        if fringe_order_mm:
            k = int(np.round(float(np.median(res[sel])) / fringe_order_mm))
            shift = k * fringe_order_mm
            if k:
                info["reordered"].append({"pixels": int(sel.sum()), "orders": k})
        out[sel] = res[sel] - shift
    info.update(piston_nm=float(coef[0]) * MM_TO_NM,
                tilt_x_urad=float(coef[1] / pixel) * RAD_TO_URAD,
                tilt_y_urad=float(coef[2] / pixel) * RAD_TO_URAD)
    return out, info


def measured_difference(a: np.ndarray, b: np.ndarray, *, pixel: float,
                        labels_a: np.ndarray | None = None, labels_b: np.ndarray | None = None,
                        terms: str = "piston and tilt",
                        fringe_order_mm: float | None = None) -> tuple[np.ndarray, dict]:
    """The difference of two measurements on one camera grid, as instrument software
    forms it: ``a - b`` where both were measured, with its piston (and tilt) removed
    (:func:`level_map`; the regions are those where both maps' regions overlap).

    Returns
    -------
    levelled : (ny, nx) float64, mm
    info : dict
        :func:`level_map`'s, with ``pixels`` (where both were measured).
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape != b.shape:
        raise InputError(f"the two measurements must share one grid, got shapes {a.shape} "
                         f"and {b.shape}")
    d = a - b
    both = np.isfinite(d)
    labels = None
    if labels_a is not None and labels_b is not None:
        la, lb = np.asarray(labels_a, np.int64), np.asarray(labels_b, np.int64)
        pair = np.where(both & (la > 0) & (lb > 0), la * (int(lb.max()) + 1) + lb, 0)
        _, inv = np.unique(pair, return_inverse=True)
        labels = np.where(pair > 0, inv.reshape(pair.shape) + 1, 0)
        # regions of one label pair that do not touch are separate regions
        lab2 = np.zeros(pair.shape, dtype=np.int64)
        nxt = 0
        for v in np.unique(labels[labels > 0]):
            sub, n = ndimage.label(labels == v)
            lab2[sub > 0] = sub[sub > 0] + nxt
            nxt += n
        labels = lab2
    out, info = level_map(np.where(both, d, np.nan), pixel=pixel, labels=labels, terms=terms,
                          fringe_order_mm=fringe_order_mm)
    info["pixels"] = int(both.sum())
    return out, info

