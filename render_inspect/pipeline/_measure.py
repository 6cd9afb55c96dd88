"""``measure``: interferometer frames on disk -> measured height (no truth), and the
evaluation of such a measurement against the truth a simulation keeps beside its frames."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.frames import Frames
from ..core.units import MM_TO_NM
from ..io import (
    STACK_EXTENSIONS,
    atomic_output_dir,
    check_frames,
    check_output_dir,
    read_exr,
    read_frame_stack,
    read_frames_exr,
    write_exr,
    write_measurement_exr,
)
from ..metrology import (
    PhaseResult,
    areal_parameters,
    evaluate_measurement,
    measure_frames,
    remove_form,
)
from ..report import analysis_summary, measurement_summary, save_map_png
from ._metrics import measurement_metrics, write_metrics

__all__ = ["measure_and_evaluate", "measurement_outputs", "read_frames", "run_measure",
           "measure_summary", "analyze_summary"]

#: the one-screen summaries of ``measure`` and ``analyze`` (the command line prints them)
measure_summary = measurement_summary
analyze_summary = analysis_summary


def read_frames(path: str | Path, *,
                settings: str | Path | dict | None = None) -> tuple[Frames, list[str]]:
    """Frames and settings from ``interferogram.exr`` (or any EXR with the frames
    channels and header) or a TIFF / PNG stack with a settings JSON.

    Returns
    -------
    frames : Frames
    ignored : list of str
        Channels of the file that are not frames (a simulation's truth): not read.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"frames file not found: {str(path)!r}")
    if path.is_file() and path.suffix.lower() == ".exr":
        if settings is not None:
            raise InputError("--settings is for TIFF / PNG stacks; an EXR carries its settings "
                             "in its header")
        frames, extra, _ = read_frames_exr(path)
        return _usable(frames, path), sorted(extra)
    if path.is_dir() or path.suffix.lower() in STACK_EXTENSIONS:
        return _usable(read_frame_stack(path, settings=settings), path), []
    raise InputError(f"{path}: frames must be an .exr, a {'/'.join(STACK_EXTENSIONS)} stack or "
                     f"a folder of frames, got {path.suffix or 'no extension'!r}")


def _usable(frames, path):
    # pixels without a finite intensity in every frame are not measured; a stack
    # with none is refused (all-NaN frames would give an empty map and exit 0)
    frames.valid = check_frames(frames.frames, frames.valid, what="frames", path=path)
    return frames


def measurement_outputs(out: Path, frames: Frames, result: PhaseResult, *,
                        source: str = "") -> dict:
    """Write ``height.exr`` (``height`` mm, NaN where not measured; ``valid``;
    ``modulation``; the instrument settings in the header) and ``height.png`` (the
    height minus its best-fit plane, nm) into ``out``; return the measurement's metrics."""
    out = Path(out)
    meta = result.meta
    attrs = {"mode": frames.mode, "algorithm": meta["algorithm"],
             "wavelength_nm": float(frames.wavelength_nm),
             "effective_wavelength_nm": float(meta["effective_wavelength_nm"]),
             "numerical_aperture": float(frames.numerical_aperture),
             "objective": str(frames.objective), "min_modulation": meta["min_modulation"],
             "z_ref_mm": float(frames.z_ref), "source": source,
             "instrument": dict(frames.settings)}
    write_measurement_exr(out / "height.exr", result.height, result.valid, pixel=frames.pixel,
                          origin=frames.origin, modulation=result.modulation, attrs=attrs)
    valid = result.valid & np.isfinite(result.height)
    metrics = {"mode": frames.mode, "algorithm": meta["algorithm"],
               "wavelength_nm": float(frames.wavelength_nm),
               "effective_wavelength_nm": float(meta["effective_wavelength_nm"]),
               "shape": list(result.height.shape), "pixel_mm": float(frames.pixel),
               "origin_mm": [float(v) for v in frames.origin],
               "valid_fraction": float(valid.mean()),
               "light_fraction": meta.get("light_fraction"),
               "saturated_pixels": int(meta.get("saturated_pixels", 0)),
               "regions": int(meta.get("regions", 0)), "min_modulation": meta["min_modulation"],
               "noise": meta.get("noise"), "z_ref_mm": float(frames.z_ref),
               "validity": "decided from the frames: not saturated, fringes above the frames' "
                           "own noise, contrast >= min_modulation"}
    if valid.sum() >= 3:
        flat, _ = remove_form(np.where(valid, result.height, np.nan), pixel=frames.pixel,
                              method="plane")
        params = areal_parameters(flat, pixel=frames.pixel)
        metrics["height"] = {"form_removed": "plane",
                             **{f"{k}_nm": float(params[k]) * MM_TO_NM
                                for k in ("Sa", "Sq", "Sp", "Sv", "Sz")}}
        x0 = frames.origin[0] - frames.pixel / 2
        y0 = frames.origin[1] - frames.pixel / 2
        ny, nx = result.height.shape
        save_map_png(out / "height.png", flat * MM_TO_NM,
                     extent=(x0, x0 + nx * frames.pixel, y0, y0 + ny * frames.pixel),
                     title=f"measured height ({frames.mode.upper()}, {meta['algorithm']}), plane removed",
                     label="height (nm)", cmap="turbo")
    return metrics


def run_measure(path: str | Path, out: str | Path, *, algorithm: str = "auto",
                settings: str | Path | None = None,
                min_modulation: float = 0.05, overwrite: bool = False) -> dict:
    """``render-inspect measure FRAMES --out DIR``: height from frames and settings alone.

    Parameters
    ----------
    path : path
        ``interferogram.exr`` (or any EXR with ``frame_000`` ... and the settings header),
        a multi-page TIFF / PNG, or a folder of frames (with a settings JSON).
    out : path
        Output folder (written atomically): ``height.exr``, ``height.png``,
        ``metrics.json``.
    algorithm : str
        PSI ``auto``, ``4step``, ``5step`` / ``hariharan``, ``lsq``; CSI ``auto``,
        ``envelope``, ``envelope+phase``.
    settings : path, optional
        Settings JSON of a TIFF / PNG stack (default beside it).
    min_modulation : float
    overwrite : bool
        Replace ``out`` even if render_inspect did not write it (``out`` is checked before
        the frames are read and replaced as a whole when the results are complete).

    Returns
    -------
    dict
        ``metrics.json``: ``measure`` (mode, algorithm, wavelengths, valid fraction,
        saturated pixels, regions, areal parameters of the height with its plane removed),
        ``timing_s``, ``software_version``, ``source``.  Channels of the input that are not
        frames (a simulation's ``height_true``) are listed under ``measure.ignored_channels``
        and never read.
    """
    t0 = time.perf_counter()
    check_output_dir(out, overwrite=overwrite, command="measure", inputs=(path, settings))
    frames, ignored = read_frames(path, settings=settings)
    t1 = time.perf_counter()
    result = measure_frames(frames, algorithm=algorithm, min_modulation=min_modulation)
    t2 = time.perf_counter()
    with atomic_output_dir(out, overwrite=overwrite, command="measure",
                           inputs=(path, settings)) as tmp:
        m = measurement_outputs(tmp, frames, result, source=str(path))
        m["ignored_channels"] = ignored
        metrics = measurement_metrics(path, m, {"read": t1 - t0, "measure": t2 - t1,
                                                "write": time.perf_counter() - t2})
        write_metrics(tmp, metrics)
    return metrics


def measure_and_evaluate(path: str | Path, *, algorithm: str = "auto", csi_refine: str = "envelope",
                         min_modulation: float = 0.05) -> tuple[PhaseResult, PhaseResult, dict]:
    """Measure the frames of ``interferogram.exr`` (frames and settings only), then evaluate
    the measurement against its ``height_true`` channel; add ``height_measured`` (mm,
    aligned to the truth by one constant per connected region, NaN where not measured)
    and ``valid_measured`` (0/1) to the file, rewriting it atomically, with the error
    metrics in the header as ``measured`` (JSON).

    Returns
    -------
    measured : PhaseResult
        What the instrument reports (no truth used).
    aligned : PhaseResult
        The same, aligned to the truth.
    metrics : dict
        :func:`~render_inspect.metrology.evaluate_measurement`'s metrics.
    """
    path = Path(path)
    frames, extra, _ = read_frames_exr(path)
    result = measure_frames(frames, algorithm=algorithm, csi_refine=csi_refine,
                            min_modulation=min_modulation)
    if "height_true" not in extra:
        raise InputError(f"{path}: no channel 'height_true' to evaluate the measurement against")
    aligned, metrics = evaluate_measurement(result, extra["height_true"])
    channels, attrs = read_exr(path)
    channels["height_measured"] = aligned.height
    channels["valid_measured"] = aligned.valid.astype(np.float32)
    attrs["measured"] = json.dumps(metrics, sort_keys=True)
    attrs["height_measured_piston"] = aligned.meta["piston"]
    write_exr(path, channels, attrs)
    return result, aligned, metrics
