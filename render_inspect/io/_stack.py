"""Frame stacks a user brings: a multi-page TIFF, or a folder of PNG / TIFF frames, plus a
small JSON file of the instrument settings; and ``height.exr``, the measured height.

Settings JSON (lengths in mm, angles in rad; only ``mode``, the pixel and the source
wavelength are required)::

    {"mode": "psi",                       # or "csi"
     "pixel_size_mm": 0.00088,            # or "pixel_size_um"
     "wavelength_nm": 550,                # centre wavelength of the source
     "effective_wavelength_nm": 573.6,    # calibrated fringe wavelength (NA factor);
                                          #   default wavelength_nm
     "phase_steps_rad": [0, 1.5708, ...], # PSI; or "step_rad": 1.5708 (default pi/2)
     "scan_positions_mm": [...],          # CSI; or "scan_start_mm" + "scan_step_nm"
     "z_ref_mm": 0.0, "origin_mm": [0, 0], "numerical_aperture": 0.4,
     "full_scale": 4095}                  # the ADC's largest value (default: the image
                                          #   type's: 255, 65535; 1.0 for float images)

Frames are read in file order (a TIFF's pages) or in name order (a folder).  Row 0 of an
image file is its top row, which is the largest y: rows are flipped so that row 0 is the
smallest y, as everywhere in the package.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import json
import math
import struct
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.frames import Frames
from ..core.units import NM_TO_MM, UM_TO_MM
from ._exr import write_exr
from ._limits import check_values, read_json_file
from ._registry import register_reader, register_writer

__all__ = ["STACK_EXTENSIONS", "read_frame_stack", "write_measurement_exr"]

#: Image files a frame stack may be made of.
STACK_EXTENSIONS = (".tif", ".tiff", ".png")


#: what a damaged or unusual image file raises in Pillow
_IMAGE_ERRORS = (OSError, ValueError, SyntaxError, EOFError, TypeError, IndexError, KeyError,
                 struct.error)


def _images(path: Path) -> list[np.ndarray]:
    from PIL import Image, ImageSequence

    files = ([path] if path.is_file() else
             sorted(p for p in path.iterdir() if p.suffix.lower() in STACK_EXTENSIONS))
    if not files:
        raise InputError(f"{path}: no frames (a multi-page TIFF, or a folder of "
                         f"{'/'.join(STACK_EXTENSIONS)} images)")
    # the sizes the files declare, against the memory budget, before any pixel is decoded
    count = 0
    try:
        for f in files:
            with Image.open(f) as im:
                count += im.size[0] * im.size[1] * int(getattr(im, "n_frames", 1))
    except (Image.DecompressionBombError, *_IMAGE_ERRORS) as err:
        raise InputError(f"frame stack {str(path)!r}: an image cannot be read "
                         f"({type(err).__name__}: {err})") from None
    check_values(path, what="frame stack", desc=f"{len(files)} image file(s) of "
                                                 f"{count} pixels in all", count=count)
    out = []
    try:
        for f in files:
            with Image.open(f) as im:
                for page in ImageSequence.Iterator(im):
                    a = np.asarray(page)
                    if a.ndim == 3:  # RGB(A): use the luminance the camera would record
                        a = a[..., :3].astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
                    out.append(a)
    except (Image.DecompressionBombError, *_IMAGE_ERRORS) as err:
        raise InputError(f"frame stack {str(path)!r}: an image cannot be read "
                         f"({type(err).__name__}: {err})") from None
    if any(a.ndim != 2 or a.dtype.kind not in "uif" for a in out):
        raise InputError(f"{path}: the frames must be grey or colour images of numbers")
    shapes = {a.shape for a in out}
    if len(shapes) != 1:
        raise InputError(f"{path}: the frames differ in size: {sorted(shapes)}")
    return out


def _full_scale(images, given):
    if given is not None:
        fs = float(given)
    else:
        dt = images[0].dtype
        fs = float(np.iinfo(dt).max) if np.issubdtype(dt, np.integer) else 1.0
    if not (math.isfinite(fs) and fs > 0):
        raise InputError(f"settings full_scale must be > 0, got {given!r}")
    return fs


@register_reader("frames", *STACK_EXTENSIONS)
def read_frame_stack(path: str | Path, settings: Any = None, **_: Any) -> Frames:
    """Read a frame stack and its settings into :class:`~render_inspect.core.Frames`.

    Parameters
    ----------
    path : path
        A (multi-page) TIFF or PNG file, or a folder of such frames.
    settings : path or dict, optional
        The settings JSON; default ``<stem>.json`` beside a file, or ``settings.json``
        inside a folder.

    Returns
    -------
    Frames
        Frames scaled to 0..1 by ``full_scale``; ``valid`` everywhere (the measurement
        decides from the fringes).
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"frame stack not found: {str(path)!r}")
    if settings is None:
        settings = path / "settings.json" if path.is_dir() else path.with_suffix(".json")
    if isinstance(settings, (str, Path)):
        sp = Path(settings)
        if not sp.is_file():
            raise InputError(f"{path}: settings file {str(sp)!r} not found; give the instrument "
                             f"settings as JSON (mode, pixel_size_mm, wavelength_nm, ...)")
        settings = read_json_file(sp, what="settings file")
    if not isinstance(settings, dict):
        raise InputError(f"settings must be a JSON object, got {type(settings).__name__}")
    try:
        return _stack_frames(path, dict(settings))
    except (TypeError, ValueError, IndexError, KeyError, OverflowError) as err:
        raise InputError(f"{path}: a settings value is not what the frames need "
                         f"({type(err).__name__}: {err})") from None


#: the keys a settings JSON may hold (the module docstring)
SETTINGS_KEYS = ("mode", "pixel_size_mm", "pixel_size_um", "wavelength_nm",
                 "effective_wavelength_nm", "phase_steps_rad", "step_rad", "scan_positions_mm",
                 "scan_start_mm", "scan_step_nm", "z_ref_mm", "origin_mm", "numerical_aperture",
                 "objective", "bandwidth_nm", "full_scale")
#: keys whose values must be numbers (or lists of numbers)
_NUMBER_KEYS = ("pixel_size_mm", "pixel_size_um", "wavelength_nm", "effective_wavelength_nm",
                "step_rad", "scan_start_mm", "scan_step_nm", "z_ref_mm", "numerical_aperture",
                "bandwidth_nm", "full_scale")


def _check_settings_keys(s: dict) -> None:
    """Unknown keys (a misspelling would be ignored), both pixel keys, text for a number:
    refused in one line."""
    import difflib

    for k in s:
        if k not in SETTINGS_KEYS:
            close = difflib.get_close_matches(str(k), SETTINGS_KEYS, n=1)
            raise InputError(f"settings: unknown key {k!r}"
                             + (f"; did you mean {close[0]!r}?" if close else
                                f"; the keys are {', '.join(SETTINGS_KEYS)}"))
    if "pixel_size_mm" in s and "pixel_size_um" in s:
        raise InputError(f"settings give both pixel_size_mm ({s['pixel_size_mm']!r}) and "
                         f"pixel_size_um ({s['pixel_size_um']!r}): give one")
    for k in _NUMBER_KEYS:
        v = s.get(k)
        if k in s and v is not None and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise InputError(f"settings {k} must be a number, received {v!r}")


def _stack_frames(path: Path, s: dict) -> Frames:
    _check_settings_keys(s)
    mode = s.get("mode")
    if mode not in ("psi", "csi"):
        raise InputError(f"settings mode must be 'psi' or 'csi', got {mode!r}")
    if "pixel_size_mm" in s:
        key, pixel = "pixel_size_mm", float(s["pixel_size_mm"])
    elif "pixel_size_um" in s:
        key, pixel = "pixel_size_um", float(s["pixel_size_um"]) * UM_TO_MM
    else:
        raise InputError("settings need pixel_size_mm (or pixel_size_um): the pixel on the part")
    if not (math.isfinite(pixel) and pixel > 0):
        raise InputError(f"settings {key} must be > 0, received {s[key]!r}")
    if "wavelength_nm" not in s:
        raise InputError("settings need wavelength_nm (the source's centre wavelength)")
    wl = float(s["wavelength_nm"])
    if not 200 <= wl <= 2000:
        raise InputError(f"settings wavelength_nm must be in [200, 2000], got {wl!r}")
    images = _images(path)
    n = len(images)
    fs = _full_scale(images, s.get("full_scale"))
    stack = np.stack([a[::-1].astype(np.float32) / np.float32(fs) for a in images])
    lam_eff = float(s.get("effective_wavelength_nm", wl))
    if not 200 <= lam_eff <= 4000:  # (the NA factor lengthens the fringes, never doubles them)
        raise InputError(f"settings effective_wavelength_nm must be in [200, 4000], got {lam_eff!r}")
    z_ref = float(s.get("z_ref_mm", 0.0))
    if mode == "psi":
        if "phase_steps_rad" in s:
            steps = np.asarray(s["phase_steps_rad"], dtype=np.float64)
        else:
            steps = float(s.get("step_rad", math.pi / 2)) * np.arange(n)
        if steps.shape != (n,):
            raise InputError(f"settings phase_steps_rad must list one step per frame ({n}), got "
                             f"{steps.size}")
        scan = z_ref - steps * lam_eff * NM_TO_MM / (4 * math.pi)
    else:
        steps = np.empty(0)
        if "scan_positions_mm" in s:
            scan = np.asarray(s["scan_positions_mm"], dtype=np.float64)
        elif "scan_step_nm" in s:
            scan = (float(s.get("scan_start_mm", 0.0))
                    + float(s["scan_step_nm"]) * NM_TO_MM * np.arange(n))
        else:
            raise InputError("CSI settings need scan_positions_mm, or scan_step_nm (and "
                             "scan_start_mm)")
        if scan.shape != (n,):
            raise InputError(f"settings scan_positions_mm must list one position per frame ({n}), "
                             f"got {scan.size}")
    origin = s.get("origin_mm", [0.0, 0.0])
    if not (isinstance(origin, (list, tuple)) and len(origin) == 2
            and all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                    for v in origin)):
        raise InputError(f"settings origin_mm must be [x, y], two finite numbers (mm), got "
                         f"{origin!r}")
    for name, v in (("effective_wavelength_nm", lam_eff), ("z_ref_mm", z_ref)):
        if not math.isfinite(v):
            raise InputError(f"settings {name} must be a finite number, got {v!r}")
    if not np.all(np.isfinite(scan)):
        raise InputError("settings: the phase steps / scan positions must be finite numbers")
    return Frames(frames=stack, valid=np.ones(stack.shape[1:], dtype=bool), pixel=pixel,
                  origin=(float(origin[0]), float(origin[1])), mode=mode, wavelength_nm=wl,
                  numerical_aperture=float(s.get("numerical_aperture", 0.0)),
                  phase_steps=steps, scan_positions=scan, z_ref=z_ref,
                  bandwidth_nm=s.get("bandwidth_nm"), objective=str(s.get("objective", "")),
                  intensity_index=0, effective_wavelength_nm=lam_eff,
                  meta={"source": str(path)},
                  settings={k: v for k, v in s.items() if k not in ("phase_steps_rad",
                                                                     "scan_positions_mm")})


@register_writer("measurement", ".exr")
def write_measurement_exr(path: str | Path, height: np.ndarray, valid: np.ndarray, *, pixel: float,
                          origin: Sequence[float], attrs: dict | None = None,
                          modulation: np.ndarray | None = None, **_: Any) -> Path:
    """Write ``height.exr``: channels ``height`` (mm, NaN where not measured), ``valid``
    (0/1) and optionally ``modulation``; header ``pixel_size_mm``, ``origin_mm``,
    ``units`` = "mm", ``software_version`` and ``attrs`` (the instrument settings, the
    algorithm ...), atomically.  Row 0 is the smallest y."""
    h = np.asarray(height, dtype=np.float64)
    v = np.asarray(valid, dtype=bool)
    ch = {"height": np.where(v, h, np.nan).astype(np.float32), "valid": v.astype(np.float32)}
    if modulation is not None:
        ch["modulation"] = np.asarray(modulation, dtype=np.float32)
    header = {"pixel_size_mm": float(pixel), "origin_mm": [float(origin[0]), float(origin[1])],
              "units": "mm", "software_version": __version__}
    for k, val in (attrs or {}).items():
        header[k] = val if isinstance(val, (str, int, float, bool)) else json.dumps(val, default=str)
    return write_exr(path, ch, header)
