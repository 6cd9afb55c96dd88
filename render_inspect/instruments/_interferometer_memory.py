"""The memory the virtual interferometer needs at its peak, from its field, sub-samples,
frames and mesh (the constants were measured as each comment says), checked against the
scene's budget before a render starts."""

from __future__ import annotations

import math

from ..core.units import MIB_TO_BYTES, MM_TO_NM
from ._interferometer import MAX_AUTO_SUBSAMPLES, InterferometerConfig, microscope_from_config
from ._microscope import recommended_subsamples
from ._sampling import grid_subsamples

__all__ = ["interferometer_memory", "BYTES_PER_SUBSAMPLE", "BYTES_PER_FRAME_PIXEL",
           "BYTES_PER_CSI_FRAME_PIXEL", "RENDERER_BYTES"]


#: bytes per ray-traced sub-sample (Mitsuba's ray and hit arrays, heights and normals,
#: the complex field of each wavelength sample and its temporaries): measured 63-68 B
#: (peak resident memory of the 20x preset, 1024 x 1024 pixels, 1 to 5 sub-samples)
BYTES_PER_SUBSAMPLE = 72
#: bytes per camera pixel and frame: PSI (a few frames: float64 frames, float32 copy with
#: noise, the written channels); CSI (a float32 stack exposed in place, and its
#: written channels): measured 8 B for 95 frames of 1024 x 1024 pixels
BYTES_PER_FRAME_PIXEL = 8 + 8 + 4 + 4
BYTES_PER_CSI_FRAME_PIXEL = 10
#: the renderer's own working memory (Mitsuba / Dr.Jit start-up, its thread pool, the
#: acceleration structure's fixed part): the intercept of the peak against the field's
#: size, measured 140-150 MiB above the loaded libraries on two machines
RENDERER_BYTES = 160 * MIB_TO_BYTES


def interferometer_memory(geom: dict, icfg: InterferometerConfig, *, mesh_cells: int = 0,
                          max_slope: float | None = None, grid_pixel: float | None = None) -> int:
    """Bytes the interferometer needs at its peak for the geometry ``geom``
    (:func:`interferometer_geometry`): the sub-sample rays over the field and its margin
    (``subsamples``; when automatic, what slopes up to ``max_slope`` (rad; default the
    steepest that returns light) ask for, or what a map of ``grid_pixel`` (mm) can hold
    that folds into the pupil (:func:`~._sampling.grid_subsamples`), at most
    :data:`MAX_AUTO_SUBSAMPLES`), the frames (PSI: ``steps``; CSI: ``frames``, or when
    automatic the least a scan needs, the coherence envelope either side of one height:
    the scan over the heights' range is checked again by the imaging model, which refuses
    stacks over :data:`~render_inspect.instruments._imaging.MAX_STACK_BYTES`) and the
    mesh of the field (``mesh_cells`` height-map cells)."""
    nx, ny, m = int(geom["nx"]), int(geom["ny"]), int(geom.get("margin", 0))
    mic = microscope_from_config(icfg)
    if icfg.subsamples is not None:
        s = int(icfg.subsamples)
    else:
        s = recommended_subsamples(float(geom["pixel"]), mic, max_slope=max_slope)
        if grid_pixel is not None:
            s = max(s, grid_subsamples(float(geom["pixel"]), float(grid_pixel), mic))
        s = min(s, MAX_AUTO_SUBSAMPLES)
    per_frame = BYTES_PER_FRAME_PIXEL
    if icfg.mode == "psi":
        frames = int(icfg.steps)
    elif icfg.frames is not None:
        per_frame = BYTES_PER_CSI_FRAME_PIXEL
        frames = int(icfg.frames)
    else:
        lam = mic.effective_wavelength_nm()
        step = icfg.scan_step_nm if icfg.scan_step_nm is not None else lam / 8
        sigma = mic.coherence_sigma()
        span_nm = 2 * 4.5 / sigma * MM_TO_NM if sigma > 0 else 4 * lam
        frames = int(math.ceil(span_nm / step)) + 1
        per_frame = BYTES_PER_CSI_FRAME_PIXEL
    rays = (nx + 2 * m) * (ny + 2 * m) * s * s
    return int(RENDERER_BYTES + rays * BYTES_PER_SUBSAMPLE
               + frames * nx * ny * per_frame + mesh_cells * 2 * 48)
