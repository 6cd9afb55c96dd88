"""The interference microscope as a registered instrument: what it images
(:func:`~render_inspect.instruments.render_interferogram`), the field it looks at, the
memory it needs, and the files it writes (``interferogram.exr`` and the fringe image)
with its summary."""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..core import GridCoordinates
from ..core.limits import Driver
from ..io import atomic_write_bytes, png_bytes_with_text
from ._interferometer import (
    Interferogram,
    InterferometerConfig,
    interferometer_geometry,
    render_interferogram,
    write_interferogram_exr,
)
from ._imaging import _Serial, _threads_allowed
from ._interferometer_memory import interferometer_memory
from ._modes import LIGHT_FRACTION
from ._registry import register_instrument

__all__ = ["write_interferogram_outputs", "interferogram_summary", "interferometer_needs",
           "interferometer_field", "rendered_settings"]


def interferogram_summary(ig: Interferogram) -> dict:
    """What ``render_metrics.json`` and ``compare``'s metrics say of an interferogram.
    ``valid_fraction`` is the simulation's estimate of where light returns (the object
    beam alone at least 5 % of a mirror's: truth, not what the instrument measures);
    ``focus`` how the PSI focus was found; ``sampling`` the imaging model's sampling of
    the surface and its under-sampling diagnostics."""
    light = ig.accepted_fraction
    model = dict(ig.settings.get("model", {}))
    return {"mode": ig.mode, "objective": ig.objective, "shape": list(ig.shape),
            "frames": int(ig.frames.shape[0]), "pixel_mm": ig.pixel,
            "origin_mm": list(ig.origin), "wavelength_nm": ig.wavelength_nm,
            "bandwidth_nm": ig.bandwidth_nm, "numerical_aperture": ig.numerical_aperture,
            "subsamples": ig.subsamples, "noise": ig.noise, "seed": ig.seed,
            "z_ref_mm": ig.z_ref,
            "valid_fraction": None if light is None
            else float(np.mean(np.asarray(light) >= LIGHT_FRACTION)),
            "focus": ig.settings.get("focus"),
            "sampling": {k: model.get(k) for k in ("subsamples", "undersampled_fraction",
                                                   "surface_sampling")},
            "surface": ig.surface, "mitsuba_variant": ig.variant}


def write_interferogram_outputs(out: str | Path, ig: Interferogram, *, scene: dict | None = None) -> tuple[dict, dict]:
    """Write ``interferogram.exr`` and ``interferogram_fringes.png`` (the intensity frame as
    the camera records it, row 0 = smallest y drawn at the bottom) into ``out``; return
    the summary and no figures (the true height stays in ``heightmap.exr``: an
    instrument's outputs show what it records)."""
    out = Path(out)
    # the fringe image is encoded in a thread while the EXR is written (in a process's
    # main thread; elsewhere one after the other: _imaging._threads_allowed)
    with ThreadPoolExecutor(max_workers=1) if _threads_allowed() else _Serial() as pool:
        png = pool.submit(_fringe_png, ig)
        write_interferogram_exr(out / "interferogram.exr", ig, scene=scene)
        data = png.result()
    atomic_write_bytes(out / "interferogram_fringes.png", data)
    return interferogram_summary(ig), {}


def _fringe_png(ig) -> bytes:
    """The bytes of ``interferogram_fringes.png``: the intensity frame, row 0 = smallest
    y drawn at the bottom, grey in RGB."""
    g = np.clip(ig.intensity, 0, 1)[::-1]
    rgb = np.repeat(g[..., None], 3, axis=2)
    return png_bytes_with_text((rgb * 255 + 0.5).astype(np.uint8),
                               {"mitsuba_variant": ig.variant, "mode": ig.mode,
                                "wavelength_nm": ig.wavelength_nm,
                                "numerical_aperture": ig.numerical_aperture,
                                "pixel_size_mm": ig.pixel, "seed": ig.seed,
                                "software_version": __version__})


def rendered_settings(ig: Interferogram, icfg: InterferometerConfig) -> dict:
    """The interferometer settings as rendered: the scene's keys with the preset values
    resolved (wavelength, NA, pixel, field of view)."""
    d = icfg.model_dump(mode="json")
    d.update(wavelength_nm=ig.wavelength_nm, numerical_aperture=ig.numerical_aperture,
             pixel=ig.pixel, field_of_view=list(ig.meta.get("window_mm", [])),
             bandwidth_nm=ig.bandwidth_nm, camera_pixels=list(ig.shape))
    if d.get("reference_height") is None:
        d["reference_height"] = ig.z_ref
    if ig.mode == "psi":
        d.pop("scan_step_nm", None)
        d.pop("bandwidth_nm", None)
    else:
        d.pop("steps", None)
        d.pop("step_rad", None)
    return d


def interferometer_field(grid: GridCoordinates, icfg: InterferometerConfig) -> dict:
    """The field the interferometer images on ``grid`` (:func:`interferometer_geometry`),
    with ``settings``: ``icfg`` fixed on that field (the same image from a crop of the
    map)."""
    geom = interferometer_geometry(grid, icfg)
    window = tuple(float(v) for v in geom["window"])
    return {**geom, "window": list(window),
            "settings": icfg.model_copy(update={"field_of_view": window})}


def interferometer_needs(grid: GridCoordinates, icfg: InterferometerConfig, *,
                         slope: Callable[[Any], float] | None = None) -> tuple[int, str, list]:
    """(bytes, what, drivers) of the interferometer over ``grid`` (a height map's grid):
    the rays, frames and mesh of its field (:func:`interferometer_memory`); ``slope`` is
    called with the traced window to get the design's largest slope (rad) when the
    sub-sampling is automatic."""
    geom = interferometer_geometry(grid, icfg)
    x0, y0, x1, y1 = geom["window"]
    ny, nx = grid.shape
    cells = min(ny * nx, int(((x1 - x0) / grid.pixel + 5) * ((y1 - y0) / grid.pixel + 5)))
    max_slope = slope(geom["trace_window"]) if (icfg.subsamples is None and slope is not None) \
        else None
    nbytes = interferometer_memory(geom, icfg, mesh_cells=cells, max_slope=max_slope,
                                   grid_pixel=grid.pixel)
    rays = (f"{icfg.subsamples}^2 rays each" if icfg.subsamples is not None else
            "rays sub-sampled by the design's slopes")
    what = f"the interferometer ({geom['nx']} x {geom['ny']} camera pixels, {rays})"
    drivers = [Driver("render.interferometer.pixel", geom["pixel"], -2, "mm")]
    if icfg.subsamples is not None:  # (automatic sub-sampling has no value to lower)
        drivers.insert(0, Driver("render.interferometer.subsamples", icfg.subsamples, 2,
                                 limit=(1, 8)))
    return nbytes, what, drivers


# the interference microscope with its hooks (its schema class is defined, and first
# registered, in render_inspect.instruments._interferometer)
register_instrument("interferometer", InterferometerConfig, render=render_interferogram,
                    write=write_interferogram_outputs, field=interferometer_field,
                    memory=interferometer_needs, frames=True)
