"""Burrs on the sharp edges of a machined surface: where they form, their height and shape.

Two ways to set them:

* **from the material** (:func:`material_burrs`, what the processes do when a
  ``[material]`` is set): a burr model from the micro-cutting burr literature.  Gillespie
  & Blotter [2]_ name three mechanisms (lateral deformation, chip rollover at the exit,
  tearing); Hashimura, Chang & Dornfeld [3]_ show the burr growing with the uncut chip
  thickness, shrinking as the exit angle opens and following the workpiece's ductility
  (a brittle workpiece breaks out instead).  The model keeps exactly those dependences::

      h_b = C * min(1, A / A_ref) * h_u * g,     g = clip(turn / (pi / 2), 0, 1)

  with h_u the uncut chip thickness of the finishing cut, ``turn`` = pi - psi the angle
  by which the surface turns at the edge (psi the exit angle between the cutting
  direction and the exit face: psi = pi / 2 at a square edge, g = 1; psi -> pi at a smooth
  exit, no burr), A the elongation at break (ductility), A_ref = 10 % and C the burr
  coefficient (assumed 1, range 0.5-1.5: no source gives it for diamond cutting; the
  linear g is an assumed shape).  Lateral (side) burrs along the passes and exit
  (rollover) burrs across them take the same law with the turn measured across the edge.
  The plastic side flow of the ploughed material at the cusps (a burr of (1 - kappa) h_min
  where two passes meet) is the material kernel's (:mod:`._cutting`).
* **given** (:func:`apply_burrs`, ``[artifacts.burrs] height``): a ridge of the height
  the scene gives (an override of the model; no formation physics).

Both put the same ridge on the edges:

* where: on *sharp edges* of the machined surface (``edges_from="machined"``, what the
  processes use: the edges where the machine cut them, moved by servo lag), or of the
  design.  An edge is a grid line where the slope difference between neighbouring pixel
  pairs exceeds ``edge_angle_deg`` and is a local maximum across the edge; on the
  machined surface the feed marks are smoothed out first (Gaussian of standard deviation
  ``smoothing``).  The turn at an edge is measured between the slopes a few pixels to
  either side (beyond the smoothing), so a smoothed edge keeps its angle.
* shape: a ridge centred on the edge, h(d) = height * v * cos^2(pi d / width) for the
  distance d < width / 2 from the edge, 0 beyond (material is pushed up, never removed).
* variation: v = max(0, 1 + variation * g(x, y)) with g a unit-variance Gaussian random
  field of correlation length ``correlation_length`` (default 4 x width), built from 64
  random Fourier modes drawn from ``simulation.seed``; g depends on the position in mm
  only, so the same seed gives the same burr at the same place on any grid.
* assumptions: the burr does not change the cut elsewhere (it is added after the
  envelope) and the edge position is resolved to one pixel.

References
----------
.. [1] C. Zhang, C.-F. Cheung, X. Liang, B. Bulla, "A theoretical and experimental
       investigation of high-frequency ultrasonic vibration-assisted sculpturing of
       optical microstructures," Applied Sciences 12(21), 10937 (2022).
.. [2] L. K. Gillespie, P. T. Blotter, "The formation and properties of machining burrs,"
       Journal of Engineering for Industry 98(1), 66 (1976).
.. [3] M. Hashimura, Y. P. Chang, D. Dornfeld, "Analysis of burr formation mechanism in
       orthogonal cutting," Journal of Manufacturing Science and Engineering 121(1), 1-7
       (1999). :DOI:`10.1115/1.2830569`
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import cast

import numpy as np
from numpy.typing import ArrayLike
from ..core.lazy import lazy_module

from ..core.errors import InputError, check_range
from ..core.units import MM_TO_UM
from ._burr_bound import SAMPLE, no_edge_possible
from ._burr_kernels import (_BOUND_ABS, _bound_limit, edge_turn_maps, edge_turn_window, gaussian_nearest,
                            gaussian_nearest_cross, gaussian_weights)

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["sharp_edges", "edge_turns", "machined_sharp_edges", "burr_map", "apply_burrs",
           "material_burrs", "material_burr_block", "material_burr_facts", "burr_halo", "burr_height_law",
           "BURR_WIDTH_PER_CHIP"]

#: full base width of a burr per unit uncut chip thickness (assumed, range 2-5)
BURR_WIDTH_PER_CHIP = 3.0

_MODES = 64


def _edge_masks(z, *, pixel: float, edge_angle_deg: float):
    """Per grid axis (0: along y, 1: along x): the edge pixels of that axis (the turn
    between neighbouring pixel pairs exceeds ``edge_angle_deg`` and is a local maximum
    along the axis; ``edge_angle_deg = 0``: every local maximum of the turn) and the
    slope between neighbouring pixels (s[i] between i and i + 1, along the axis)."""
    out: list[tuple[np.ndarray, np.ndarray | None]] = []
    for axis in (0, 1):
        zz = np.moveaxis(z, axis, 0)
        if zz.shape[0] < 3:
            out.append((np.zeros(z.shape, dtype=bool), None))
            continue
        s = np.diff(zz, axis=0) / pixel                     # slope between pixels i, i+1
        j = np.abs(np.arctan(s[1:]) - np.arctan(s[:-1]))    # turn at pixel i (1..n-2), rad
        j = np.nan_to_num(j, nan=0.0)
        jp = np.pad(j, ((1, 1),) + ((0, 0),) * (j.ndim - 1))
        peak = (j > math.radians(edge_angle_deg)) & (j >= jp[:-2]) & (j >= jp[2:]) & (j > 0)
        m = np.zeros(zz.shape, dtype=bool)
        m[1:-1] = peak
        out.append((np.moveaxis(m, 0, axis), s))
    return out


def _check_map(z, pixel, edge_angle_deg):
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2:
        raise InputError(f"design must be a 2-D array, received shape {z.shape}")
    check_range("pixel", pixel, 0.0, None, lo_open=True)
    check_range("edge_angle_deg", edge_angle_deg, 0.0, 90.0, lo_open=True, hi_open=True)
    return z


def sharp_edges(design: np.ndarray, *, pixel: float, edge_angle_deg: float = 1.0) -> np.ndarray:
    """Pixels on sharp edges of ``design`` (where the slope jumps).

    Parameters
    ----------
    design : (ny, nx) array, mm
    pixel : float, mm
    edge_angle_deg : float
        Smallest slope jump (deg, in (0, 90)) counted as a sharp edge.  A smooth surface of
        radius of curvature rho has a jump of about pixel / rho rad between neighbouring
        pixels, so keep pixel / rho well below this.

    Returns
    -------
    (ny, nx) bool
    """
    z = _check_map(design, pixel, edge_angle_deg)
    mask = np.zeros(z.shape, dtype=bool)
    for m, _ in _edge_masks(z, pixel=pixel, edge_angle_deg=edge_angle_deg):
        mask |= m
    return mask


def edge_turns(z: np.ndarray, *, pixel: float, edge_angle_deg: float = 1.0,
               span: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Sharp edges of ``z`` and the angle by which the surface turns at each: a local
    maximum of the pixel-to-pixel turn where the difference of the two faces' slope angles
    at the edge exceeds ``edge_angle_deg``, that difference across it (the
    larger of the two grid directions where both hold), each face's angle extrapolated
    linearly to the edge from its slopes ``span`` and 2 ``span`` pixels away (beyond the
    rounding that smoothing gives the edge).

    Parameters
    ----------
    z : (ny, nx) array, mm
    pixel : float, mm
    edge_angle_deg : float
        See :func:`sharp_edges`.
    span : int
        Pixels between the edge and the slopes compared (>= 1; beyond any smoothing).

    Returns
    -------
    edges : (ny, nx) bool
    turn : (ny, nx) float64, rad (0 off the edges)
    """
    z = _check_map(z, pixel, edge_angle_deg)
    span = int(check_range("span", span, 1, None))
    # compiled passes, threaded over rows (the same numbers as the array expressions of
    # the docstring: _burr_kernels)
    return edge_turn_maps(z, pixel=pixel, edge_angle_deg=edge_angle_deg, span=span)


def burr_height_law(chip_thickness: float, coefficient: float, turn: ArrayLike) -> np.ndarray:
    """h_b = coefficient * chip_thickness * clip(turn / (pi / 2), 0, 1) (module docstring):
    the burr on an edge where the surface turns by ``turn`` (rad; the exit angle is pi -
    turn), for an uncut chip thickness ``chip_thickness`` (mm) and the material's burr
    coefficient (ductility included)."""
    check_range("chip_thickness", chip_thickness, 0.0, 1.0)
    check_range("coefficient", coefficient, 0.0, 10.0)
    g = np.clip(np.asarray(turn, dtype=np.float64) / (math.pi / 2), 0.0, 1.0)
    return coefficient * chip_thickness * g


def _random_field(x, y, *, correlation_length: float, seed: int) -> np.ndarray:
    """Unit-variance Gaussian random field with covariance exp(-r^2 / (2 l^2)) at (x, y) mm."""
    rng = np.random.default_rng(seed)
    k = rng.normal(0.0, 1.0 / correlation_length, size=(_MODES, 2))
    phase = rng.uniform(0.0, 2 * math.pi, size=_MODES)
    arg = np.multiply.outer(x, k[:, 0]) + np.multiply.outer(y, k[:, 1]) + phase
    return math.sqrt(2.0 / _MODES) * np.cos(arg).sum(axis=-1)


def burr_map(design: np.ndarray, *, pixel: float, origin: Sequence[float] = (0.0, 0.0),
             height: float | np.ndarray, width: float,
             variation: float = 0.3, seed: int = 0, edge_angle_deg: float = 1.0,
             correlation_length: float | None = None, edges: np.ndarray | None = None,
             start: Sequence[int] = (0, 0)) -> np.ndarray:
    """Height (mm, >= 0) that burrs add on the sharp edges of ``design``.

    Parameters
    ----------
    design : (ny, nx) array, mm (row 0 = smallest y)
    pixel : float, mm
    origin : (x, y) of pixel [0, 0], mm (positions of the seeded variation)
    height : float or (ny, nx) array, mm
        Nominal burr height (>= 0), or the height of each edge pixel's burr (read on the
        edge pixels; a ridge takes the height of its nearest edge pixel).
    width : float, mm
        Full base width (>= 0; 0 gives no burrs).
    variation : float
        Relative seeded variation along the edges, in [0, 1].
    seed : int
        Seed of the variation (``simulation.seed``).
    edge_angle_deg : float
        See :func:`sharp_edges`.
    correlation_length : float, optional
        mm; default 4 x ``width``.
    edges : (ny, nx) bool, optional
        Edge pixels; detected with :func:`sharp_edges` if None.
    start : (row, column)
        Grid index of the arrays' pixel [0, 0] when they are a block of a larger grid
        whose pixel [0, 0] lies at ``origin`` (a tile: the variation is read at the same
        positions as on the whole grid, to the last bit).

    Returns
    -------
    (ny, nx) float64
    """
    per_pixel = np.ndim(height) > 0
    if not per_pixel:
        check_range("burrs.height", height, 0.0, 0.1)
    check_range("burrs.width", width, 0.0, 1.0)
    check_range("burrs.variation", variation, 0.0, 1.0)
    design = np.asarray(design, dtype=np.float64)
    out = np.zeros(design.shape)
    if per_pixel:
        height = np.asarray(height, dtype=np.float64)
        if height.shape != design.shape:
            raise InputError(f"height must be a number or have the design's shape {design.shape}, "
                             f"received {height.shape}")
    if width == 0 or (not per_pixel and height == 0):
        return out
    mask = sharp_edges(design, pixel=pixel, edge_angle_deg=edge_angle_deg) if edges is None \
        else np.asarray(edges, dtype=bool)
    if mask.shape != design.shape:
        raise InputError(f"edges must have the design's shape {design.shape}, received {mask.shape}")
    if not mask.any():
        return out
    # a ridge reaches less than width / 2 from its edge: the nearest edges are found on the
    # edges' bounding box widened by that (the same as on the whole map: scipy's transform
    # passes over the pixels without an edge, and no edge lies outside the box)
    r0, r1, c0, c1 = _edge_box(mask, int(math.ceil(width / (2 * pixel))) + 1)
    dist, (iy, ix) = ndimage.distance_transform_edt(~mask[r0:r1, c0:c1], return_indices=True)
    d = dist * pixel
    near = d < width / 2
    if not near.any():
        return out
    ell = correlation_length if correlation_length is not None else 4.0 * width
    check_range("burrs.correlation_length", ell, 0.0, None, lo_open=True)
    iy_n, ix_n = iy[near] + r0, ix[near] + c0
    ex = origin[0] + pixel * (ix_n + start[1])
    ey = origin[1] + pixel * (iy_n + start[0])
    v = np.maximum(1.0 + variation * _random_field(ex, ey, correlation_length=ell, seed=seed), 0.0)
    h = cast(np.ndarray, height)[iy_n, ix_n] if per_pixel else height
    out[r0:r1, c0:c1][near] = h * v * np.cos(np.pi * d[near] / width) ** 2
    return out


def _edge_box(mask: np.ndarray, margin: int) -> tuple[int, int, int, int]:
    """(first row, end row, first column, end column) of the True pixels of ``mask`` (some
    are) widened by ``margin`` pixels, inside the map."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    ny, nx = mask.shape
    return (max(int(rows[0]) - margin, 0), min(int(rows[-1]) + margin + 1, ny),
            max(int(cols[0]) - margin, 0), min(int(cols[-1]) + margin + 1, nx))


def _smoothed(machined, pixel: float, smoothing: float, border=(True, True, True, True), cross=None):
    """The map with NaN pixels filled from their nearest valid neighbour and smoothed by a
    Gaussian of standard deviation ``smoothing`` (mm), and the mask of pixels where no
    edge is looked for: NaN pixels and, when smoothed, the band of 3 standard deviations
    along the grid's border, where the smoothing bends the map (None for the map when all
    pixels are NaN).  ``border``: which sides of the map (first rows, last rows, first
    columns, last columns) are the grid's border (a block of a grid has the band only
    there).  ``cross`` = (window, reach): the smoothed map only where
    :func:`~._burr_kernels.edge_turn_window` reads it for that window (undefined elsewhere)."""
    check_range("smoothing", smoothing, 0.0, None)
    z = np.asarray(machined, dtype=np.float64)
    bad = ~np.isfinite(z)
    if bad.all():
        return None, bad
    if bad.any():
        idx = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
        z = z[tuple(idx)]
    if smoothing > 0:
        zc = None if cross is None else gaussian_nearest_cross(z, smoothing / pixel, *cross)
        # scipy's gaussian_filter, threaded (on the cross only where that is what is read)
        z = gaussian_nearest(z, smoothing / pixel) if zc is None else zc
        b = int(math.ceil(3 * smoothing / pixel))
        bad = bad.copy()
        if border[0]:
            bad[:b] = True
        if border[1]:
            bad[-b:] = True
        if border[2]:
            bad[:, :b] = True
        if border[3]:
            bad[:, -b:] = True
    return z, bad


def machined_sharp_edges(machined: np.ndarray, *, pixel: float, smoothing: float = 0.0,
                         edge_angle_deg: float = 1.0) -> np.ndarray:
    """Sharp edges of the *machined* surface: :func:`sharp_edges` of the map smoothed by
    a Gaussian of standard deviation ``smoothing`` (mm; 0 = none), which removes the feed
    marks so that only the edges of the cut form remain, where the machine put them
    (shifted by servo lag, not on the design's edges).  NaN pixels are filled from their
    nearest valid neighbour first."""
    z, bad = _smoothed(machined, pixel, smoothing)
    if z is None:
        return np.zeros(bad.shape, dtype=bool)
    return sharp_edges(z, pixel=pixel, edge_angle_deg=edge_angle_deg) & ~bad


def apply_burrs(machined: np.ndarray, design: np.ndarray, *, pixel: float,
                origin: Sequence[float] = (0.0, 0.0), height: float,
                width: float, variation: float = 0.3, edge_angle_deg: float = 1.0,
                correlation_length: float | None = None, seed: int = 0,
                edges_from: str = "design",
                smoothing: float = 0.0) -> tuple[np.ndarray, dict]:
    """Add burrs (:func:`burr_map`, same parameters) to ``machined``.

    ``edges_from``: ``"design"`` puts them on the design's sharp edges, ``"machined"`` on
    the machined surface's (:func:`machined_sharp_edges` with ``smoothing``, mm).

    Returns
    -------
    machined : (ny, nx) float64, mm (a new array; NaN stays NaN)
    info : dict
        The settings, the seed, the edge-pixel count and the largest added height (um):
        what goes into ``metrics["burrs"]``.
    """
    if edges_from not in ("design", "machined"):
        raise InputError(f"edges_from must be 'design' or 'machined', received {edges_from!r}")
    info = {"model": "cos^2 ridge on sharp edges, seeded multiplicative variation",
            "height_mm": height, "width_mm": width, "variation": variation,
            "edge_angle_deg": edge_angle_deg, "correlation_length_mm": correlation_length,
            "seed": int(seed), "edge_pixels": 0, "max_added_um": 0.0, "edges_from": edges_from}
    machined = np.array(machined, dtype=np.float64, copy=True)
    if height == 0 or width == 0:
        return machined, info
    if edges_from == "design":
        edges = sharp_edges(design, pixel=pixel, edge_angle_deg=edge_angle_deg)
    else:
        edges = machined_sharp_edges(machined, pixel=pixel, smoothing=smoothing,
                                     edge_angle_deg=edge_angle_deg)
        info["smoothing_mm"] = smoothing
    b = burr_map(design, pixel=pixel, origin=origin, height=height, width=width,
                 variation=variation, seed=seed, edge_angle_deg=edge_angle_deg,
                 correlation_length=correlation_length, edges=edges)
    machined += b
    info["edge_pixels"] = int(edges.sum())
    info["max_added_um"] = float(b.max() * MM_TO_UM)
    return machined, info


def material_burrs(machined: np.ndarray, design: np.ndarray, *, pixel: float,
                   origin: Sequence[float] = (0.0, 0.0), chip_thickness: float,
                   coefficient: float, variation: float = 0.3, seed: int = 0,
                   edge_angle_deg: float = 1.0, smoothing: float = 0.0,
                   width: float | None = None,
                   overwrite: bool = False) -> tuple[np.ndarray, dict]:
    """Add the burrs of the material model (module docstring) on the sharp edges of the
    machined surface.

    Parameters
    ----------
    machined, design : (ny, nx) arrays, mm
    pixel : float, mm;  origin : (x, y) of pixel [0, 0], mm
    chip_thickness : float, mm
        Uncut chip thickness h_u of the finishing cut
        (:func:`~render_inspect.machining.uncut_chip_thickness` in turning, the last
        layer's depth in sculpturing).
    coefficient : float
        The material's burr coefficient with its ductility
        (:attr:`~render_inspect.machining.MaterialResponse.burr_coefficient`).
    variation, seed, edge_angle_deg : as :func:`burr_map`
    smoothing : float, mm
        Gaussian smoothing of the machined map before the edges are found (removes the
        feed marks).
    width : float, optional
        mm; default :data:`BURR_WIDTH_PER_CHIP` x ``chip_thickness``.
    overwrite : bool
        Add the burrs into ``machined`` itself when it is a float64 array (the caller no
        longer needs the map without them): no copy of the map is made.

    Returns
    -------
    machined : (ny, nx) float64, mm (a new array unless ``overwrite``; NaN stays NaN)
    info : dict
        ``model``, ``chip_thickness_um``, ``coefficient``, ``width_um``, ``edge_pixels``,
        ``turn_max_deg`` (largest turn at an edge), ``height_max_um`` (the law's largest
        height), ``max_added_um`` (with the variation), ``seed``: ``metrics["burrs"]``.
    """
    check_range("chip_thickness", chip_thickness, 0.0, 1.0)
    w = BURR_WIDTH_PER_CHIP * chip_thickness if width is None else float(width)
    machined = (np.asarray(machined, dtype=np.float64) if overwrite
                else np.array(machined, dtype=np.float64, copy=True))
    info = material_burr_facts(chip_thickness=chip_thickness, coefficient=coefficient,
                               variation=variation, seed=seed, edge_angle_deg=edge_angle_deg,
                               smoothing=smoothing, width=w)
    if np.shape(design) != machined.shape:
        raise InputError(f"design must have the machined map's shape {machined.shape}, "
                         f"received {np.shape(design)}")
    # (the design: the map with which a map without edges is shown to be one cheaply)
    r = material_burr_block(machined, pixel=pixel, origin=origin, chip_thickness=chip_thickness,
                            coefficient=coefficient, variation=variation, seed=seed,
                            edge_angle_deg=edge_angle_deg, smoothing=smoothing, width=w,
                            reference=design)
    if r is None:
        return machined, info
    b, edges, turn, heights = r
    machined += b
    info.update(material_burr_facts(
        chip_thickness=chip_thickness, coefficient=coefficient, variation=variation, seed=seed,
        edge_angle_deg=edge_angle_deg, smoothing=smoothing, width=w, edge_pixels=int(edges.sum()),
        turn_max=turn[edges].max(), height_max=heights.max(), added_max=np.nanmax(b)))
    return machined, info


def material_burr_facts(*, chip_thickness: float, coefficient: float, variation: float, seed: int,
                        edge_angle_deg: float, smoothing: float, width: float | None = None,
                        edge_pixels: int = 0, turn_max: float = 0.0, height_max: float = 0.0,
                        added_max: float = 0.0) -> dict:
    """``metrics["burrs"]`` of :func:`material_burrs` (its settings, and the edge pixels,
    the largest turn (rad), law's height and added height (mm) it found): also what the
    sums and maxima of a simulation tile by tile give."""
    w = BURR_WIDTH_PER_CHIP * chip_thickness if width is None else float(width)
    return {"model": "material: h = C min(1, A / A_ref) h_u clip(turn / 90 deg, 0, 1) on "
                     "the machined edges",
            "chip_thickness_um": chip_thickness * MM_TO_UM, "coefficient": float(coefficient),
            "width_um": w * MM_TO_UM, "variation": variation, "edge_angle_deg": edge_angle_deg,
            "smoothing_mm": smoothing, "seed": int(seed), "edge_pixels": int(edge_pixels),
            "turn_max_deg": float(np.degrees(turn_max)) if edge_pixels else 0.0,
            "height_max_um": float(height_max * MM_TO_UM),
            "max_added_um": float(added_max * MM_TO_UM)}


def material_burr_block(machined: np.ndarray, *, pixel: float,
                        origin: Sequence[float] = (0.0, 0.0), chip_thickness: float,
                        coefficient: float, variation: float = 0.3, seed: int = 0,
                        edge_angle_deg: float = 1.0, smoothing: float = 0.0, width: float,
                        border: Sequence[bool] = (True, True, True, True),
                        start: Sequence[int] = (0, 0),
                        inner: Sequence[int] | None = None,
                        reference: np.ndarray | Callable[[], np.ndarray] | None = None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
    """The burrs of :func:`material_burrs` on ``machined`` (a whole grid, or a block of
    it): (added height, edges, turn at the edges (rad), the law's height at the edges),
    maps of the block (mm), or None where there are none.  A block of a grid: ``start`` =
    its grid index (row, column) of pixel [0, 0] (``origin`` stays the grid's) and
    ``border`` = which of its sides (first rows, last rows, first columns, last columns)
    are the grid's; on the pixels farther than :func:`burr_halo` from the block's other
    sides the result equals the whole grid's bit for bit.

    ``inner`` = (first row, end row, first column, end column) of the block: the maps of
    those pixels only (the tile of a halo'd block), the same numbers as the block's maps
    there.  The edges are then looked for only within the ridge's half width of them
    (the edges whose burrs reach them), each from the smoothed map along its row and
    column (:func:`~._burr_kernels.edge_turn_window`), and the ridges are laid on that
    window; None where no edge lies in it.  ``reference``: a map of the block close to
    ``machined`` (its design), or a function that makes it (then it is let go before the
    block is smoothed), with which a window where no pixel can be an edge is shown to be
    one before the block is smoothed (:func:`~._burr_bound.no_edge_possible`: None, as
    the search would find); without ``inner``, the whole block (read to its ends, clamped
    as the search reads it)."""
    w = float(width)
    span = _span(pixel, smoothing)
    window = None
    if inner is not None:
        # the edges whose ridges reach the inner pixels: within the ridge's half width
        ny, nx = np.shape(machined)
        a0, a1, b0, b1 = (int(v) for v in inner)
        rw = int(math.ceil(w / (2 * pixel)))
        window = (max(a0 - rw, 0), min(a1 + rw, ny), max(b0 - rw, 0), min(b1 + rw, nx))
        if reference is not None and smoothing > 0:
            ref = reference() if callable(reference) else reference
            proved = _no_edge(machined, ref, window, pixel=pixel, smoothing=smoothing, span=span,
                              edge_angle_deg=edge_angle_deg)
            del ref
            if proved:
                return None
    elif reference is not None and smoothing > 0 and np.ndim(machined) == 2 and 0 < edge_angle_deg < 90 \
            and chip_thickness and coefficient and w:
        # the whole block, read to its ends as the search reads it; the pixels of the
        # band along the grid's border (no edge is looked for there) left out
        ny, nx = np.shape(machined)
        band = int(math.ceil(3 * smoothing / pixel))
        edge = [band if f else 0 for f in border]
        ref = reference() if callable(reference) else reference
        proved = _no_edge(machined, ref, (edge[0], ny - edge[1], edge[2], nx - edge[3]), pixel=pixel,
                          smoothing=smoothing, span=span, edge_angle_deg=edge_angle_deg, ends=True)
        del ref
        if proved:
            return None
    z, bad = _smoothed(machined, pixel, smoothing, border,
                       cross=None if window is None else (window, 3 * span + 1))
    if z is None or chip_thickness == 0 or coefficient == 0 or w == 0:
        return None
    if window is not None:
        return _burr_window(machined, z, bad, cast(Sequence[int], inner), window, pixel=pixel,
                            origin=origin, chip_thickness=chip_thickness, coefficient=coefficient,
                            variation=variation, seed=seed, edge_angle_deg=edge_angle_deg,
                            width=w, span=span, start=start)
    edges, turn = edge_turns(z, pixel=pixel, edge_angle_deg=edge_angle_deg, span=span)
    edges &= ~bad
    if not edges.any():
        return None
    heights = np.where(edges, burr_height_law(chip_thickness, coefficient, turn), 0.0)
    b = burr_map(machined, pixel=pixel, origin=origin, height=heights, width=w,
                 variation=variation, seed=seed, edge_angle_deg=edge_angle_deg, edges=edges,
                 start=start)
    return b, edges, turn, heights


def _no_edge(machined, reference, window, *, pixel: float, smoothing: float, span: int,
             edge_angle_deg: float, ends: bool = False) -> bool:
    """Whether no pixel of ``window`` can be an edge of the block smoothed by ``smoothing``
    (:func:`~._burr_bound.no_edge_possible` with the edge search's own bound; ``ends``:
    the block is the whole map smoothed, read to its ends, the allowance between the
    sampled lines chosen from the margin)."""
    check_range("edge_angle_deg", edge_angle_deg, 0.0, 90.0, lo_open=True, hi_open=True)
    if np.shape(reference) != np.shape(machined):
        return False
    thr = math.radians(edge_angle_deg)
    lim, eps = _bound_limit(thr, pixel)
    return no_edge_possible(machined, reference, gaussian_weights(smoothing / pixel), window, pixel=pixel,
                            edge_angle_deg=edge_angle_deg, span=span, lim=lim, eps=eps, rel=_BOUND_ABS,
                            sample=None if ends else SAMPLE, ends=ends)


def _burr_window(machined, z, bad, inner: Sequence[int], window: Sequence[int], *, pixel: float,
                 origin: Sequence[float], chip_thickness: float, coefficient: float, variation: float,
                 seed: int, edge_angle_deg: float, width: float, span: int, start: Sequence[int]):
    """:func:`material_burr_block`'s maps on the pixels ``inner`` of the block from its
    smoothed map ``z`` and excluded pixels ``bad``: the edges on ``window``, the pixels
    within the ridge's half width of them (a ridge reaches a pixel less than width / 2
    from its edge: all of them lie in the window), and the ridges laid on that window."""
    a0, a1, b0, b1 = (int(v) for v in inner)
    r0, r1, c0, c1 = (int(v) for v in window)
    check_range("edge_angle_deg", edge_angle_deg, 0.0, 90.0, lo_open=True, hi_open=True)
    edges, turn = edge_turn_window(z, (r0, r1, c0, c1), pixel=pixel,
                                   edge_angle_deg=edge_angle_deg, span=span)
    edges &= ~bad[r0:r1, c0:c1]
    if not edges.any():
        return None
    heights = np.where(edges, burr_height_law(chip_thickness, coefficient, turn), 0.0)
    b = burr_map(machined[r0:r1, c0:c1], pixel=pixel, origin=origin, height=heights, width=width,
                 variation=variation, seed=seed, edge_angle_deg=edge_angle_deg, edges=edges,
                 start=(int(start[0]) + r0, int(start[1]) + c0))
    at = (slice(a0 - r0, a1 - r0), slice(b0 - c0, b1 - c0))
    return b[at], edges[at], turn[at], heights[at]


def _span(pixel: float, smoothing: float) -> int:
    """Pixels between a machined edge and the slopes its turn is measured from (beyond
    the smoothing's 3 standard deviations)."""
    return max(2, int(math.ceil(3 * smoothing / pixel)) + 1)


def burr_halo(pixel: float, smoothing: float, width: float, *, nan: bool = False) -> int:
    """Pixels around a block of the grid beyond which :func:`material_burrs` does not
    reach: its burrs on the block's inner pixels equal the whole grid's.

    The reach adds up from the steps of the model (sigma = ``smoothing`` / ``pixel``):

    * the burr ridge: an edge pixel less than ``width`` / 2 away, ceil(width / (2 pixel));
    * the edge and its turn: the pixel-to-pixel turn must peak within +-3 span pixels of
      the edge and each turn is taken from three pixels, 3 span + 1 with span =
      max(2, ceil(3 sigma) + 1) (:func:`edge_turns`);
    * the Gaussian smoothing: scipy truncates it at int(4 sigma + 0.5) pixels;
    * ``nan``: where the machined map has NaN pixels (the path did not reach them), each
      is filled from its nearest valid pixel before the smoothing.  A filled pixel that
      matters lies within (3 span + 1 + r_g, r_g) pixels of a valid edge candidate (r_g
      the Gaussian's reach), so its nearest valid pixel is at most the length D of that
      offset away: floor(D) + 1 more pixels.
    """
    check_range("pixel", pixel, 0.0, None, lo_open=True)
    sd = smoothing / pixel
    r_g = int(4.0 * sd + 0.5) if smoothing > 0 else 0
    reach = 3 * _span(pixel, smoothing) + 1
    halo = int(math.ceil(width / (2 * pixel))) + reach + r_g
    if nan:
        halo += int(math.floor(math.hypot(reach + r_g, r_g))) + 1
    return halo
