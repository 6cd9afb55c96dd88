"""Checks that a measured map belongs to a design before it is compared with it.

- :func:`registered_overlap`: after registration, the fraction of the smaller of the two
  areas (the measured valid area and the design region) that both cover.
- :func:`correlation_area`: area of the positive central lobe of a map's autocorrelation,
  used to count independent residuals.
- :func:`registration_checks`: overlap, registration residual against the roughness the
  process should leave, and the registration's uncertainty (lateral shift, rotation);
  returns what refuses the comparison and what only deserves a warning.
- :func:`kinematic_sq_mm`: the Sq a round-nosed tool leaves at a given feed.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np
from ..core.lazy import lazy_module

from ..core.errors import InputError, check_positive, check_range
from ..core.units import MM_TO_NM, MM_TO_UM
from ._filters import pixel_xy, valid_mask
from ._params import autocorrelation
from ._registration import RIGID_KEYS, registration_covariance, rotation_matrix

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["registered_overlap", "correlation_area", "registration_checks", "kinematic_sq_mm",
           "DEFAULT_MIN_OVERLAP", "DEFAULT_MAX_RESIDUAL_RATIO", "DEFAULT_RESIDUAL_FLOOR_MM"]

#: Smallest accepted overlap, as a fraction of the smaller of the two areas.
DEFAULT_MIN_OVERLAP = 0.8
#: Largest accepted registration residual RMS, in multiples of the expected Sq ...
DEFAULT_MAX_RESIDUAL_RATIO = 20.0
#: ... but never below this (mm): form errors of a few um are normal on a real part.
DEFAULT_RESIDUAL_FLOOR_MM = 0.002


def kinematic_sq_mm(feed_per_rev_mm: float, nose_radius_mm: float) -> float:
    """Sq of the ideal turned profile: nose arcs of radius ``R`` stepped by the feed ``f``.

    The profile is the parabola ``x^2 / (2 R)`` over one feed (``f << R``), whose RMS
    about its mean is ``f^2 / (12 sqrt(5) R)`` (peak-to-valley ``f^2 / (8 R)``).
    """
    check_positive("feed_per_rev_mm", feed_per_rev_mm)
    check_positive("nose_radius_mm", nose_radius_mm)
    return float(feed_per_rev_mm) ** 2 / (12.0 * math.sqrt(5.0) * float(nose_radius_mm))


def registered_overlap(z: np.ndarray, *, pixel: float | tuple[float, float],
                       origin: Sequence[float] = (0.0, 0.0), region: Sequence[float],
                       registration: dict | None = None,
                       mask: np.ndarray | None = None) -> dict:
    """Overlap of a measured map with a design region after registration.

    Each valid measured point ``p`` is taken into the design frame, ``q = R^T (p - t)``
    (the registration moves the design into the measured frame, see
    :data:`~render_inspect.metrology.RIGID_KEYS`), and counted when ``q`` lies inside
    ``region``.  The overlap is the area of those points (``n px py``) over the smaller
    of the measured valid area and the region's area.

    Parameters
    ----------
    z : (ny, nx) array
        Measured heights, mm (NaN = missing).
    pixel : float or (pixel_x, pixel_y)
        mm.
    origin : (x, y)
        Centre of pixel [0, 0], mm.
    region : (x0, y0, x1, y1)
        The design region, mm (e.g. the scene's ``simulation.region``).
    registration : dict, optional
        A :func:`register_lsq` / :func:`register_icp` result (identity when None).

    Returns
    -------
    dict
        ``fraction``, ``overlap_area_mm2``, ``measured_area_mm2``, ``region_area_mm2``.
    """
    x0, y0, x1, y1 = (float(v) for v in region)
    if not (x1 > x0 and y1 > y0):
        raise InputError(f"region must be (x0, y0, x1, y1) with x1 > x0 and y1 > y0, got {region}")
    px, py = pixel_xy(pixel)
    z = np.asarray(z, dtype=np.float64)
    ok = valid_mask(z, mask)
    ny, nx = z.shape
    xx, yy = np.meshgrid(origin[0] + px * np.arange(nx), origin[1] + py * np.arange(ny))
    x, y, h = xx[ok], yy[ok], z[ok]
    if registration is not None:
        v = np.array([float(registration.get(k, 0.0)) for k in RIGID_KEYS])
        r = rotation_matrix(*v[3:])
        dx, dy, dz = x - v[0], y - v[1], h - v[2]
        x = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz
        y = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
    inside = (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
    cell = px * py
    meas = float(ok.sum()) * cell
    reg_area = (x1 - x0) * (y1 - y0)
    over = float(inside.sum()) * cell
    smaller = min(meas, reg_area)
    return {"fraction": float(min(1.0, over / smaller)) if smaller > 0 else 0.0,
            "overlap_area_mm2": over, "measured_area_mm2": meas, "region_area_mm2": reg_area}


def correlation_area(z: np.ndarray, *, pixel: float | tuple[float, float],
                     mask: np.ndarray | None = None) -> float:
    """Area (mm^2) of the positive central lobe of the autocorrelation of ``z``:
    ``sum(ACF) px py`` over the connected region around zero lag where ACF > 0.  The
    number of independent values in a map of area ``A`` is about ``A`` / this."""
    px, py = pixel_xy(pixel)
    acf, _ = autocorrelation(z, mask=mask)
    pos = np.nan_to_num(acf, nan=-1.0) > 0
    lab, _ = ndimage.label(pos)
    c = lab[acf.shape[0] // 2, acf.shape[1] // 2]
    lobe = lab == c
    return float(np.sum(acf[lobe]) * px * py)


def registration_checks(z: np.ndarray, design: np.ndarray, registration: dict, *,
                        pixel: float | tuple[float, float], origin: Sequence[float] = (0.0, 0.0),
                        region: Sequence[float],
                        expected_sq_mm: float | None, residual: np.ndarray | None = None,
                        mask: np.ndarray | None = None,
                        min_overlap: float = DEFAULT_MIN_OVERLAP,
                        max_residual_ratio: float = DEFAULT_MAX_RESIDUAL_RATIO,
                        residual_floor_mm: float = DEFAULT_RESIDUAL_FLOOR_MM,
                        max_shift_sigma_mm: float | None = None,
                        max_rotation_sigma_rad: float = 1e-3) -> dict:
    """Is this measurement a map of this design?  Checks for ``compare --measured``.

    Refused (``ok`` False, reasons in ``refusals``):

    - the registered overlap (:func:`registered_overlap`) is below ``min_overlap`` of
      the smaller of the measured area and ``region``;
    - the registration residual RMS (of ``residual`` when given, else the registration's
      own ``rms_mm``) exceeds ``max(max_residual_ratio * expected_sq_mm,
      residual_floor_mm)``.

    - the lateral position is undetermined: the standard uncertainty of the lateral
      shift exceeds a tenth of the smaller side of the measured field (the design has no
      lateral structure within the field to register to, e.g. a map read 1000 x too
      small).

    Not refused but warned: a design that turns freely about a point in the field (one
    round lenslet) leaves the shift undetermined only while the rotation about z is free;
    with it held the shift is fixed (``uncertainty["shift_mm_rotation_held"]``), and
    ``free_rotation`` is True (:func:`compare_measured` then registers again with the
    rotation held).

    Warned (``warnings``): the standard uncertainty of the lateral shift exceeds
    ``max_shift_sigma_mm`` (default: one pixel) or that of the rotation about z exceeds
    ``max_rotation_sigma_rad``; no expected roughness given (residual not checked).

    Parameters
    ----------
    z : (ny, nx) array
        Measured heights, mm (outliers already left out through ``mask`` if wanted).
    design : object with ``height(x, y)`` (and ``gradient``)
        The design surface the map was registered to.
    registration : dict
        :func:`register_lsq` / :func:`register_icp` result.
    pixel, origin
        mm.
    region : (x0, y0, x1, y1)
        Design region, mm.
    expected_sq_mm : float or None
        The Sq the process should leave (e.g. :func:`kinematic_sq_mm`), mm.
    residual : (ny, nx) array, optional
        Measured minus registered design: its autocovariance makes the uncertainty
        account for correlated residuals (:func:`registration_covariance`); without it
        the formal (independent-residual) uncertainty is reported.

    Returns
    -------
    dict
        ``ok``, ``refusals`` (list of str), ``warnings`` (list of str), ``overlap``
        (:func:`registered_overlap`), ``residual_rms_mm``, ``residual_limit_mm``,
        ``expected_sq_mm``, ``shift_mm`` (tx, ty), ``rotation_rad`` (gamma),
        ``uncertainty`` (:func:`registration_covariance` plus ``shift_mm`` = combined
        lateral standard uncertainty and ``rotation_rad``), ``thresholds``.
    """
    check_range("min_overlap", min_overlap, 0.0, 1.0)
    check_positive("max_residual_ratio", max_residual_ratio)
    px, py = pixel_xy(pixel)
    max_shift = float(max_shift_sigma_mm) if max_shift_sigma_mm is not None else max(px, py)
    refusals, warns = [], []
    ov = registered_overlap(z, pixel=(px, py), origin=origin, region=region,
                            registration=registration, mask=mask)
    if ov["fraction"] < min_overlap:
        refusals.append(f"the registered measurement overlaps {ov['fraction']:.1%} of the smaller "
                        f"of its area ({ov['measured_area_mm2']:.4g} mm^2) and the design region "
                        f"({ov['region_area_mm2']:.4g} mm^2); at least {min_overlap:.0%} is needed")
    rms = float(registration.get("rms_mm", float("nan")))
    if residual is not None and np.isfinite(residual).any():
        # the heights' residual: ICP's own rms is the distance of each point to the nearest
        # template point's tangent plane, which a map of another surface can make small
        rms = float(np.sqrt(np.nanmean(np.asarray(residual, dtype=np.float64) ** 2)))
    limit = None
    if expected_sq_mm is None:
        warns.append("no expected roughness known: the registration residual was not checked")
    else:
        check_positive("expected_sq_mm", expected_sq_mm)
        limit = max(max_residual_ratio * float(expected_sq_mm), residual_floor_mm)
        if not rms <= limit:
            refusals.append(f"the registration residual RMS {rms * MM_TO_NM:.4g} nm is above "
                            f"{limit * MM_TO_NM:.4g} nm (max of {max_residual_ratio:g} x the "
                            f"expected Sq {expected_sq_mm * MM_TO_NM:.3g} nm and "
                            f"{residual_floor_mm * MM_TO_NM:.4g} nm)")
    unc = registration_covariance(z, design, registration, pixel=(px, py), origin=origin,
                                  mask=mask, residual=residual)
    sig = unc["sigma"]
    s_shift = float(np.hypot(sig.get("tx_mm", 0.0), sig.get("ty_mm", 0.0)))
    s_rot = float(sig.get("gamma_rad", 0.0))
    unc.update({"shift_mm": s_shift, "rotation_rad": s_rot})
    ny, nx = np.shape(z)
    field_min = min(px * nx, py * ny)
    free_turn = False
    fitted = list(registration.get("fitted") or [k.split("_")[0] for k in RIGID_KEYS])
    if s_shift > 0.1 * field_min and "gamma" in fitted and len(fitted) > 1:
        # a design symmetric about a point in the field (one round lenslet) turns about
        # it freely: a rotation there is a shift plus a rotation about the origin, so the
        # shift alone is undetermined although the map fits in one place only
        held = registration_covariance(z, design, {**registration, "fitted": [
            k for k in fitted if k != "gamma"]}, pixel=(px, py), origin=origin, mask=mask,
            residual=residual)["sigma"]
        s_held = float(np.hypot(held.get("tx_mm", 0.0), held.get("ty_mm", 0.0)))
        unc["shift_mm_rotation_held"] = s_held
        free_turn = s_held <= 0.1 * field_min
    if free_turn:
        warns.append(f"the design turns freely about a point in the field (e.g. one round "
                     f"lenslet): the rotation about z is undetermined (standard uncertainty "
                     f"{np.degrees(s_rot):.3g} deg) and with it the shift "
                     f"({s_shift * MM_TO_UM:.3g} um); with the rotation held the shift's "
                     f"standard uncertainty is {unc['shift_mm_rotation_held'] * MM_TO_UM:.3g} "
                     f"um")
    elif s_shift > 0.1 * field_min:
        refusals.append(f"the lateral registration is undetermined: standard uncertainty of the "
                        f"shift {s_shift * MM_TO_UM:.3g} um > {0.1 * field_min * MM_TO_UM:.3g} um "
                        f"(a tenth "
                        f"of the measured field); the design has no lateral structure in the "
                        f"field to register to (wrong units or origin?)")
    elif s_shift > max_shift:
        warns.append(f"the lateral registration is uncertain: standard uncertainty "
                     f"{s_shift * MM_TO_UM:.3g} um > {max_shift * MM_TO_UM:.3g} um")
    if s_rot > max_rotation_sigma_rad and not free_turn:
        warns.append(f"the rotation about z is uncertain: standard uncertainty "
                     f"{np.degrees(s_rot):.3g} deg > {np.degrees(max_rotation_sigma_rad):.3g} deg")
    return {"ok": not refusals, "refusals": refusals, "warnings": warns, "overlap": ov,
            "residual_rms_mm": rms, "residual_limit_mm": limit, "expected_sq_mm": expected_sq_mm,
            "shift_mm": [float(registration.get("tx_mm", 0.0)), float(registration.get("ty_mm", 0.0))],
            "rotation_rad": float(registration.get("gamma_rad", 0.0)), "uncertainty": unc,
            "free_rotation": free_turn,
            "thresholds": {"min_overlap": min_overlap, "max_residual_ratio": max_residual_ratio,
                           "residual_floor_mm": residual_floor_mm, "max_shift_sigma_mm": max_shift,
                           "max_rotation_sigma_rad": max_rotation_sigma_rad}}
