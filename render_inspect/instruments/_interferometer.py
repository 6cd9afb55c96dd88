"""``[render.interferometer]``: the virtual interference microscope over a height map.

Geometry from Mitsuba: the chosen channel of the height map is meshed and ray-traced
straight down (a telecentric objective) at ``s x s`` sub-sample points per camera pixel
over the field of view plus a margin, giving each sample's height and shading normal;
the mean of each pixel's sub-samples (where a pass at the pixel centres hits the
surface) gives the truth, ``height_true``, which is kept beside the frames for
evaluation and never used to measure.

Image from the imaging model (:mod:`._imaging`, docs/instrument.md): the Kirchhoff 3-D
transfer function of the objective with Koehler illumination, the source spectrum,
defocus from the scanner position, pixel integration of intensity and the camera's
noise; PSI or CSI frames come out as :class:`~render_inspect.core.Frames`.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import threading
from pathlib import Path
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from ..core.errors import InputError, MemoryBudgetError
from ..core.lazy import collector_paused
from ..core.limits import usable_cpus
from ..core import Frames, GridCoordinates, HeightMap
from ..core.section import Length, Region, Section
from ..core.units import MM_TO_NM
from ..io import read_frames_exr, write_frames_exr
from ..mesh import heightmap_mesh
from ..render import mitsuba_variant, trace_grids
from ._camera import Camera, make_fixed_patterns
from ._imaging import _by_rows, _row_blocks, _Serial, _threads_allowed
from ._kernels import pixel_means, preload
from ._transfer import acceptance_table
from ._modes import check_scan_covers, csi_frames, psi_frames
from ._microscope import Disturbances, Microscope, recommended_subsamples
from ._objectives import OBJECTIVES, objective, objective_names
from ._sampling import (ALIAS_TOLERANCE_NM, SurfaceSpectrum, alias_onset, content_subsamples,
                        grid_subsamples, pupil_cutoff)
from ._sources import led, monochromatic, spectrum_problem, spectrum_table

__all__ = [
    "MAX_AUTO_SUBSAMPLES",
    "pixel_truth",
    "DEFAULT_CSI_BANDWIDTH_NM",
    "DEFAULT_CSI_WAVELENGTH_NM",
    "DEFAULT_PSI_BANDWIDTH_NM",
    "DEFAULT_PSI_WAVELENGTH_NM",
    "Interferogram",
    "InterferometerConfig",
    "disturbances_from_config",
    "interferometer_geometry",
    "microscope_from_config",
    "read_interferogram_exr",
    "render_interferogram",
    "trace_heights",
    "write_interferogram_exr",
]

log = logging.getLogger("render_inspect")

#: Default sources (nm): PSI a filtered green LED; CSI a white LED.
DEFAULT_PSI_WAVELENGTH_NM = 550.0
DEFAULT_PSI_BANDWIDTH_NM = 10.0
DEFAULT_CSI_WAVELENGTH_NM = 600.0
DEFAULT_CSI_BANDWIDTH_NM = 120.0
#: Narrowest source band (nm) other than 0 (a line): a narrower Gaussian underflows.
MIN_BANDWIDTH_NM = 1e-3  # not a unit conversion
#: Largest number of sub-samples per pixel side chosen automatically.
MAX_AUTO_SUBSAMPLES = 6

class InterferometerConfig(Section):
    """``[render.interferometer]``: the virtual interference microscope."""
    mode: Literal["psi", "csi"] = "psi"
    objective: str = Field("20x", description="preset: magnification, NA, pixel, field; a "
                                              "registered objective (built in: 2.5x, 5x, 10x, "
                                              "20x, 50x, 100x)")
    wavelength_nm: float | None = Field(None, gt=200, lt=2000,
                                        description="source centre; default 550 (PSI) / 600 (CSI)")
    bandwidth_nm: float | None = Field(None, ge=0, lt=1000,
                                       description="source FWHM; default 10 (PSI) / 120 (CSI); 0 = a line")
    spectrum: list[tuple[Annotated[float, Field(ge=200, le=2000)], Annotated[float, Field(ge=0)]]] | None = Field(
        None, min_length=1, description="measured source spectrum [[wavelength_nm, weight], ...] (replaces "
                          "wavelength_nm / bandwidth_nm)")
    numerical_aperture: float | None = Field(None, gt=0, le=0.95, description="overrides the preset")
    illumination_na: float | None = Field(None, ge=0, le=0.95,
                                          description="condenser NA; None = filled pupil, 0 = one on-axis wave")
    central_obscuration: float = Field(0.0, ge=0, le=0.9, description="fraction of the pupil radius")
    pixel: float | None = Field(None, ge=1e-6, le=1.0, description="mm at the part; overrides the preset")
    field_of_view: Region | None = Field(None, description="mm, [x0, y0, x1, y1]")
    steps: int = Field(4, ge=3, le=16, description="PSI frames")
    step_rad: float = Field(1.5707963267948966, gt=0, lt=6.283185307179586, description="PSI phase step")
    scan_step_nm: float | None = Field(None, ge=1, le=10000,
                                       description="CSI scan step; None = lambda_eff / 8")
    frames: int | None = Field(None, ge=8, le=4096,
                               description="CSI frames; None = heights + 4.5 envelopes either side")
    subsamples: int | None = Field(None, ge=1, le=8,
                                   description="sub-samples per pixel side; None = sampled for the "
                                               "pupil's cut-off, the surface's slopes and its "
                                               "content finer than the pupil passes")
    margin: int = Field(8, ge=0, le=256, description="pixels traced around the field and cropped")
    reflectance: float = Field(1.0, gt=0, le=1, description="power reflectance of the part")
    reference_reflectance: float | None = Field(None, gt=0, le=1,
                                                description="None = reflectance (balanced beams)")
    noise: bool = True
    bit_depth: int = Field(12, ge=1, le=16)
    full_well: float = Field(20000.0, gt=0, description="electrons")
    read_noise: float = Field(5.0, ge=0, description="electrons rms")
    prnu: float = Field(0.005, ge=0, le=0.5, description="fixed gain pattern, relative rms")
    dsnu: float = Field(2.0, ge=0, description="fixed offset pattern, electrons rms")
    fill_factor: float = Field(1.0, gt=0, le=1, description="sensitive fraction of a pixel")
    exposure: float = Field(0.8, gt=0, le=10,
                            description="fraction of the full well at the brightest pixel")
    fixed_pattern_seed: int = Field(0, ge=0, description="seed of the camera's fixed pattern")
    step_error: float = Field(0.0, ge=-0.5, le=0.5, description="phase shifter / scanner scale error")
    step_nonlinearity: float = Field(0.0, ge=-0.5, le=0.5, description="quadratic phase-shifter error")
    vibration_amplitude_nm: float = Field(0.0, ge=0, le=10000)
    vibration_frequency_hz: float = Field(0.0, ge=0, le=1e6)
    frame_rate_hz: float = Field(100.0, gt=0, le=1e6)
    reference_figure_rms_nm: float = Field(0.0, ge=0, le=1000, description="reference mirror figure")
    reference_figure_correlation_mm: float = Field(0.02, gt=0)
    reference_figure_seed: int = Field(0, ge=0)
    reference_height: Length | None = Field(None, description="PSI z_ref (focus), mm (default: "
                                                              "the instrument's autofocus)")

    @field_validator("objective")
    @classmethod
    def _registered_objective(cls, v: str) -> str:
        names = objective_names()
        if v not in names:
            shown = [repr(n) for n in names]
            raise ValueError(f"must be one of {', '.join(shown[:-1])} or {shown[-1]}")
        return v

    @model_validator(mode="after")
    def _apertures(self):
        if self.spectrum is not None and (why := spectrum_problem(*zip(*self.spectrum))):
            raise ValueError(f"spectrum {why}")
        fov = self.field_of_view
        if fov is not None and not (fov[2] > fov[0] and fov[3] > fov[1]):
            raise ValueError(f"field_of_view must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0 "
                             f"(mm), received {list(fov)}")
        if self.bandwidth_nm is not None and 0 < self.bandwidth_nm < MIN_BANDWIDTH_NM:
            raise ValueError(f"bandwidth_nm must be 0 (a line) or >= "
                             f"{MIN_BANDWIDTH_NM:g} nm, received {self.bandwidth_nm!r}")
        na = (self.numerical_aperture if self.numerical_aperture is not None
              else OBJECTIVES[self.objective].numerical_aperture)
        if self.illumination_na is not None and self.illumination_na > na:
            raise ValueError(f"illumination_na must be <= the objective's NA "
                             f"({na:g}), received {self.illumination_na:g}")
        return self



@dataclass
class Interferogram(Frames):
    """What the virtual interference microscope records (:class:`~render_inspect.core.Frames`:
    the frames and the instrument settings) plus the truth it was made from, kept apart
    for evaluation: measuring uses the :class:`Frames` part only (:meth:`recorded`).

    Attributes (beyond :class:`~render_inspect.core.Frames`)
    ----------------------------------------------------------
    height_true : (H, W) float64, mm
        Ray-traced height averaged over each camera pixel's sub-samples, the surface as the
        pixel integrates it (NaN where the pixel centre's ray missed); texture finer than
        the pixel averages out instead of aliasing into the truth.
    accepted_fraction : (H, W) float32
        The object beam alone, as a fraction of a mirror's (the geometric acceptance of the
        pixel's facets).
    surface : {"design", "machined"}
    """

    height_true: np.ndarray | None = None
    accepted_fraction: np.ndarray | None = None
    surface: str = "machined"

    def recorded(self) -> Frames:
        """The frames and settings alone (what an instrument's file would hold)."""
        return Frames(**{f.name: getattr(self, f.name) for f in dataclasses.fields(Frames)})

    def header(self) -> dict:
        h = super().header()
        h["surface"] = self.surface
        return h


# -------------------------------------------------------------------------- settings
def microscope_from_config(icfg: InterferometerConfig) -> Microscope:
    """The :class:`Microscope` of ``[render.interferometer]`` (objective preset with its
    overrides, source, illumination, camera)."""
    obj = objective(icfg.objective, numerical_aperture=icfg.numerical_aperture,
                    pixel=icfg.pixel, central_obscuration=icfg.central_obscuration)
    csi = icfg.mode == "csi"
    if icfg.spectrum is not None:
        source = spectrum_table(*zip(*icfg.spectrum))
    else:
        wl = icfg.wavelength_nm or (DEFAULT_CSI_WAVELENGTH_NM if csi else DEFAULT_PSI_WAVELENGTH_NM)
        bw = icfg.bandwidth_nm
        if bw is None:
            bw = DEFAULT_CSI_BANDWIDTH_NM if csi else DEFAULT_PSI_BANDWIDTH_NM
        if csi and bw == 0:
            raise InputError("render.interferometer.bandwidth_nm must be > 0 for CSI (a line has "
                             "no coherence envelope to find), received 0")
        source = led(wl, bandwidth_nm=bw) if csi else monochromatic(wl, bandwidth_nm=bw)
    camera = Camera(full_well_e=icfg.full_well, read_noise_e=icfg.read_noise,
                    bit_depth=icfg.bit_depth, prnu=icfg.prnu, dsnu_e=icfg.dsnu,
                    fill_factor=icfg.fill_factor, exposure=icfg.exposure,
                    fixed_pattern_seed=icfg.fixed_pattern_seed, noise=icfg.noise)
    ref = icfg.reference_reflectance if icfg.reference_reflectance is not None else icfg.reflectance
    return Microscope(objective=obj, source=source, camera=camera,
                      illumination_na=icfg.illumination_na, reflectance=icfg.reflectance,
                      reference_reflectance=ref)


def disturbances_from_config(icfg: InterferometerConfig) -> Disturbances:
    """The :class:`Disturbances` of ``[render.interferometer]``."""
    return Disturbances(step_error=icfg.step_error, step_nonlinearity=icfg.step_nonlinearity,
                        vibration_amplitude_nm=icfg.vibration_amplitude_nm,
                        vibration_frequency_hz=icfg.vibration_frequency_hz,
                        frame_rate_hz=icfg.frame_rate_hz,
                        reference_figure_rms_nm=icfg.reference_figure_rms_nm,
                        reference_figure_correlation_mm=icfg.reference_figure_correlation_mm,
                        reference_figure_seed=icfg.reference_figure_seed)


# ---------------------------------------------------------------------------- geometry
def interferometer_geometry(heightmap: GridCoordinates, icfg: InterferometerConfig) -> dict:
    """Resolve the objective preset and overrides into plain numbers.

    Returns a dict with ``objective``, ``numerical_aperture``, ``pixel`` (mm), ``nx``,
    ``ny``, ``origin`` (x, y of the first pixel centre, mm), ``window``
    ``[x0, y0, x1, y1]`` (pixel edges, mm), ``margin`` (pixels traced around the window,
    cropped after imaging), ``trace_window`` (the window with the margin),
    ``wavelength_nm``, ``bandwidth_nm``.  The default field of view is the preset's,
    centred on the height map and clipped to it (to the span of its pixel centres,
    which the mesh covers).
    """
    preset = OBJECTIVES[icfg.objective]
    na = float(icfg.numerical_aperture if icfg.numerical_aperture is not None
               else preset.numerical_aperture)
    pixel = float(icfg.pixel if icfg.pixel is not None else preset.pixel)
    # the mesh spans the pixel centres of the height map (its vertices)
    x_lo, x_hi = float(heightmap.x[0]), float(heightmap.x[-1])
    y_lo, y_hi = float(heightmap.y[0]), float(heightmap.y[-1])
    if icfg.field_of_view is not None:
        x0, y0, x1, y1 = (float(v) for v in icfg.field_of_view)
        if not (x1 > x0 and y1 > y0):
            raise InputError(f"render.interferometer.field_of_view must be [x0, y0, x1, y1] with "
                             f"x1 > x0 and y1 > y0 (mm), got {list(icfg.field_of_view)}")
        if x0 < x_lo - 1e-9 or x1 > x_hi + 1e-9 or y0 < y_lo - 1e-9 or y1 > y_hi + 1e-9:
            raise InputError(f"render.interferometer.field_of_view {list(icfg.field_of_view)} mm must "
                             f"lie inside the height map (x {x_lo:g}..{x_hi:g}, "
                             f"y {y_lo:g}..{y_hi:g} mm); enlarge simulation.region or move it")
    else:
        fov = preset.field_of_view
        cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
        x0, x1 = max(x_lo, cx - fov / 2), min(x_hi, cx + fov / 2)
        y0, y1 = max(y_lo, cy - fov / 2), min(y_hi, cy + fov / 2)
    nx = math.floor((x1 - x0) / pixel + 1e-9)
    ny = math.floor((y1 - y0) / pixel + 1e-9)
    if nx < 2 or ny < 2:
        raise InputError(f"render.interferometer.pixel = {pixel:g} mm leaves fewer than 2 x 2 "
                         f"camera pixels in the field of view {[x0, y0, x1, y1]} mm: use a "
                         f"smaller pixel or a larger field_of_view")
    if nx * ny > 4096 * 4096:
        raise MemoryBudgetError(f"the interferogram would have {nx} x {ny} pixels (> 4096 x 4096): "
                                f"raise render.interferometer.pixel (got {pixel:g} mm) or shrink "
                                f"field_of_view")
    # centre the pixel grid in the window
    x0 += ((x1 - x0) - nx * pixel) / 2
    y0 += ((y1 - y0) - ny * pixel) / 2
    m = int(icfg.margin)
    csi = icfg.mode == "csi"
    wl = icfg.wavelength_nm or (DEFAULT_CSI_WAVELENGTH_NM if csi else DEFAULT_PSI_WAVELENGTH_NM)
    bw = icfg.bandwidth_nm
    if bw is None:
        bw = DEFAULT_CSI_BANDWIDTH_NM if csi else DEFAULT_PSI_BANDWIDTH_NM
    return {"objective": icfg.objective, "numerical_aperture": na, "pixel": pixel,
            "nx": nx, "ny": ny, "origin": (x0 + pixel / 2, y0 + pixel / 2),
            "window": [x0, y0, x0 + nx * pixel, y0 + ny * pixel], "margin": m,
            "trace_window": [x0 - m * pixel, y0 - m * pixel, x0 + (nx + m) * pixel,
                             y0 + (ny + m) * pixel],
            "wavelength_nm": float(wl), "bandwidth_nm": float(bw)}


def trace_heights(heightmap: HeightMap, geom: dict, *, surface: str = "machined",
                  subsamples: int = 2, meshed: Callable[[], object] | None = None
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray-trace the mesh of one height-map channel through the objective.

    Rays that pass exactly through a mesh edge or vertex can slip between the two
    triangles (floating point), and camera pixels often sit exactly on height-map
    vertices.  The rays are therefore cast a small, odd offset ``(dx, dy)`` (about 1-3 %
    of the finer of the two grids) away from the nominal points, and the height is carried
    back to the nominal point along the hit triangle's plane (its geometric normal):
    exact for points of that triangle, the height at the sample position otherwise.

    The sub-samples cover ``geom["trace_window"]`` (the field plus ``geom["margin"]``
    pixels each side; outside the height map the rays miss: NaN); the pixel centres cover
    the field only.  ``meshed``, when given, is called once the mesh is made, before the
    ray tracer builds its tree.

    Returns
    -------
    h_sub : ((ny + 2 m) s, (nx + 2 m) s) float64, mm (NaN where missed); row 0 = smallest y
    n_sub : ((ny + 2 m) s, (nx + 2 m) s, 3) float32, unit shading normal ((0, 0, 0) where missed)
    h_centre : (ny, nx) float64, mm, the height at the pixel centres (NaN where missed)
    """
    if surface not in ("design", "machined"):
        raise InputError(f"surface must be 'design' or 'machined', got {surface!r}")
    s = int(subsamples)
    m = int(geom.get("margin", 0))
    x0, y0, x1, y1 = geom.get("trace_window", geom["window"])
    # the mesh: the traced window clipped to the height map (its vertices' span)
    cx0, cy0 = max(x0, float(heightmap.x[0])), max(y0, float(heightmap.y[0]))
    cx1, cy1 = min(x1, float(heightmap.x[-1])), min(y1, float(heightmap.y[-1]))
    gm = heightmap_mesh(heightmap, channel=surface, exaggeration=1.0, window=[cx0, cy0, cx1, cy1],
                        margin=2, normals=True)
    z_off = gm.metadata["z_offset_mm"]
    if meshed is not None:  # (called once the mesh is made, before the ray tracer's tree)
        meshed()
    z_top = float(gm.vertices[:, 2].max()) + max(1.0, 10 * geom["pixel"])
    fine = min(heightmap.pixel, geom["pixel"] / s)
    coord = max(abs(x0), abs(x1), abs(y0), abs(y1), 1e-3)
    ulp = float(np.spacing(np.float32(coord)))
    dx = max(0.0123 * fine, 64 * ulp)
    dy = max(0.0271 * fine, 150 * ulp)

    nx, ny = geom["nx"], geom["ny"]
    wx0, wy0, wx1, _ = geom["window"]
    grids = [{"x0": x0, "y0": y0, "width_mm": x1 - x0, "nx": (nx + 2 * m) * s, "ny": (ny + 2 * m) * s},
             {"x0": wx0, "y0": wy0, "width_mm": wx1 - wx0, "nx": nx, "ny": ny}]
    # (the copies of the traced normals and the heights' float64 pass over blocks of rows
    # in threads, in a process's main thread: the same arrays)
    workers = min(2, usable_cpus()) if _threads_allowed() else 1
    traced = trace_grids(gm, grids, z_top=z_top, shift=(dx, dy), full_normals=True,
                         workers=workers)
    z_sub, n_sub = traced[0]
    h_sub = np.empty(z_sub.shape, dtype=np.float64)  # (float64(z) + z_off, in one pass)
    pool = ThreadPoolExecutor(max_workers=workers) if workers > 1 else None
    try:
        _by_rows(pool, _row_blocks(z_sub.shape[0], workers),
                 lambda r: np.add(z_sub[r], z_off, out=h_sub[r], dtype=np.float64))
    finally:
        if pool is not None:
            pool.shutdown()
    # a sample outside the height map's own span is not part of the surface
    xs = x0 + (np.arange((nx + 2 * m) * s) + 0.5) * (x1 - x0) / ((nx + 2 * m) * s)
    ys = y0 + (np.arange((ny + 2 * m) * s) + 0.5) * (x1 - x0) / ((nx + 2 * m) * s)
    out_x = (xs < heightmap.x[0]) | (xs > heightmap.x[-1])
    out_y = (ys < heightmap.y[0]) | (ys > heightmap.y[-1])
    if out_x.any() or out_y.any():  # (a field inside the map has none)
        h_sub[out_y[:, None] | out_x[None, :]] = np.nan
    h_centre = traced[1][0].astype(np.float64) + z_off
    return h_sub, n_sub, h_centre


def _max_slope(heightmap, surface: str, window) -> float:
    """Largest surface slope (rad) inside ``window`` (a robust 99.9th percentile)."""
    x, y = heightmap.x, heightmap.y
    ix = np.nonzero((x >= window[0] - heightmap.pixel) & (x <= window[2] + heightmap.pixel))[0]
    iy = np.nonzero((y >= window[1] - heightmap.pixel) & (y <= window[3] + heightmap.pixel))[0]
    if ix.size < 2 or iy.size < 2:
        return 0.0
    z = getattr(heightmap, surface)[iy[0]:iy[-1] + 1, ix[0]:ix[-1] + 1]
    gy, gx = np.gradient(np.asarray(z, dtype=np.float64), heightmap.pixel)
    g = np.hypot(gx, gy)
    g = g[np.isfinite(g)]
    return float(math.atan(np.percentile(g, 99.9))) if g.size else 0.0


def _window_of(heightmap, surface: str, window):
    """The ``surface`` channel of ``heightmap`` over ``window`` (mm) and a pixel around."""
    x, y = heightmap.x, heightmap.y
    ix = np.nonzero((x >= window[0] - heightmap.pixel) & (x <= window[2] + heightmap.pixel))[0]
    iy = np.nonzero((y >= window[1] - heightmap.pixel) & (y <= window[3] + heightmap.pixel))[0]
    if ix.size < 2 or iy.size < 2:
        return None
    return np.asarray(getattr(heightmap, surface)[iy[0]:iy[-1] + 1, ix[0]:ix[-1] + 1])


def surface_sampling(heightmap: HeightMap, surface: str, geom: dict, mic: Microscope, *, s_rec: int,
                     fixed: bool = False) -> tuple[int, dict]:
    """Sub-samples per pixel side for ``heightmap``'s ``surface`` channel over the traced
    window (:mod:`._sampling`): at least ``s_rec`` (the pupil and the slopes'), more where
    the surface holds content that would fold into the pupil (at most
    :data:`MAX_AUTO_SUBSAMPLES`); ``fixed`` keeps ``s_rec`` (the user's).  Returns ``s``
    and the diagnostic: ``aliased_rms_nm`` (the content that still folds into the pupil),
    ``alias_onset_per_mm``, ``pupil_cutoff_per_mm``, ``map_pixel_mm``, ``tolerance_nm``,
    ``chosen_from``."""
    pixel = float(geom["pixel"])
    s_grid = grid_subsamples(pixel, heightmap.pixel, mic)
    info = {"map_pixel_mm": float(heightmap.pixel), "pupil_cutoff_per_mm": pupil_cutoff(mic),
            "tolerance_nm": ALIAS_TOLERANCE_NM,
            "chosen_from": "set (render.interferometer.subsamples)" if fixed
            else "the pupil and the slopes"}
    s = int(s_rec)
    rms = 0.0
    z = None if s_grid <= s else _window_of(heightmap, surface, geom["trace_window"])
    if z is not None:
        spec = SurfaceSpectrum(z, heightmap.pixel)
        s_max = s if fixed else max(s, min(s_grid, MAX_AUTO_SUBSAMPLES))
        s, rms = content_subsamples(pixel, mic, spec, s_min=s, s_max=s_max)
        if s > s_rec:
            info["chosen_from"] = "the surface's content"
    info.update(aliased_rms_nm=float(rms), alias_onset_per_mm=alias_onset(pixel, s, mic),
                subsamples=int(s))
    if rms > ALIAS_TOLERANCE_NM:
        log.warning("the interferometer samples the surface with %d x %d sub-samples per "
                    "pixel: %.3g nm rms of the surface's content finer than that folds into "
                    "the pupil and comes back as a false coarse pattern (set "
                    "render.interferometer.subsamples higher%s)", s, s, rms,
                    "" if fixed else f", up to {s_grid}")
    return s, info


def _preload_thread(mic: Microscope, shape: tuple[int, int]) -> threading.Thread:
    """A thread (not started) that loads what the imaging model of ``mic`` uses after the
    ray tracing (:func:`~._kernels.preload`, the facets' acceptance table) and makes the
    camera's fixed patterns over its ``shape`` pixels.  A failure there is left to the
    model's own call of the same code, which reports it."""

    def run():
        try:
            # (the collector paused while numba and SciPy are imported: their modules
            # live as long as the process)
            with collector_paused():
                preload()
            acceptance_table(mic.na, mic.na_ill, mic.obscuration)
            make_fixed_patterns(mic.camera, shape)
        except Exception:  # (the model's own call raises it again, where it is reported)
            pass

    return threading.Thread(target=run, name="render_inspect-preload", daemon=True)


# -------------------------------------------------------------------------- top level
def render_interferogram(heightmap: HeightMap, icfg: InterferometerConfig | None = None, *,
                         surface: str = "machined", seed: int = 0) -> Interferogram:
    """Render the virtual interference microscope over a height map.

    Parameters
    ----------
    heightmap : HeightMap
        Heights in mm; its ``design`` or ``machined`` channel is meshed and ray-traced.
    icfg : InterferometerConfig, optional
        ``[render.interferometer]`` (defaults when None).
    surface : {"machined", "design"}
    seed : int
        Seed of the camera's temporal noise and of the vibration (recorded in the result).

    Returns
    -------
    Interferogram
        The frames and settings, with ``height_true`` and ``accepted_fraction`` beside.
    """
    if icfg is None:
        icfg = InterferometerConfig()
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    if surface not in ("design", "machined"):
        raise InputError(f"surface must be 'design' or 'machined', got {surface!r}")
    geom = interferometer_geometry(heightmap, icfg)
    mic = microscope_from_config(icfg)
    dist = disturbances_from_config(icfg)
    if icfg.subsamples is not None:
        s_rec = int(icfg.subsamples)
    else:
        slope = _max_slope(heightmap, surface, geom["trace_window"])
        s_rec = min(recommended_subsamples(geom["pixel"], mic, max_slope=slope), MAX_AUTO_SUBSAMPLES)
    if icfg.mode == "csi" and icfg.frames is not None:
        # a scan that cannot reach the heights is refused before anything is traced
        z = _window_of(heightmap, surface, geom["trace_window"])
        if z is not None and np.isfinite(z).any():
            check_scan_covers(float(np.nanmin(z)), float(np.nanmax(z)), mic,
                              scan_step_nm=icfg.scan_step_nm, frames=int(icfg.frames))
    s, sampling = surface_sampling(heightmap, surface, geom, mic, s_rec=s_rec,
                                   fixed=icfg.subsamples is not None)
    # the compiled passes and the libraries the frames use next are loaded in a thread
    # while the ray tracer builds its tree and traces (it lets go of the interpreter),
    # started once the mesh is made (whose array work would otherwise share the
    # interpreter with it); only in a process's main thread, as the model's other threads
    loading = _preload_thread(mic, (geom["ny"], geom["nx"])) if _threads_allowed() else None
    try:
        h_sub, n_sub, h_centre = trace_heights(heightmap, geom, surface=surface, subsamples=s,
                                               meshed=None if loading is None else loading.start)
    finally:
        if loading is not None and loading.ident is not None:  # (started)
            loading.join()
    diag: dict = {}
    common = {"pixel": geom["pixel"], "subsamples": s, "microscope": mic, "disturbances": dist,
                  "seed": int(seed), "origin": geom["origin"], "crop": geom["margin"], "diagnostics": diag}
    # the truth (from the traced heights alone) is made in a thread beside the frames
    # (in a process's main thread; elsewhere after them: _imaging._threads_allowed)
    with (ThreadPoolExecutor(max_workers=1, thread_name_prefix="render_inspect-truth")
          if _threads_allowed() else _Serial()) as pool:
        truth = pool.submit(pixel_truth, h_sub, h_centre, s=s, margin=geom["margin"])
        if icfg.mode == "psi":
            # the focus: the user's, or the one the instrument finds on its own fringes
            z_ref = None if icfg.reference_height is None else float(icfg.reference_height)
            fr = psi_frames(h_sub, n_sub, steps=icfg.steps, step_rad=icfg.step_rad, z_ref=z_ref,
                            **common)
        else:
            fr = csi_frames(h_sub, n_sub, scan_step_nm=icfg.scan_step_nm, frames=icfg.frames,
                            **common)
        h_true, unresolved = truth.result()
    del h_sub, n_sub
    fr.settings["model"]["surface_sampling"] = sampling
    fields = {f.name: getattr(fr, f.name) for f in dataclasses.fields(Frames)}
    fields.update(variant=mitsuba_variant(), meta={
        "window_mm": geom["window"],
        "height_true": "the mean of the ray-traced sub-samples over each camera pixel (the "
                       "surface as the pixel integrates it; texture finer than the pixel "
                       "averages out instead of aliasing)",
        "height_true_unresolved_rms_nm": unresolved})
    light = np.asarray(diag["light"], dtype=np.float32) / np.float32(mic.reflectance)
    return Interferogram(**fields, height_true=h_true, accepted_fraction=light, surface=surface)


def _nanmean_quiet(a, axis):
    """``np.nanmean(a, axis)`` by NumPy's own steps (the NaNs set to 0, summed, divided by
    the count: the same sums and quotient), NaN without a warning where a mean has no
    value; ``warnings.catch_warnings``, which would silence it, is not safe in a thread."""
    arr = np.array(a, copy=True)
    mask = np.isnan(arr)
    np.copyto(arr, 0, where=mask)
    cnt = np.sum(~mask, axis=axis, dtype=np.intp)
    tot = np.sum(arr, axis=axis)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.true_divide(tot, cnt, out=tot, casting="unsafe")


def pixel_truth(h_sub: np.ndarray, h_centre: np.ndarray, *, s: int,
                margin: int) -> tuple[np.ndarray, float]:
    """The truth as the camera samples it: the mean of the ``s x s`` traced sub-samples
    over each camera pixel (NaN where the pixel centre's ray missed), and the rms (nm) of
    the texture finer than the pixel (the sub-samples about their pixel's plane; 0 with
    one sub-sample).  A point sample at the pixel centre would alias that texture into
    the truth; the mean keeps what a pixel can hold."""
    ny, nx = h_centre.shape
    m = int(margin) * s
    blk = np.asarray(h_sub[m:m + ny * s, m:m + nx * s], dtype=np.float64).reshape(ny, s, nx, s)
    # (the means in one compiled pass, the numbers of _nanmean_quiet: _kernels.pixel_means)
    mean = pixel_means(np.asarray(h_sub), s, m, (ny, nx))
    if mean is None:
        mean = _nanmean_quiet(blk, (1, 3))
    truth = np.where(np.isfinite(h_centre), np.where(np.isfinite(mean), mean, h_centre), np.nan)
    unresolved = 0.0
    if s > 1:
        u = (np.arange(s) - (s - 1) / 2)
        uu, vv = np.meshgrid(u, u)  # (s, s): row = y, col = x
        a = np.stack([np.ones(s * s), uu.ravel(), vv.ravel()], 1)
        z = blk.transpose(0, 2, 1, 3).reshape(ny * nx, s * s)
        ok = np.all(np.isfinite(z), axis=1)
        if ok.any():
            # (the pixels with all their sub-samples, gathered once: every pixel of a
            # field the surface fills, as the gathered copy lays them out)
            zt = (np.ascontiguousarray(z) if ok.all() else z[ok]).T
            coef = np.linalg.lstsq(a, zt, rcond=None)[0]
            # (the residuals and their squares written over the plane's values: the same
            # numbers without two more arrays of all the sub-samples)
            r = a @ coef
            r = np.subtract(zt, r, out=r)
            unresolved = float(np.sqrt(np.mean(np.multiply(r, r, out=r)))) * MM_TO_NM
    return truth, unresolved


def write_interferogram_exr(path: str | Path, ig: Interferogram, *,
                            scene: dict | None = None) -> Path:
    """Write ``interferogram.exr``: the frames and settings
    (:func:`~render_inspect.io.write_frames_exr`) plus the truth channels ``height_true``
    (mm, NaN where missed) and ``accepted_fraction``, and ``scene`` (JSON) in the header."""
    extra = {"height_true": ig.height_true}
    if ig.accepted_fraction is not None:
        extra["accepted_fraction"] = ig.accepted_fraction
    return write_frames_exr(path, ig, extra_channels=extra,
                            attrs={"scene": json.dumps(scene or {}, sort_keys=True, default=str),
                                   "surface": ig.surface})


def read_interferogram_exr(path: str | Path) -> Interferogram:
    """Read an ``interferogram.exr`` written by :func:`write_interferogram_exr`."""
    frames, extra, attrs = read_frames_exr(path)
    if "height_true" not in extra:
        raise InputError(f"{path}: no channel 'height_true' (channels: "
                         f"{sorted(extra) + ['intensity', 'valid']}); it holds frames only")
    fields = {f.name: getattr(frames, f.name) for f in dataclasses.fields(Frames)}
    return Interferogram(**fields, height_true=extra["height_true"].astype(np.float64),
                         accepted_fraction=extra.get("accepted_fraction"),
                         surface=str(attrs.get("surface", "")))
