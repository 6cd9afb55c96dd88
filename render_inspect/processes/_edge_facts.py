"""What a measured cutting edge does to a turned part: ``metrics["tool_edge"]`` and the
``tool_edge.png`` figure.

A tool tracing a surface of slope angle theta touches it at theta on the edge, so the
edge's deviation delta(theta) moves the cut surface by -delta(theta) along the normal,
-delta(theta) / cos(theta) in Z (:mod:`render_inspect.toolpath._edge`).  The facts give
that imprint predicted on the simulated region from the design's radial slope (what the
edge does to a path planned for the circular nose) and, on the simulated surface, the
form error along one radial section next to it: with ``process.compensation = "edge"``
the path is planned against the edge and the imprint cancels (the compared pair of such
a scene shows both cuts)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.grid import grid_shape
from ..core.units import MM_TO_NM
from ..design import make_surface
from ..machining import WEAR_RATES, merge_moments

from ..toolpath import edge_notes

if TYPE_CHECKING:
    from ..toolpath import EdgeProfile
    from ._machine import ProcessScene

__all__ = ["edge_facts", "edge_facts_tiled", "edge_figure_tiled", "edge_imprint",
           "check_edge_and_wear"]

#: what the contact angles are, in the notes of the angles beyond the measured edge
_CONTACT = "the design's slope on the simulated region (contact angles)"
#: pixels of the design evaluated at once by :func:`edge_facts_tiled`
BAND_PIXELS = 1 << 20  # not a unit conversion


def edge_imprint(edge: EdgeProfile, design: np.ndarray, region: Sequence[float],
                 pixel: float) -> tuple[np.ndarray, np.ndarray]:
    """(contact angle theta (rad), predicted imprint -delta(theta) / cos(theta) (mm)) on the
    grid of ``design`` (the design heights over ``region``, spacing ``pixel``)."""
    x0, y0 = region[0], region[1]
    ny, nx = design.shape
    x = x0 + pixel * np.arange(nx)
    y = y0 + pixel * np.arange(ny)
    gy, gx = (np.gradient(design, pixel) if min(ny, nx) > 1 else
              (np.zeros_like(design), np.zeros_like(design)))
    return _contact(edge, x, y, gx, gy)


def _contact(edge: EdgeProfile, x: np.ndarray, y: np.ndarray, gx: np.ndarray,
             gy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(theta, imprint) at the points (x, y) of the grid where the design's gradient is
    (gx, gy): the radial slope's angle and -delta(theta) / cos(theta)."""
    xx, yy = np.meshgrid(x, y)
    r = np.hypot(xx, yy)
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = np.where(r > 0, (gx * xx + gy * yy) / np.where(r > 0, r, 1.0), 0.0)
    theta = np.arctan(slope)
    return theta, -edge.deviation(theta) / np.cos(theta)


def _band_imprints(edge: EdgeProfile, surface: Any, region: Sequence[float], pixel: float,
                   shape: tuple[int, int], rows: int, start: int = 0, stop: int | None = None):
    """(theta, imprint) of each band of ``rows`` rows of the grid's rows ``start`` ..
    ``stop`` - 1 (default: all) in turn, equal to the same rows of :func:`edge_imprint` on
    the whole grid: each band's design is evaluated with a row beyond it either side, so
    its gradient is the whole grid's."""
    ny, nx = shape
    x = region[0] + pixel * np.arange(nx)
    if min(ny, nx) <= 1:  # (no gradient: as edge_imprint, on the whole grid)
        y = region[1] + pixel * np.arange(ny)
        design = np.broadcast_to(surface.height(x[None, :], y[:, None]), (ny, nx))
        theta, imprint = edge_imprint(edge, np.array(design, dtype=np.float64), region, pixel)
        yield theta[start:stop], imprint[start:stop]
        return
    for a in range(start, ny if stop is None else stop, rows):
        b = min(a + rows, ny if stop is None else stop)
        a0, b0 = max(a - 1, 0), min(b + 1, ny)
        y = region[1] + pixel * np.arange(a0, b0)
        band = np.array(np.broadcast_to(surface.height(x[None, :], y[:, None]), (b0 - a0, nx)),
                        dtype=np.float64)
        gy, gx = np.gradient(band, pixel)
        keep = slice(a - a0, a - a0 + (b - a))
        yield _contact(edge, x, y[keep], gx[keep], gy[keep])


def edge_facts_tiled(tool: Any, compensation: str, design: Any, region: Sequence[float],
                     pixel: float, residual: dict) -> dict:
    """``metrics["tool_edge"]`` of a map simulated tile by tile, with the keys and the
    warnings of :func:`edge_facts`: the contact angles and the predicted imprint from the
    design (``design``: the ``[design]`` section) evaluated band by band (memory bounded
    by a band), the form error (machined - design, mean removed) from the tiles'
    ``residual`` metrics (its Sz and Sq)."""
    edge = tool.edge
    surface = make_surface(design)
    shape = grid_shape(region, pixel)
    rows = max(2, BAND_PIXELS // max(int(shape[1]), 1))
    lo, hi = math.inf, -math.inf
    moments: tuple = (0, 0.0, 0.0, math.inf, -math.inf)
    for theta, imprint in _band_imprints(edge, surface, region, pixel, shape, rows):
        lo, hi = min(lo, float(np.nanmin(theta))), max(hi, float(np.nanmax(theta)))
        v = imprint[np.isfinite(imprint)]
        if v.size:  # the imprint's moments, band by band
            bm = float(v.mean())
            moments = merge_moments(moments, (v.size, bm, float(np.sum((v - bm) ** 2)),
                                              float(v.min()), float(v.max())))
    n, _, m2, imin, imax = moments
    return {**edge.to_dict(tool.half_angle),
            "compensation": compensation,
            "contact_angle_range_deg": [math.degrees(lo), math.degrees(hi)],
            "warnings": edge_notes(edge, tool.nose_radius, (lo, hi), _CONTACT),
            "imprint_predicted_pv_nm": (imax - imin if n else 0.0) * MM_TO_NM,
            "imprint_predicted_rms_nm": (math.sqrt(m2 / n) if n else 0.0) * MM_TO_NM,
            "form_error_pv_nm": float(residual["Sz_nm"]),
            "form_error_rms_nm": float(residual["Sq_nm"])}


def _rms(a) -> float:
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean((a - a.mean()) ** 2))) if a.size else 0.0


def _pv(a) -> float:
    a = a[np.isfinite(a)]
    return float(np.ptp(a)) if a.size else 0.0


def edge_facts(tool: Any, compensation: str, machined: np.ndarray, design: np.ndarray,
               region: Sequence[float], pixel: float, *,
               name: str = "") -> tuple[dict, dict]:
    """(``metrics["tool_edge"]``, {"tool_edge.png": figure spec}) of a turned part cut by
    ``tool`` (whose ``edge`` is set) with the path's ``compensation``."""
    edge = tool.edge
    theta, imprint = edge_imprint(edge, design, region, pixel)
    err = machined - design
    lo, hi = float(np.nanmin(theta)), float(np.nanmax(theta))
    facts = {**edge.to_dict(tool.half_angle),
             "compensation": compensation,
             "contact_angle_range_deg": [math.degrees(lo), math.degrees(hi)],
             # what the cut took from beyond the measurement (the ends held), a fitted
             # radius the cut does not use
             "warnings": edge_notes(edge, tool.nose_radius, (lo, hi), _CONTACT),
             # the imprint the edge leaves on a path planned for the circular nose
             "imprint_predicted_pv_nm": _pv(imprint) * MM_TO_NM,
             "imprint_predicted_rms_nm": _rms(imprint) * MM_TO_NM,
             # the simulated surface's form error (machined - design, mean removed)
             "form_error_pv_nm": _pv(err) * MM_TO_NM,
             "form_error_rms_nm": _rms(err) * MM_TO_NM}
    row = design.shape[0] // 2
    return facts, _figure(tool, facts, imprint[row], err[row], region, pixel, row, name=name)


def _figure(tool: Any, facts: dict, imprint: np.ndarray, error: np.ndarray,
            region: Sequence[float], pixel: float, row: int, *, name: str) -> dict:
    """{"tool_edge.png": figure spec}: the edge's deviation, and one section through the
    grid's ``row`` (the region's middle one) against the distance from the axis: the
    predicted ``imprint`` and the simulated form ``error`` (machined - design) of that
    row (mm), each with its mean removed."""
    edge = tool.edge
    x = region[0] + pixel * np.arange(np.asarray(error).shape[0])
    y = region[1] + pixel * row
    r = np.hypot(x, y)
    ok = np.isfinite(error)
    spec = {"kind": "tool_edge",
            "angle_deg": np.degrees(edge.angle), "delta_nm": edge.delta * MM_TO_NM,
            "half_angle_deg": math.degrees(tool.half_angle),
            "contact_deg": [facts["contact_angle_range_deg"][0], facts["contact_angle_range_deg"][1]],
            "r_mm": r, "imprint_nm": (imprint - np.nanmean(imprint)) * MM_TO_NM,
            "error_nm": (error - (np.mean(error[ok]) if ok.any() else 0.0)) * MM_TO_NM,
            "compensation": facts["compensation"],
            "title": f"{name}: the measured cutting edge ({edge.source})"}
    return {"tool_edge.png": spec}


def edge_figure_tiled(tool: Any, design: Any, region: Sequence[float], pixel: float,
                      facts: dict, residual_row: Callable[[int], np.ndarray], *,
                      name: str = "") -> dict:
    """{"tool_edge.png": figure spec} of a map simulated tile by tile: the figure
    :func:`edge_facts` draws, from what the tiled run keeps.  The section through the
    region's middle row takes the predicted imprint from the design (``design``: the
    ``[design]`` section) evaluated on that row and the rows either side of it (the whole
    grid's gradient: the same numbers as the whole map's), and the form error from
    ``residual_row(row)``: that row of machined - design as the tiles stored it (mm;
    float32 in the store, so the error agrees with the whole map's to float32's
    precision).  ``facts``: :func:`edge_facts_tiled`'s."""
    shape = grid_shape(region, pixel)
    row = int(shape[0]) // 2
    _, imprint = next(_band_imprints(tool.edge, make_surface(design), region, pixel, shape,
                                         1, row, row + 1))
    error = np.asarray(residual_row(row), dtype=np.float64)
    return _figure(tool, facts, imprint[0], error, region, pixel, row, name=name)


def check_edge_and_wear(kind: str | None, compensation: str, scene: ProcessScene) -> None:
    """The turning processes' cross-checks of the measured edge and the wear (ValueError,
    one line): ``compensation = "edge"`` needs STS and an edge; ``tool.wear`` a material
    with wear rates."""
    if compensation == "edge":
        if kind != "sts":
            raise ValueError(f"compensation = 'edge' is planned for process.kind = 'sts', received "
                             f"kind {kind!r}; use 'z' there")
        if not (scene.tool.edge_profile or scene.tool.waviness):
            raise ValueError("compensation = 'edge' plans the path against the measured cutting "
                             "edge: set tool.edge_profile or tool.waviness")
    if getattr(scene.tool, "wear", False) and scene.material.preset not in WEAR_RATES:
        raise ValueError(f"tool.wear wears the edge at the rates of material.preset, one of "
                         f"{', '.join(sorted(WEAR_RATES))}; received material.preset "
                         f"{scene.material.preset!r}")
