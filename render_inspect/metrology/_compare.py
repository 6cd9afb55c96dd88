"""Characterise a map with a scene's ``[metrology]`` settings, and compare a measured map
with a scene's design and simulation through the same chain."""

from __future__ import annotations

from typing import Any, Protocol, cast
from collections.abc import Sequence
import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from ..core.lazy import lazy_module

from ..core.errors import InputError
from ..core.heightmap import HeightMap
from ..core.units import MM_TO_NM
from ._chance import registration_against_chance, unreliable_registration_warning
from ._checks import registration_checks
from ._filters import l_filter, pixel_xy, remove_form, s_filter
from ._params import areal_parameters
from ._registration import (
    RIGID_KEYS,
    MovedSurface,
    detect_outliers,
    register_icp,
    register_lsq,
    rotation_matrix,
)

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["characterise_map", "coverage", "check_same_pixel", "resample_map", "sample_map",
           "Comparison",
           "compare_measured"]


def _cfg_get(cfg, key, default):
    if cfg is None:
        return default
    if isinstance(cfg, dict):
        return cfg.get(key, default)
    return getattr(cfg, key, default)


def characterise_map(z: np.ndarray, *, pixel: float | tuple[float, float],
                     origin: Sequence[float] = (0.0, 0.0), form_removal: str = "plane",
                     polynomial_degree: int = 2, design: Any = None,
                     s_filter_mm: float | None = None,
                     l_filter_mm: float | None = None, mask: np.ndarray | None = None,
                     slope: str = "forward",
                     filter_edges: str = "normalised") -> dict:
    """Form removal, S- and L-filtering, then areal parameters (heights in nm).

    Parameters
    ----------
    z : (ny, nx) array
        Heights, mm (NaN = missing).
    pixel : float or (pixel_x, pixel_y)
        mm.
    origin : (x, y)
        mm.
    form_removal : {"none", "plane", "polynomial", "sphere", "design"}
        See :func:`remove_form` (``design`` needs ``design=``, already registered).
    s_filter_mm, l_filter_mm : float, optional
        ISO 16610-61 nesting indices, mm (S removes shorter, L longer wavelengths).
    filter_edges : {"normalised", "mirror", "cut"}
        Edge handling of both filters (:func:`gaussian_filter`).

    Returns
    -------
    dict
        ``Sa_nm, Sq_nm, Sp_nm, Sv_nm, Sz_nm, Ssk, Sku, Sdq, Sdr_percent, n_valid`` and the
        settings used (``slope_estimator``, ``form_removal``, ``s_filter_mm``, ``l_filter_mm``,
        ``filter_edges``).
    """
    res, _ = remove_form(z, pixel=pixel, method=form_removal, degree=polynomial_degree,
                         design=design, origin=origin, mask=mask)
    if s_filter_mm:
        res = s_filter(res, pixel=pixel, nesting_index=s_filter_mm, edges=filter_edges)
    if l_filter_mm:
        if s_filter_mm and not l_filter_mm > s_filter_mm:
            raise InputError(f"metrology.l_filter ({l_filter_mm} mm) must be > metrology.s_filter "
                             f"({s_filter_mm} mm)")
        res = l_filter(res, pixel=pixel, nesting_index=l_filter_mm, edges=filter_edges)
    p = areal_parameters(res, pixel=pixel, slope=slope)
    out = {f"{k}_nm": p[k] * MM_TO_NM for k in ("Sa", "Sq", "Sp", "Sv", "Sz")}
    out.update({"Ssk": p["Ssk"], "Sku": p["Sku"], "Sdq": p["Sdq"], "Sdr_percent": p["Sdr"],
                "n_valid": p["n_valid"], "slope_estimator": slope, "form_removal": form_removal,
                "s_filter_mm": s_filter_mm, "l_filter_mm": l_filter_mm,
                "filter_edges": filter_edges})
    return out


def coverage(z: np.ndarray, *, pixel: float | tuple[float, float], origin: Sequence[float],
             region: Sequence[float]) -> float:
    """Fraction of the area of ``region`` = (x0, y0, x1, y1) (mm) covered by the cells
    (pixel_x x pixel_y, centred on the points) of the map's valid points; ``pixel`` one
    number or (pixel_x, pixel_y), mm."""
    x0, y0, x1, y1 = region
    if not (x1 > x0 and y1 > y0):
        raise InputError(f"region must be (x0, y0, x1, y1) with x1 > x0 and y1 > y0, got {region}")
    px, py = pixel_xy(pixel)
    z = np.asarray(z)
    ny, nx = z.shape
    xc = origin[0] + px * np.arange(nx)
    yc = origin[1] + py * np.arange(ny)
    lx = np.clip(np.minimum(xc + px / 2, x1) - np.maximum(xc - px / 2, x0), 0.0, None)
    ly = np.clip(np.minimum(yc + py / 2, y1) - np.maximum(yc - py / 2, y0), 0.0, None)
    covered = float(ly @ np.isfinite(z).astype(np.float64) @ lx)
    return min(1.0, covered / ((x1 - x0) * (y1 - y0)))


def _pixel_text(p) -> str:
    px, py = pixel_xy(p)
    return f"{px:g}" if px == py else f"{px:g} x {py:g}"


def check_same_pixel(pixel_a: float | tuple[float, float], pixel_b: float | tuple[float, float], *,
                     name_a: str = "measured",
                     name_b: str = "simulated", rtol: float = 1e-6) -> None:
    """Raise :class:`InputError` naming both pixel sizes (x and y) when they differ."""
    a, b = pixel_xy(pixel_a), pixel_xy(pixel_b)
    if not np.allclose(a, b, rtol=rtol, atol=0):
        raise InputError(f"pixel sizes differ: {name_a} {_pixel_text(a)} mm vs {name_b} "
                         f"{_pixel_text(b)} mm; resample one map (resample_map) or set "
                         f"simulation.pixel = {a[0]:g}")


def resample_map(z: np.ndarray, *, pixel: float | tuple[float, float], origin: Sequence[float],
                 target_pixel: float | tuple[float, float], target_origin: Sequence[float],
                 target_shape: tuple[int, ...]) -> np.ndarray:
    """Bilinear resampling of a map onto another grid (pixels: one number or (x, y), mm);
    NaN outside and next to missing points."""
    tx, ty = pixel_xy(target_pixel, "target_pixel")
    ny, nx = target_shape
    x = target_origin[0] + tx * np.arange(nx)
    y = target_origin[1] + ty * np.arange(ny)
    xx, yy = np.meshgrid(x, y)
    return sample_map(z, xx, yy, pixel=pixel, origin=origin)


def sample_map(z: np.ndarray, xx: np.ndarray, yy: np.ndarray, *,
               pixel: float | tuple[float, float], origin: Sequence[float]) -> np.ndarray:
    """Bilinear look-up of a map at points (``xx``, ``yy``) (mm); NaN outside the map and
    next to missing points."""
    px, py = pixel_xy(pixel)
    col = (xx - origin[0]) / px
    row = (yy - origin[1]) / py
    z = np.asarray(z, float)
    ok = np.isfinite(z)
    v = ndimage.map_coordinates(np.where(ok, z, 0.0), [row, col], order=1, mode="constant", cval=0.0)
    bad = ndimage.map_coordinates((~ok).astype(float), [row, col], order=1, mode="constant", cval=1.0)
    inside = (row >= 0) & (row <= z.shape[0] - 1) & (col >= 0) & (col <= z.shape[1] - 1)
    return np.where(inside & (bad < 1e-9), v, np.nan)


def _check_units(z, design, *, pixel, origin, force: bool = False):
    """Refuse (warn with ``force``) when the measured height range and the design's
    differ by > 100 x: a map in micrometres read as millimetres (or the reverse) would
    otherwise give silent nonsense.  The message says which unit the heights were probably
    in, and names ``--force`` (compare anyway) and the reader's ``units``."""
    ny, nx = z.shape
    px, py = pixel_xy(pixel)
    step = max(1, max(ny, nx) // 64)
    x = origin[0] + px * np.arange(0, nx, step)
    y = origin[1] + py * np.arange(0, ny, step)
    d = np.asarray(design.height(x[None, :], y[:, None]), float)
    zs = z[::step, ::step]
    ok = np.isfinite(d) & np.isfinite(zs)
    if ok.sum() < 4:
        return
    pd, pm = float(np.ptp(d[ok])), float(np.ptp(zs[ok]))
    if pd > 1e-6 and pm > 0 and not 0.01 < pm / pd < 100:
        ratio = pm / pd
        # the unit factor (10^3 steps: mm, um, nm) closest to the ratio
        steps = round(math.log10(ratio) / 3)
        if abs(math.log10(ratio) - 3 * steps) > 0.5:
            steps = 0
        likely = {1: "heights in micrometres or nanometres read as millimetres",
                  2: "heights in nanometres read as millimetres",
                  -1: "heights in millimetres read as micrometres",
                  -2: "heights in millimetres read as nanometres"}.get(
            max(-2, min(2, steps)), "a height unit that does not match, or a pixel size in "
                                    "another unit than the file declares")
        msg = (f"the measured heights span {pm:.4g} mm but the design spans {pd:.4g} mm over "
               f"the same area (ratio {ratio:.3g}): the height unit is probably wrong "
               f"({likely}); check the file's height unit (an .npy's side-car "
               f"\"units\", or read_surface(path, units='um' | 'nm' | 'mm')), or "
               f"compare anyway with --force")
        if force:
            warnings.warn(msg.replace(", or compare anyway with --force",
                                      "; compared anyway (--force)"), stacklevel=3)
            return
        raise InputError(msg)


@dataclass
class Comparison:
    """Result of :func:`compare_measured`.

    Attributes
    ----------
    metrics : dict
        JSON-able: ``measured``, ``simulated`` (or None), ``difference`` (or None),
        ``registration``, ``coverage``, ``outliers``, ``source``.
    maps : dict of (ny, nx) arrays, mm
        ``measured`` (outliers replaced), ``design`` (registered, on the measured grid),
        ``residual`` (measured - design), and with a simulation ``simulated_residual`` and
        ``difference`` (measured residual - simulated residual), all on the measured grid.
    pixel : (pixel_x, pixel_y)
        mm.
    origin : (x, y)
    """

    metrics: dict
    maps: dict = field(default_factory=dict)
    pixel: tuple = (0.0, 0.0)
    origin: tuple = (0.0, 0.0)


class _MeasuredGrid(Protocol):
    """A measured map (as :class:`render_inspect.io.MeasuredMap`): heights (mm) and grid."""

    @property
    def z(self) -> np.ndarray: ...
    @property
    def pixel(self) -> float | tuple[float, float]: ...
    @property
    def origin(self) -> Sequence[float]: ...


# (``design_surface: Any``: a design's Surface, which this layer does not import;
# ``metrology: Any``: the scene's ``[metrology]`` section, a model of the scene layer, or a dict)
def compare_measured(measured: _MeasuredGrid | tuple, design_surface: Any, *,
                     metrology: Any = None, simulated: HeightMap | None = None,
                     region: Sequence[float] | None = None,
                     seed: int = 0, resample_simulated: bool = False,
                     expected_sq_mm: float | None = None, force: bool = False,
                     against_chance: bool = True) -> Comparison:
    """Compare a measured height map with the design (and a simulation) of a scene.

    Chain: unit sanity check -> outliers
    (spikes, ``metrology.outlier_sigma``; always left out of the registration
    fit, left out of the parameters only with ``metrology.outliers = "sigma"``) ->
    coverage of ``region`` -> registration to the design (``metrology.registration``:
    "lsq", "icp" or "none"; free parameters ``metrology.registration_dof``) -> checks
    (:func:`registration_checks`: overlap after registration, residual against
    ``expected_sq_mm``, uncertainty of the registration) -> residual = measured -
    registered design -> the registration against chance (``against_chance``) ->
    :func:`characterise_map` with the scene's form removal and
    filters.  With ``simulated`` (a HeightMap) the simulated residual (machined - design)
    goes through the same :func:`characterise_map`, and the difference of the two
    residuals is characterised too.  Pixels may be non-square: ``(pixel_x, pixel_y)``.

    Parameters
    ----------
    measured : map object or tuple
        A :class:`render_inspect.io.MeasuredMap` (``z``, ``pixel``, ``origin``, ``meta``;
        from :func:`render_inspect.io.read_surface`) or a ``(z_mm, pixel_mm, origin_mm[,
        source])`` tuple (``pixel_mm`` one number or (x, y)).
    design_surface : Surface
    metrology : MetrologyConfig or dict, optional
        The scene's ``[metrology]`` section (defaults otherwise); also read:
        ``outliers`` ("none" | "sigma"), ``min_overlap`` (0.8).
    simulated : HeightMap, optional
    region : (x0, y0, x1, y1), optional
        mm; the area the comparison should cover (e.g. ``scene.simulation.region``).
    seed : int
        Seed of the point subset used by the registration (recorded in the metrics).
    resample_simulated : bool
        When the simulation's pixel differs from the measurement's: False (default) raises
        an :class:`InputError` naming both; True resamples the simulation (bilinear) onto
        the measured points with a warning.
    expected_sq_mm : float, optional
        The roughness the process should leave, mm (for the residual check).
    force : bool
        Go on (with the reasons in ``metrics["checks"]["refusals"]``) when the checks
        refuse the comparison.
    against_chance : bool
        Set the registration against chance (:func:`registration_against_chance`: its
        score against the best of :data:`NULL_SURROGATES` phase-randomised surrogates of
        the map registered the same way): ``registration.reliable``, ``score``,
        ``null_score`` and ``chance`` in the metrics, a warning in ``checks.warnings``
        (or a Python warning without a region) when it does not beat them, and
        ``registration_reliable`` in ``measured`` and ``difference``.  False (a check
        that only needs the refusals) leaves them out.

    Raises
    ------
    InputError
        Pixel sizes differ (see ``resample_simulated``); the map does not overlap
        ``region``; the measured heights span a range 100 x larger or smaller than the
        design's over the same area (wrong units?); no valid points; the checks refuse
        the comparison (unless ``force``).
    """
    if hasattr(measured, "z") and hasattr(measured, "pixel"):
        grid_map = cast(_MeasuredGrid, measured)
        z, pixel, origin = grid_map.z, grid_map.pixel, grid_map.origin
        source = dict(getattr(measured, "meta", {}) or {})
    elif isinstance(measured, tuple) and len(measured) in (3, 4):
        z, pixel, origin = measured[:3]
        source = dict(measured[3]) if len(measured) == 4 else {"format": "array"}
    else:
        raise InputError("measured must be a MeasuredMap or a (z_mm, pixel_mm, origin_mm[, "
                         "source]) tuple; read files with render_inspect.io.read_surface")
    z = np.asarray(z, float)
    origin = (float(origin[0]), float(origin[1]))
    px, py = pixel_xy(pixel)
    pixel = (px, py)
    k = float(_cfg_get(metrology, "outlier_sigma", 3.0))
    out_mode = _cfg_get(metrology, "outliers", "none")
    if out_mode not in ("none", "sigma"):
        raise InputError(f"metrology.outliers must be 'none' or 'sigma', got {out_mode!r}")
    method = _cfg_get(metrology, "registration", "lsq")
    dof = tuple(_cfg_get(metrology, "registration_dof",
                         ("tx", "ty", "tz", "alpha", "beta", "gamma")))
    min_cov = float(_cfg_get(metrology, "min_coverage", 0.95))
    min_overlap = float(_cfg_get(metrology, "min_overlap", 0.8))
    if simulated is not None and not resample_simulated:
        check_same_pixel(pixel, simulated.pixel)
    elif simulated is not None and not np.allclose(pixel, pixel_xy(simulated.pixel), rtol=1e-6):
        warnings.warn(f"pixel sizes differ (measured {_pixel_text(pixel)} mm, simulated "
                      f"{_pixel_text(simulated.pixel)} mm): the simulation is resampled "
                      f"bilinearly onto the measured points", stacklevel=2)
    cov = None
    if region is not None:
        cov = coverage(z, pixel=pixel, origin=origin, region=region)
        if cov == 0.0:
            raise InputError(f"the measured map (origin {origin} mm, {z.shape[1]} x {z.shape[0]} "
                             f"pixels of {_pixel_text(pixel)} mm) does not overlap the region "
                             f"{tuple(region)} mm: check the units and origin of the measurement")
        if cov < min_cov:
            warnings.warn(f"the measurement covers only {cov:.1%} of the region {tuple(region)} mm "
                          f"(metrology.min_coverage = {min_cov:.0%}); parameters describe the "
                          f"covered part only", stacklevel=2)
    _check_units(z, design_surface, pixel=pixel, origin=origin, force=force)
    _, outl = detect_outliers(z, pixel=pixel, k=k, replace=False)
    valid = np.isfinite(z)
    outl &= valid
    fit_use = valid & ~outl
    ny, nx = z.shape
    x = origin[0] + px * np.arange(nx)
    y = origin[1] + py * np.arange(ny)
    use = fit_use if out_mode == "sigma" else valid
    free_note: list = []
    oversample = int(_cfg_get(metrology, "template_oversample", 10))
    for _ in range(2):
        if method == "lsq":
            reg = register_lsq(z, design_surface, pixel=pixel, origin=origin, mask=fit_use,
                               fit=dof, seed=seed)
        elif method == "icp":
            reg = register_icp(z, design_surface, pixel=pixel, origin=origin, mask=fit_use,
                               fit=dof, seed=seed, oversample=oversample)
        elif method == "none":
            reg = None
        else:
            raise InputError(f"metrology.registration must be 'lsq', 'icp' or 'none', got "
                             f"{method!r}")
        surf = design_surface if reg is None else MovedSurface(design_surface, reg)
        design_map = np.broadcast_to(surf.height(x[None, :], y[:, None]), z.shape).astype(float)
        residual = np.where(use, z - design_map, np.nan)
        checks = None
        if reg is None or region is None:
            break
        checks = registration_checks(z, design_surface, reg, pixel=pixel, origin=origin,
                                     region=region, expected_sq_mm=expected_sq_mm,
                                     residual=np.where(fit_use, residual, np.nan), mask=fit_use,
                                     min_overlap=min_overlap)
        if not checks.get("free_rotation"):
            break
        # the design turns freely about a point in the field: the rotation about z is held
        # at the file's orientation and the rest registered again
        dof = tuple(d for d in dof if d != "gamma")
        free_note = [w for w in checks["warnings"] if w.startswith("the design turns freely")]
        free_note = [f"{w}; the rotation about z is therefore held at the file's orientation "
                     f"and the other {len(dof)} registered" for w in free_note]
    if checks is not None and reg is not None:
        checks["rotation_held"] = bool(free_note)
        checks["warnings"] = free_note + checks["warnings"]
        reg["uncertainty"] = checks["uncertainty"]
        if not checks["ok"] and not force:
            raise InputError("the measured file does not match the design: "
                             + "; ".join(checks["refusals"]) + " (--force compares anyway)")
    if reg is not None and against_chance:
        chance = registration_against_chance(z, design_surface, reg, pixel=pixel, origin=origin,
                                             mask=fit_use, oversample=oversample, seed=seed)
        reg.update(reliable=chance["reliable"], score=chance["score"],
                   null_score=chance["null_score"], chance=chance)
        note = unreliable_registration_warning(chance)
        if note and checks is not None:
            checks["warnings"].append(note)
        elif note:
            warnings.warn(note, stacklevel=2)
    settings = {"form_removal": _cfg_get(metrology, "form_removal", "plane"),
                    "polynomial_degree": int(_cfg_get(metrology, "polynomial_degree", 2)),
                    "s_filter_mm": _cfg_get(metrology, "s_filter", None),
                    "l_filter_mm": _cfg_get(metrology, "l_filter", None)}

    def char(r):
        s = dict(settings)
        if s["form_removal"] == "design":  # the residual is already the deviation from design
            s["form_removal"] = "none"
        return characterise_map(r, pixel=pixel, origin=origin, **s)

    n_valid = int(valid.sum())
    reliable = None if reg is None or "reliable" not in reg else bool(reg["reliable"])
    metrics = {"measured": {**char(residual), "registration_reliable": reliable},
               "simulated": None, "difference": None,
               "registration": reg, "coverage": cov, "checks": checks,
               "outliers": {"method": out_mode, "sigma": k, "count": int(outl.sum()),
                            "fraction": float(outl.sum() / max(n_valid, 1)),
                            "left_out_of": ["registration", "parameters"] if out_mode == "sigma"
                            else ["registration"]},
               "source": {k2: v for k2, v in source.items() if k2 != "scene"}, "seed": seed,
               "pixel_mm": [px, py], "origin_mm": list(origin), "shape": [ny, nx],
               "units": {"lateral": "mm", "heights": "nm (keys *_nm)",
                         "in_file": source.get("units_in_file")}}
    maps = {"measured": np.where(valid, z, np.nan), "design": design_map, "residual": residual,
            "outliers": outl}
    if simulated is not None:
        # the simulation lives in the design frame: look it up where each measured point
        # lies in that frame (the inverse of the registration)
        xx, yy = np.meshgrid(x, y)
        if reg is not None:
            vec = np.array([reg[k] for k in RIGID_KEYS])
            rot = rotation_matrix(*vec[3:])
            zz = np.where(np.isfinite(design_map), design_map, 0.0)
            dx, dy, dz = xx - vec[0], yy - vec[1], zz - vec[2]
            xx = rot[0, 0] * dx + rot[1, 0] * dy + rot[2, 0] * dz
            yy = rot[0, 1] * dx + rot[1, 1] * dy + rot[2, 1] * dz
        sim_res = sample_map(np.asarray(simulated.machined) - np.asarray(simulated.design),
                             xx, yy, pixel=simulated.pixel, origin=simulated.origin)
        both = np.isfinite(sim_res) & np.isfinite(residual)
        if not both.any():
            raise InputError(f"the measured map and the simulation do not overlap (measured origin "
                             f"{origin} mm, simulated origin {tuple(simulated.origin)} mm)")
        frac = float(both.sum() / max(1, np.isfinite(residual).sum()))
        if frac < min_cov:
            warnings.warn(f"the simulation covers only {frac:.1%} of the measured points; the "
                          f"comparison uses the overlap only", stacklevel=2)
        metrics["simulated"] = char(np.where(both, sim_res, np.nan))
        diff = np.where(both, residual - sim_res, np.nan)
        metrics["difference"] = {**char(diff), "registration_reliable": reliable}
        metrics["simulated_overlap"] = frac
        maps["simulated_residual"] = sim_res
        maps["difference"] = diff
    return Comparison(metrics, maps, pixel, origin)

