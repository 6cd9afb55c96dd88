"""The virtual interference microscope (Mirau/Michelson, PSI and CSI).

Geometry from Mitsuba: the part's mesh is ray-traced through a telecentric
(orthographic) objective, straight down, at ``s x s`` sub-pixel sample points per camera
pixel (cell centres), giving each sample's hit height ``h`` and shading normal ``n``; one
more pass at the pixel centres gives ``height_true``.

Image from the two-beam interference model on top (numpy):

* phase of a sample ``phi = 2 pi OPD / lambda`` with ``OPD = 2 (h - z_ref)``;
* a sample returns light only if its slope is inside the objective's acceptance,
  ``n_z >= cos(asin(NA))``; a pixel is ``valid`` when at least half its samples return;
* a pixel's object field is the mean of ``exp(i phi)`` over its returning samples (zero
  for the others), so fringe visibility falls where fringes are dense;
* PSI frame k (phase step ``delta_k = k * step_rad``), balanced beams, 0..1:
  ``I_k = (1 + |E|^2 + 2 Re(E exp(i delta_k))) / 4``, i.e. for one sample per pixel
  ``I_k = (1 + cos(phi + delta_k)) / 2``.  The step corresponds to moving the reference
  by ``-delta_k lambda / (4 pi)``.  A 4-step retrieval is
  ``phi = atan2(I_3 - I_1, I_0 - I_2)``, ``h = z_ref + phi lambda / (4 pi)`` (mod lambda/2).
* CSI (white light, Gaussian spectrum of centre ``lambda_0`` and FWHM ``bandwidth``):
  frame j at scan position ``z_j`` (reference mirror height),
  ``I_j = (1 + <|E(k)|^2> + 2 mean_s g(OPD_s) cos(k_0 OPD_s)) / 4`` with
  ``OPD_s = 2 (h_s - z_j)``, ``g(x) = exp(-sigma_k^2 x^2 / 2)``,
  ``sigma_k = 2 pi bandwidth / lambda_0^2 / (2 sqrt(2 ln 2))``; the envelope peaks where
  ``z_j = h``.
* camera noise: shot (Poisson on ``full_well`` electrons), read (Gaussian, electrons rms)
  and quantisation to ``bit_depth`` bits, drawn from ``numpy.random.default_rng(seed)``;
  off with ``noise = false`` (then the frames are the exact model).
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import Field

from ..core.errors import InputError, MemoryBudgetError, check_positive, check_range
from ..core.frames import Frames
from ..core.section import Length, Region, Section
from ..io import read_frames_exr, write_frames_exr
from ..mesh import heightmap_mesh
from ..render import mitsuba_variant, trace_grids
from ._registry import register_instrument

__all__ = ["OBJECTIVES", "Interferogram", "InterferometerConfig", "render_interferogram",
           "interferometer_memory",
           "interferometer_geometry", "trace_heights", "interference_frames", "camera_noise",
           "write_interferogram_exr", "read_interferogram_exr"]

#: Objective presets: numerical aperture, field of view (mm, square) and camera pixels.
OBJECTIVES = {
    "5x": {"numerical_aperture": 0.13, "field_of_view_mm": 3.6, "camera_pixels": 1024},
    "10x": {"numerical_aperture": 0.30, "field_of_view_mm": 1.8, "camera_pixels": 1024},
    "20x": {"numerical_aperture": 0.40, "field_of_view_mm": 0.9, "camera_pixels": 1024},
    "50x": {"numerical_aperture": 0.55, "field_of_view_mm": 0.36, "camera_pixels": 1024},
}

#: Default wavelengths (nm): PSI quasi-monochromatic green; CSI white-light LED.
DEFAULT_PSI_WAVELENGTH_NM = 550.0
DEFAULT_CSI_WAVELENGTH_NM = 600.0
DEFAULT_CSI_BANDWIDTH_NM = 120.0
#: A pixel is valid when at least this fraction of its sub-samples returns light.
VALID_FRACTION = 0.5
#: CSI stacks longer than this, or larger than this many bytes, are refused.
MAX_CSI_FRAMES = 1024
MAX_STACK_BYTES = 2 * 1024**3

class InterferometerConfig(Section):
    """``[render.interferometer]``: the virtual interference microscope."""
    mode: Literal["psi", "csi"] = "psi"
    objective: Literal["5x", "10x", "20x", "50x"] = "20x"
    wavelength_nm: float | None = Field(None, gt=100, lt=2000, description="PSI wavelength / CSI centre")
    bandwidth_nm: float | None = Field(None, gt=0, lt=1000, description="CSI source FWHM")
    numerical_aperture: float | None = Field(None, gt=0, lt=1)
    pixel: float | None = Field(None, ge=1e-6, le=10, description="mm at the part")
    field_of_view: Region | None = Field(None, description="mm, [x0, y0, x1, y1]")
    steps: int = Field(4, ge=3, le=16, description="PSI frames")
    step_rad: float = Field(1.5707963267948966, gt=0, description="PSI phase step")
    scan_step_nm: float = Field(80.0, ge=0.1, le=1e5, description="CSI scan step")
    subsamples: int = Field(2, ge=1, le=8, description="sub-pixel samples per axis")
    noise: bool = True
    bit_depth: int = Field(12, ge=1, le=16)
    full_well: float = Field(20000.0, gt=0, description="electrons")
    read_noise: float = Field(5.0, ge=0, description="electrons rms")
    reference_height: Length | None = Field(None, description="z_ref, mm (default: mean height in the field)")


register_instrument("interferometer", InterferometerConfig)


@dataclass
class Interferogram(Frames):
    """What the virtual interference microscope records (:class:`~render_inspect.core.Frames`:
    the frames and the instrument settings) plus the truth it was made from, kept apart
    for evaluation: measuring uses the :class:`Frames` part only (:meth:`recorded`).

    Attributes (beyond :class:`~render_inspect.core.Frames`)
    ----------------------------------------------------------
    height_true : (H, W) float64, mm
        Ray-traced height at the pixel centres (NaN where the ray missed).
    accepted_fraction : (H, W) float32
        Fraction of each pixel's sub-samples inside the NA acceptance.
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


# ---------------------------------------------------------------------------- geometry
def interferometer_geometry(heightmap, icfg) -> dict:
    """Resolve the objective preset and overrides into plain numbers.

    Returns a dict with ``objective``, ``numerical_aperture``, ``pixel`` (mm),
    ``nx``, ``ny``, ``origin`` (x, y of the first pixel centre, mm), ``window``
    ``[x0, y0, x1, y1]`` (pixel edges, mm), ``wavelength_nm``, ``bandwidth_nm`` (CSI).
    The default field of view is the preset's, centred on the height map and clipped
    to it (to the span of its pixel centres, which the mesh covers).
    """
    preset = OBJECTIVES[icfg.objective]
    na = float(icfg.numerical_aperture if icfg.numerical_aperture is not None
               else preset["numerical_aperture"])
    pixel = float(icfg.pixel if icfg.pixel is not None
                  else preset["field_of_view_mm"] / preset["camera_pixels"])
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
        fov = preset["field_of_view_mm"]
        cx, cy = (x_lo + x_hi) / 2, (y_lo + y_hi) / 2
        x0, x1 = max(x_lo, cx - fov / 2), min(x_hi, cx + fov / 2)
        y0, y1 = max(y_lo, cy - fov / 2), min(y_hi, cy + fov / 2)
    nx = int(math.floor((x1 - x0) / pixel + 1e-9))
    ny = int(math.floor((y1 - y0) / pixel + 1e-9))
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
    csi = icfg.mode == "csi"
    wl = icfg.wavelength_nm if icfg.wavelength_nm is not None else (
        DEFAULT_CSI_WAVELENGTH_NM if csi else DEFAULT_PSI_WAVELENGTH_NM)
    bw = (icfg.bandwidth_nm if icfg.bandwidth_nm is not None else DEFAULT_CSI_BANDWIDTH_NM) if csi else None
    return {"objective": icfg.objective, "numerical_aperture": na, "pixel": pixel,
            "nx": nx, "ny": ny, "origin": (x0 + pixel / 2, y0 + pixel / 2),
            "window": [x0, y0, x0 + nx * pixel, y0 + ny * pixel],
            "wavelength_nm": float(wl), "bandwidth_nm": None if bw is None else float(bw)}


#: bytes per ray-traced sub-sample (heights float64 and float32, normal z, acceptance, the
#: complex field and its temporaries)
BYTES_PER_SUBSAMPLE = 48
#: bytes per camera pixel and frame (float64 frames, float32 copy with noise, the
#: written channels)
BYTES_PER_FRAME_PIXEL = 8 + 8 + 4 + 4


def interferometer_memory(geom: dict, icfg, *, mesh_cells: int = 0) -> int:
    """Bytes the interferometer needs at its peak for the geometry ``geom``
    (:func:`interferometer_geometry`): the sub-sample rays, the frames (PSI: ``steps``;
    CSI: at most :data:`MAX_CSI_FRAMES`, limited by :data:`MAX_STACK_BYTES`) and the mesh
    of the field (``mesh_cells`` height-map cells)."""
    nx, ny, s = int(geom["nx"]), int(geom["ny"]), int(icfg.subsamples)
    frames = int(icfg.steps) if icfg.mode == "psi" else MAX_CSI_FRAMES
    frame_bytes = min(frames * nx * ny * BYTES_PER_FRAME_PIXEL,
                      MAX_STACK_BYTES * BYTES_PER_FRAME_PIXEL // 4)
    return int(nx * ny * s * s * BYTES_PER_SUBSAMPLE + frame_bytes + mesh_cells * 2 * 48)


def trace_heights(heightmap, geom: dict, *, surface: str = "machined", subsamples: int = 2):
    """Ray-trace the mesh of one height-map channel through the objective.

    Rays that pass exactly through a mesh edge or vertex can slip between the two
    triangles (floating point), and camera pixels often sit exactly on height-map
    vertices.  The rays are therefore cast a small, odd offset ``(dx, dy)`` (about 1-3 %
    of the finer of the two grids) away from the nominal points, and the height is carried
    back to the nominal point along the hit triangle's plane (its geometric normal):
    exact for points of that triangle, the height at the sample position otherwise.

    Returns
    -------
    h_sub : (ny*s, nx*s) float64, mm (NaN where missed); row 0 = smallest y
    nz_sub : (ny*s, nx*s) float32, z component of the shading normal (0 where missed)
    h_centre : (ny, nx) float64, mm, the height at the pixel centres (NaN where missed)
    """
    if surface not in ("design", "machined"):
        raise InputError(f"surface must be 'design' or 'machined', got {surface!r}")
    s = int(subsamples)
    x0, y0, x1, y1 = geom["window"]
    gm = heightmap_mesh(heightmap, channel=surface, exaggeration=1.0, window=geom["window"],
                        margin=2, normals=True)
    z_off = gm.metadata["z_offset_mm"]
    z_top = float(gm.vertices[:, 2].max()) + max(1.0, 10 * geom["pixel"])
    fine = min(heightmap.pixel, geom["pixel"] / s)
    coord = max(abs(x0), abs(x1), abs(y0), abs(y1), 1e-3)
    ulp = float(np.spacing(np.float32(coord)))
    dx = max(0.0123 * fine, 64 * ulp)
    dy = max(0.0271 * fine, 150 * ulp)

    nx, ny = geom["nx"], geom["ny"]
    grid = dict(x0=x0, y0=y0, width_mm=x1 - x0)
    grids = [dict(grid, nx=nx * s, ny=ny * s)]
    if s % 2 == 0:  # the pixel centres are not sub-sample points: one more grid
        grids.append(dict(grid, nx=nx, ny=ny))
    traced = trace_grids(gm, grids, z_top=z_top, shift=(dx, dy))
    z_sub, nz_sub = traced[0]
    h_sub = z_sub.astype(np.float64) + z_off
    if s % 2 == 1:
        c = s // 2
        h_centre = h_sub[c::s, c::s].copy()
    else:
        h_centre = traced[1][0].astype(np.float64) + z_off
    return h_sub, nz_sub, h_centre


# ------------------------------------------------------------------------------- model
def _block_mean(a: np.ndarray, s: int) -> np.ndarray:
    if s == 1:
        return a
    ny, nx = a.shape[0] // s, a.shape[1] // s
    return a.reshape(ny, s, nx, s).mean(axis=(1, 3), dtype=np.result_type(a, np.float32))


def interference_frames(h_sub, nz_sub, *, subsamples: int, numerical_aperture: float,
                        wavelength_nm: float, z_ref: float, mode: str = "psi", steps: int = 4,
                        step_rad: float = math.pi / 2, bandwidth_nm: float | None = None,
                        scan_step_nm: float = 80.0):
    """Two-beam interference frames from sub-sample heights and normals (no noise).

    Parameters
    ----------
    h_sub : (H*s, W*s) array, mm (NaN = no hit);  nz_sub : same shape, normal z component
    subsamples : int, s;  numerical_aperture : float in (0, 1)
    wavelength_nm : float, PSI wavelength or CSI centre;  z_ref : float, mm
    mode : {"psi", "csi"};  steps, step_rad : PSI frames and phase step (rad)
    bandwidth_nm, scan_step_nm : CSI source FWHM and scan step (nm)

    Returns
    -------
    frames : (N, H, W) float64;  accepted : (H, W) float fraction of returning samples;
    phase_steps : (N,) rad (PSI) or empty;  scan_positions : (M,) mm (CSI) or empty;
    intensity_index : int, the frame reported as ``intensity``
    """
    check_range("numerical_aperture", numerical_aperture, 0, 1, lo_open=True, hi_open=True)
    check_range("wavelength_nm", wavelength_nm, 100, 2000)
    s = int(subsamples)
    cos_acc = math.sqrt(1.0 - numerical_aperture ** 2)
    ok = np.isfinite(h_sub) & (nz_sub >= cos_acc)
    acc = ok.astype(np.float32)
    accepted = _block_mean(acc, s)
    lam = wavelength_nm * 1e-6  # nm -> mm
    dh = np.where(ok, h_sub - z_ref, 0.0)  # mm
    if mode == "psi":
        # phase in float64, the field in complex64 (phase error < 1e-5 rad)
        phase = ((4 * math.pi / lam) * dh).astype(np.float32)
        field_ = _block_mean(acc * np.exp(1j * phase), s).astype(np.complex128)
        dc = 1.0 + np.abs(field_) ** 2
        deltas = step_rad * np.arange(int(steps))
        frames = np.stack([(dc + 2 * np.real(field_ * np.exp(1j * d))) / 4 for d in deltas])
        return frames, accepted, deltas, np.empty(0), 0
    if mode != "csi":
        raise InputError(f"render.interferometer.mode must be 'psi' or 'csi', got {mode!r}")
    bw = DEFAULT_CSI_BANDWIDTH_NM if bandwidth_nm is None else float(bandwidth_nm)
    check_range("bandwidth_nm", bw, 0, 1000, lo_open=True)
    k0 = 2 * math.pi / lam  # rad/mm
    sigma_k = 2 * math.pi * (bw * 1e-6) / lam ** 2 / (2 * math.sqrt(2 * math.log(2)))
    # <|E(k)|^2> over the spectrum: Gauss-Hermite nodes in k
    xg, wg = np.polynomial.hermite_e.hermegauss(7)
    wg = wg / wg.sum()
    dc = np.zeros(accepted.shape)
    for xi, wi in zip(xg, wg):
        k = k0 + sigma_k * xi
        dc += wi * np.abs(_block_mean(acc * np.exp(2j * k * dh), s)) ** 2
    dc += 1.0
    # envelope in scan z: g = exp(-2 sigma_k^2 (h - z)^2), standard deviation 1 / (2 sigma_k)
    lc = 4.0 / (2.0 * sigma_k)  # scan margin beyond the height range: 4 standard deviations
    finite = dh[ok]
    lo = (float(finite.min()) if finite.size else 0.0) - lc
    hi = (float(finite.max()) if finite.size else 0.0) + lc
    step = float(scan_step_nm) * 1e-6
    n = int(math.floor((hi - lo) / step)) + 1
    if n > MAX_CSI_FRAMES:
        raise MemoryBudgetError(f"the CSI scan over {(hi - lo) * 1e6:.0f} nm at "
                                f"render.interferometer.scan_step_nm = {scan_step_nm:g} needs {n} "
                                f"frames (> {MAX_CSI_FRAMES}): raise scan_step_nm or shrink the "
                                f"field of view")
    # scan positions relative to z_ref, on a grid that contains 0 (= z_ref)
    i_lo = int(math.floor(lo / step))
    rel = step * np.arange(i_lo, i_lo + n + 1)
    need = rel.size * accepted.size * 4
    if need > MAX_STACK_BYTES:
        raise MemoryBudgetError(f"the CSI stack of {rel.size} frames of {accepted.shape[1]} x "
                                f"{accepted.shape[0]} pixels needs {need / 2**30:.1f} GiB (> "
                                f"{MAX_STACK_BYTES / 2**30:.0f} GiB): raise "
                                f"render.interferometer.scan_step_nm (got {scan_step_nm:g}) or "
                                f"shrink field_of_view / raise pixel")
    frames = np.empty((rel.size,) + accepted.shape, dtype=np.float32)
    for j, zj in enumerate(rel):
        opd = 2.0 * (dh - zj)
        cross = acc * np.exp(-0.5 * (sigma_k * opd) ** 2) * np.cos(k0 * opd)
        frames[j] = (dc + 2 * _block_mean(cross, s)) / 4
    idx0 = int(np.argmin(np.abs(rel)))
    return frames, accepted, np.empty(0), z_ref + rel, idx0


def camera_noise(frames: np.ndarray, *, seed: int, full_well: float = 20000.0,
                 read_noise: float = 5.0, bit_depth: int = 12) -> np.ndarray:
    """Shot noise (Poisson, ``full_well`` electrons at intensity 1), read noise (Gaussian,
    electrons rms) and quantisation to ``bit_depth`` bits; returns 0..1 float32.
    Drawn from ``numpy.random.default_rng(seed)`` (same seed -> same noise)."""
    check_positive("full_well", full_well)
    check_range("read_noise", read_noise, 0, None)
    check_range("bit_depth", bit_depth, 1, 16)
    rng = np.random.default_rng(seed)
    e = rng.poisson(np.clip(frames, 0, None) * full_well).astype(np.float64)
    if read_noise > 0:
        e += rng.normal(0.0, read_noise, size=e.shape)
    levels = 2 ** int(bit_depth) - 1
    adu = np.clip(np.rint(e / full_well * levels), 0, levels)
    return (adu / levels).astype(np.float32)


# -------------------------------------------------------------------------- top level
def render_interferogram(heightmap, icfg=None, *, surface: str = "machined", seed: int = 0) -> Interferogram:
    """Render the virtual interference microscope over a height map.

    Parameters
    ----------
    heightmap : HeightMap
        Heights in mm; its ``design`` or ``machined`` channel is meshed and ray-traced.
    icfg : InterferometerConfig, optional
        ``[render.interferometer]`` (defaults when None).
    surface : {"machined", "design"}
    seed : int
        Seed of the camera noise (recorded in the result).

    Returns
    -------
    Interferogram
    """
    if icfg is None:
        icfg = InterferometerConfig()
    if int(seed) != seed or seed < 0:
        raise InputError(f"seed must be an integer >= 0, got {seed!r}")
    geom = interferometer_geometry(heightmap, icfg)
    s = int(icfg.subsamples)
    h_sub, nz_sub, h_centre = trace_heights(heightmap, geom, surface=surface, subsamples=s)
    if icfg.reference_height is not None:
        z_ref = float(icfg.reference_height)
    else:
        z_ref = float(np.nanmean(h_centre)) if np.isfinite(h_centre).any() else 0.0
    frames, accepted, deltas, scan, i0 = interference_frames(
        h_sub, nz_sub, subsamples=s, numerical_aperture=geom["numerical_aperture"],
        wavelength_nm=geom["wavelength_nm"], z_ref=z_ref, mode=icfg.mode, steps=icfg.steps,
        step_rad=icfg.step_rad, bandwidth_nm=geom["bandwidth_nm"], scan_step_nm=icfg.scan_step_nm)
    if icfg.noise:
        frames = camera_noise(frames, seed=int(seed), full_well=icfg.full_well,
                              read_noise=icfg.read_noise, bit_depth=icfg.bit_depth)
    else:
        frames = frames.astype(np.float32)
    return Interferogram(
        frames=frames, valid=accepted >= VALID_FRACTION, pixel=geom["pixel"],
        origin=tuple(geom["origin"]), mode=icfg.mode, wavelength_nm=geom["wavelength_nm"],
        numerical_aperture=geom["numerical_aperture"], phase_steps=np.asarray(deltas),
        scan_positions=np.asarray(scan), z_ref=z_ref, bandwidth_nm=geom["bandwidth_nm"],
        objective=icfg.objective, intensity_index=int(i0), variant=mitsuba_variant(),
        subsamples=s, seed=int(seed), noise=bool(icfg.noise),
        meta={"window_mm": geom["window"]}, height_true=h_centre,
        accepted_fraction=accepted.astype(np.float32), surface=surface)


def write_interferogram_exr(path, ig: Interferogram, *, scene: dict | None = None):
    """Write ``interferogram.exr``: the frames and settings
    (:func:`~render_inspect.io.write_frames_exr`) plus the truth channels ``height_true``
    (mm, NaN where missed) and ``accepted_fraction``, and ``scene`` (JSON) in the header."""
    extra = {"height_true": ig.height_true}
    if ig.accepted_fraction is not None:
        extra["accepted_fraction"] = ig.accepted_fraction
    return write_frames_exr(path, ig, extra_channels=extra,
                            attrs={"scene": json.dumps(scene or {}, sort_keys=True, default=str),
                                   "surface": ig.surface})


def read_interferogram_exr(path) -> Interferogram:
    """Read an ``interferogram.exr`` written by :func:`write_interferogram_exr`."""
    frames, extra, attrs = read_frames_exr(path)
    if "height_true" not in extra:
        raise InputError(f"{path}: no channel 'height_true' (channels: "
                         f"{sorted(extra) + ['intensity', 'valid']}); it holds frames only")
    fields = {f.name: getattr(frames, f.name) for f in dataclasses.fields(Frames)}
    return Interferogram(**fields, height_true=extra["height_true"].astype(np.float64),
                         accepted_fraction=extra.get("accepted_fraction"),
                         surface=str(attrs.get("surface", "")))
