"""Microstructure arrays (MSA) on a base: separation, lenslet centres, dislocations and
per-lenslet form errors (Kong et al. 2020 [1]_, steps 4-5; the quadrilateral MLA of Zhang et
al. 2022 [2]_).

Lateral positions: Kong et al. (2020) take each lenslet's lowest point in its pitch cell,
which is pixel-quantised.  Here each lenslet's centre is fitted by least squares inside
``inner`` x aperture (0.95): the measured heights are matched to the (registered) design
shifted by (dx, dy) plus a piston dz.  For a spherical lenslet this is the least-squares
fit of the sphere's centre with the design radius, and it is sub-pixel accurate; the base
under the lenslet is taken from the design, so a sloped base does not bias the centre.

References
----------
.. [1] L. Kong, Y. Ma, M. Ren, M. Xu, C.-F. Cheung, "Generation and characterization of
       ultra-precision compound freeform surfaces," Science Progress 103(1), 1-12 (2020).
       :DOI:`10.1177/0036850419880112`
.. [2] C. Zhang, C.-F. Cheung, X. Liang, B. Bulla, "A theoretical and experimental
       investigation of high-frequency ultrasonic vibration-assisted sculpturing of
       optical microstructures," Applied Sciences 12(21), 10937 (2022).
"""

from __future__ import annotations

from typing import Any, Protocol
from collections.abc import Sequence
import warnings

import numpy as np
import numpy.typing as npt
from ..core.lazy import lazy_attr
from ..core.heightmap import HeightMap

from ..core.errors import InputError, check_positive
from ..core.units import MM_TO_UM
from ._filters import valid_mask
from ._registration import MovedSurface, detect_outliers, register_lsq

#: SciPy, imported on first use (render_inspect.core.lazy)
least_squares = lazy_attr("scipy.optimize", "least_squares")

__all__ = ["LENSLET_KEYS", "lenslet_centers", "separate_msa", "lenslet_table", "base_form_error",
           "characterise_msa"]

LENSLET_KEYS = ("row", "col", "x_mm", "y_mm", "dx_um", "dy_um", "Sa_um", "Sq_um", "PV_um")


def _unpack(data, which, pixel, origin):
    """(z, pixel, origin) from a HeightMap, a SimulationResult-like object, a tuple or an array."""
    if hasattr(data, "heightmap") and not hasattr(data, "machined"):
        data = data.heightmap
    if hasattr(data, "machined") and hasattr(data, "pixel"):
        if which not in ("machined", "design"):
            raise InputError(f"which must be 'machined' or 'design', got {which!r}")
        return np.asarray(getattr(data, which), float), float(data.pixel), tuple(data.origin)
    if isinstance(data, tuple) and len(data) == 3:
        z, p, o = data
        return np.asarray(z, float), float(p), tuple(o)
    if pixel is None:
        raise InputError("lenslet analysis of a bare array needs pixel= (mm) and origin= (mm)")
    return np.asarray(data, float), float(pixel), tuple(origin or (0.0, 0.0))


def lenslet_centers(design: Any,
                    centers: Sequence[Sequence[float]] | None = None) -> list[tuple[int, int, float, float]]:
    """Designed lenslet centres as ``(row, col, x_mm, y_mm)``: ``centers`` if given, else
    ``design.centers()`` (the :class:`~render_inspect.design.LensletArray` interface)."""
    if centers is None:
        if not hasattr(design, "centers"):
            raise InputError("the design has no centers(); pass centers=[(row, col, x_mm, y_mm), ...]")
        centers = design.centers()
    out = []
    for c in centers:
        if len(c) != 4:
            raise InputError(f"each centre must be (row, col, x_mm, y_mm), got {c!r}")
        out.append((int(c[0]), int(c[1]), float(c[2]), float(c[3])))
    if not out:
        raise InputError("the design has no lenslets (centers is empty)")
    return out


def _attr(design, name, default=None):
    """``design.name``, else ``design.feature.name`` (a lenslet array on a base, Compound)."""
    v = getattr(design, name, None)
    if v is None and getattr(design, "feature", None) is not None:
        v = getattr(design.feature, name, None)
    return default if v is None else v


def _aperture(design, aperture_radius):
    if aperture_radius is None:
        aperture_radius = _attr(design, "aperture_radius")
    if aperture_radius is None:
        px, py = _attr(design, "pitch_x"), _attr(design, "pitch_y")
        if px is None or py is None:
            raise InputError("pass aperture_radius= (mm): the design gives neither aperture_radius "
                             "nor pitch_x/pitch_y")
        aperture_radius = 0.5 * min(px, py)
    check_positive("aperture_radius", aperture_radius)
    return float(aperture_radius)


def separate_msa(shape: tuple[int, ...], centers: Sequence[Sequence[float]], *, pixel: float,
                 origin: Sequence[float] = (0.0, 0.0), aperture_radius: float,
                 inner: float = 0.95, outer: float = 1.05
                 ) -> tuple[npt.NDArray[np.bool_], npt.NDArray[np.bool_], npt.NDArray[np.int64]]:
    """Masks separating MSA data from base data (Kong et al. 2020, step 4).

    Returns
    -------
    msa : (ny, nx) bool
        Within ``inner * aperture_radius`` of some centre.
    base : (ny, nx) bool
        Farther than ``outer * aperture_radius`` from every centre.
    label : (ny, nx) int
        Index into ``centers`` of the lenslet a MSA point belongs to, -1 elsewhere.
    """
    check_positive("pixel", pixel)
    if not 0 < inner <= 1.0 <= outer:
        raise InputError(f"need 0 < inner <= 1 <= outer, got inner={inner}, outer={outer}")
    ny, nx = shape
    x = origin[0] + pixel * np.arange(nx)
    y = origin[1] + pixel * np.arange(ny)
    xx, yy = np.meshgrid(x, y)
    dmin = np.full(shape, np.inf)
    label = np.full(shape, -1, dtype=np.int64)
    for k, c in enumerate(centers):
        d = np.hypot(xx - c[-2], yy - c[-1])
        closer = d < dmin
        dmin = np.where(closer, d, dmin)
        label = np.where(closer, k, label)
    msa = dmin <= inner * aperture_radius
    base = dmin > outer * aperture_radius
    return msa, base, np.where(msa, label, -1)


def _stats_um(r):
    r = r - r.mean()
    return {"Sa_um": float(np.mean(np.abs(r)) * MM_TO_UM),
            "Sq_um": float(np.sqrt(np.mean(r * r)) * MM_TO_UM),
            "PV_um": float((r.max() - r.min()) * MM_TO_UM)}


def _lenslet_model(design, px, py):
    """Split the design at the points (px, py) into ``fixed + feature(u - dx, v - dy)``: only
    the lenslet moves, the base stays.  For a Compound (base + lenslet feature) the base is
    fixed exactly; for a registered Compound (:class:`MovedSurface`) the feature is moved
    in design coordinates (u, v); otherwise the whole local design is shifted (exact on a
    flat base; on a base of radius R_base it biases the centre by dislocation x
    R_lens / R_base)."""
    inner = design.surface if isinstance(design, MovedSurface) else design
    base, feat = getattr(inner, "base", None), getattr(inner, "feature", None)
    if base is None or feat is None or not hasattr(feat, "height"):
        return 0.0, design, px, py
    if inner is design:
        return np.asarray(base.height(px, py), float), feat, px, py
    m = np.asarray(design.height(px, py), float)
    u, v, _ = design.to_design(px, py, m)
    return m - np.asarray(feat.height(u, v), float), feat, u, v


class _Simulated(Protocol):
    """A simulation's result (what :func:`lenslet_table` reads of it: its height map)."""

    @property
    def heightmap(self) -> HeightMap: ...


# (``design_surface: Any``: a design's Surface, which this layer does not import; in the
# functions below too; ``metrology: Any``: the scene's ``[metrology]`` section, a model of
# the scene layer, or a dict)
def lenslet_table(data: HeightMap | _Simulated | tuple[np.ndarray, float, Sequence[float]] | np.ndarray,
                  design_surface: Any, *, which: str = "machined", pixel: float | None = None,
                  origin: Sequence[float] | None = None,
                  centers: Sequence[Sequence[float]] | None = None,
                  aperture_radius: float | None = None, inner: float = 0.95,
                  mask: np.ndarray | None = None, min_points: int = 12,
                  min_fraction: float = 0.8) -> list[dict]:
    """Per-lenslet centres, dislocations and form errors.

    Parameters
    ----------
    data : HeightMap, SimulationResult, (z, pixel, origin) tuple, or (ny, nx) array
        The measured or simulated map, mm (row 0 = smallest y).  A HeightMap's
        ``which`` channel is used.
    design_surface : Surface
        The design in the frame of ``data`` (register first, see :func:`characterise_msa`),
        with ``height(x, y)``; ``centers()``, ``aperture_radius`` are used if present.
    which : {"machined", "design"}
        Channel of a HeightMap.
    pixel, origin : float, (x, y)
        mm; only for a bare array.
    centers : list of (row, col, x_mm, y_mm), optional
        Designed centres (default ``design_surface.centers()``).
    aperture_radius : float, optional
        mm (default ``design_surface.aperture_radius``, else half the smaller pitch).
    inner : float
        Fraction of the aperture used for each lenslet's fit (0.95, as Kong et al. 2020).
    mask : bool array, optional
        ``False`` leaves points out (e.g. outliers).
    min_points, min_fraction : int, float
        Lenslets with fewer valid points inside ``inner`` x aperture than ``min_points`` or
        than ``min_fraction`` of the full disc are left out (with a warning naming them):
        a partly measured lenslet gives a biased centre.

    Returns
    -------
    list of dict
        One per lenslet: ``row, col`` (design indices), ``x_mm, y_mm`` (fitted centre),
        ``dx_um, dy_um`` (fitted minus designed centre), ``Sa_um, Sq_um, PV_um`` (form
        error: measured minus the design lenslet at its fitted position and piston, within
        ``inner`` x aperture), ``x_design_mm, y_design_mm, dz_um, n_points``.
    """
    z, pixel, origin = _unpack(data, which, pixel, origin)
    cen = lenslet_centers(design_surface, centers)
    ap = _aperture(design_surface, aperture_radius)
    ok = valid_mask(z, mask)
    ny, nx = z.shape
    x = origin[0] + pixel * np.arange(nx)
    y = origin[1] + pixel * np.arange(ny)
    rad = inner * ap
    table, skipped = [], []
    for row, col, cx, cy in cen:
        i0 = max(0, int(np.floor((cx - rad - origin[0]) / pixel)))
        i1 = min(nx, int(np.ceil((cx + rad - origin[0]) / pixel)) + 1)
        j0 = max(0, int(np.floor((cy - rad - origin[1]) / pixel)))
        j1 = min(ny, int(np.ceil((cy + rad - origin[1]) / pixel)) + 1)
        if i1 <= i0 or j1 <= j0:
            skipped.append((row, col))
            continue
        xx, yy = np.meshgrid(x[i0:i1], y[j0:j1])
        sel = ok[j0:j1, i0:i1] & (np.hypot(xx - cx, yy - cy) <= rad)
        full = np.pi * (rad / pixel) ** 2
        if sel.sum() < max(min_points, min_fraction * full):
            skipped.append((row, col))
            continue
        px, py, pz = xx[sel], yy[sel], z[j0:j1, i0:i1][sel]

        fixed, feat, u, v = _lenslet_model(design_surface, px, py)

        def resid(p, u=u, v=v, pz=pz, fixed=fixed, feat=feat):
            return pz - fixed - feat.height(u - p[0], v - p[1]) - p[2]

        def jac(p, u=u, v=v, feat=feat):
            gx, gy = feat.gradient(u - p[0], v - p[1])
            return np.column_stack([gx, gy, -np.ones_like(u)])

        d0 = resid(np.zeros(3))
        sol = least_squares(resid, [0.0, 0.0, float(np.mean(d0))], x_scale=[1e-3, 1e-3, 1e-3],
                            jac=jac if hasattr(feat, "gradient") else "2-point",
                            diff_step=1e-7, xtol=1e-13, ftol=1e-15, gtol=1e-15, max_nfev=200)
        dx, dy, dz = sol.x
        r = sol.fun
        if not np.all(np.isfinite(r)):
            skipped.append((row, col))
            continue
        entry = {"row": row, "col": col, "x_mm": float(cx + dx), "y_mm": float(cy + dy),
                 "dx_um": float(dx * MM_TO_UM), "dy_um": float(dy * MM_TO_UM), **_stats_um(r),
                 "x_design_mm": float(cx), "y_design_mm": float(cy),
                 "dz_um": float(dz * MM_TO_UM),
                 "n_points": int(r.size)}
        table.append(entry)
    if skipped:
        warnings.warn(f"lenslet_table: {len(skipped)} of {len(cen)} lenslets left out (fewer than "
                      f"{min_fraction:.0%} of their points inside {inner} x aperture are valid or in the map): "
                      f"(row, col) = {skipped[:10]}{' ...' if len(skipped) > 10 else ''}",
                      stacklevel=2)
    return table


def base_form_error(z: np.ndarray, design_surface: Any, *, pixel: float,
                    origin: Sequence[float] = (0.0, 0.0),
                    centers: Sequence[Sequence[float]] | None = None,
                    aperture_radius: float | None = None, outer: float = 1.05,
                    mask: np.ndarray | None = None, has_base: bool | None = None) -> dict | None:
    """Form error of the base: measured minus design outside ``outer`` x aperture of every
    lenslet, mean removed.  Returns ``{Sa_um, Sq_um, PV_um, n_points}``, or None where no
    base data is left (lenslets that fill the area, as the MLA of Zhang et al. 2022: a
    design with ``cells == "quad"`` has no base unless ``has_base=True``)."""
    if has_base is None:
        has_base = _attr(design_surface, "cells", "round") != "quad"
    if not has_base:
        return None
    z = np.asarray(z, float)
    cen = lenslet_centers(design_surface, centers)
    ap = _aperture(design_surface, aperture_radius)
    _, base, _ = separate_msa(z.shape, cen, pixel=pixel, origin=origin, aperture_radius=ap,
                              outer=outer)
    ny, nx = z.shape
    x = origin[0] + pixel * np.arange(nx)
    y = origin[1] + pixel * np.arange(ny)
    d = z - design_surface.height(x[None, :], y[:, None])
    sel = base & valid_mask(d, mask)
    if sel.sum() < 3:
        return None
    return {**_stats_um(d[sel]), "n_points": int(sel.sum())}


def characterise_msa(z: np.ndarray, design_surface: Any, *, pixel: float,
                     origin: Sequence[float] = (0.0, 0.0),
                     centers: Sequence[Sequence[float]] | None = None,
                     aperture_radius: float | None = None, inner: float = 0.95,
                     outer: float = 1.05, outlier_k: float = 3.0, register: bool = True,
                     fit: Sequence[str] = ("tx", "ty", "tz", "alpha", "beta", "gamma"),
                     metrology: Any = None, stages: str = "base_then_all") -> dict:
    """The characterisation of a MSA on a base of Kong et al. (2020), end to end.

    1. outliers by the second-difference ``outlier_k``-sigma rule of Kong et al.
       (``rule="curvature"``) (replaced, left out of fits);
    2. least-squares 6-DOF registration on the base data (outside ``outer`` x aperture)
       when there is enough of it, then on all data (``fit`` names the free parameters;
       ``stages = "base"`` stops after the base);
    3. separation (``inner`` / ``outer`` x aperture) and per-lenslet fits
       (:func:`lenslet_table`) against the registered design;
    4. base form error (:func:`base_form_error`).

    ``metrology`` (a scene's ``[metrology]`` section or dict), when given, supplies
    ``inner`` (``msa_inner``), ``outer`` (``msa_outer``), ``outlier_k``
    (``outlier_sigma``), ``fit`` (``registration_dof``) and ``register``
    (``registration != "none"``).

    Returns
    -------
    dict
        ``lenslets`` (list of dicts, see :func:`lenslet_table`), ``base`` (dict or None),
        ``registration`` (dict or None), ``outliers`` (count), ``summary``
        (max |dislocation|, mean and max per-lenslet Sq).
    """
    if metrology is not None:
        def get(key, default):
            return metrology.get(key, default) if isinstance(metrology, dict) else getattr(
                metrology, key, default)

        inner, outer = float(get("msa_inner", inner)), float(get("msa_outer", outer))
        outlier_k = float(get("outlier_sigma", outlier_k))
        fit = tuple(get("registration_dof", fit))
        register = get("registration", "lsq") != "none"
        stages = get("registration_stages", stages)
    z = np.asarray(z, float)
    cen = lenslet_centers(design_surface, centers)
    ap = _aperture(design_surface, aperture_radius)
    cleaned, outl = detect_outliers(z, pixel=pixel, k=outlier_k, rule="curvature")
    use = np.isfinite(cleaned) & ~outl
    reg = None
    surf = design_surface
    if register:
        _, base_data, _ = separate_msa(z.shape, cen, pixel=pixel, origin=origin,
                                       aperture_radius=ap, inner=inner, outer=outer)
        init = None
        if (_attr(design_surface, "cells", "round") != "quad"
                and (base_data & use).sum() > 0.1 * use.sum()):
            init = register_lsq(cleaned, design_surface, pixel=pixel, origin=origin,
                                mask=base_data & use, fit=fit)
        if stages == "base" and init is not None:
            reg = dict(init)
        else:
            reg = register_lsq(cleaned, design_surface, pixel=pixel, origin=origin, mask=use,
                               init=init, fit=fit)
        reg["base_stage"] = None if init is None else {k: init[k] for k in init if k != "fitted"}
        surf = MovedSurface(design_surface, reg)
        cen = [(r, c) + surf.move_point(x, y)[:2] for r, c, x, y in cen]
    table = lenslet_table((cleaned, pixel, origin), surf, centers=cen, aperture_radius=ap,
                          inner=inner, mask=use)
    base = base_form_error(cleaned, surf, pixel=pixel, origin=origin, centers=cen,
                           aperture_radius=ap, outer=outer, mask=use,
                           has_base=_attr(design_surface, "cells", "round") != "quad")
    disl = [np.hypot(e["dx_um"], e["dy_um"]) for e in table]
    sq = [e["Sq_um"] for e in table]
    summary = {"n_lenslets": len(table),
               "max_dislocation_um": float(max(disl)) if disl else None,
               "mean_Sq_um": float(np.mean(sq)) if sq else None,
               "max_Sq_um": float(max(sq)) if sq else None}
    return {"lenslets": table, "base": base, "registration": reg, "outliers": int(outl.sum()),
            "summary": summary}
