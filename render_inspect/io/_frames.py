"""``interferogram.exr``: interferometer frames and the instrument settings
(docs/formats.md): channel ``intensity`` (the frame shown), ``frame_000`` ... (every
frame), ``valid`` (1 where light returned); header ``pixel_size_mm``, ``origin_mm``,
``wavelength_nm``, ``numerical_aperture``, ``mode``, ``mitsuba_variant`` and the rest of
:meth:`~render_inspect.core.Frames.header`.  Further channels (the simulation's
``height_true``, ``accepted_fraction``, a measurement's ``height_measured``) travel beside
the frames and are returned separately by the reader."""

from __future__ import annotations

from typing import Any
import json
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.frames import Frames
from ._exr import read_exr, write_exr
from ._registry import register_writer

__all__ = ["write_frames_exr", "read_frames_exr", "FRAME_CHANNELS"]

#: channels that belong to the frames themselves
FRAME_CHANNELS = ("intensity", "valid")


@register_writer("frames", ".exr")
def write_frames_exr(path: str | Path, frames: Frames, *, extra_channels: dict | None = None,
                     attrs: dict | None = None, **_: Any) -> Path:
    """Write ``frames`` (and ``extra_channels``: name -> (H, W) array) to an EXR, atomically.

    ``attrs`` adds header attributes (e.g. ``scene`` as JSON text)."""
    ch = {"intensity": frames.intensity}
    for k, f in enumerate(frames.frames):
        ch[f"frame_{k:03d}"] = f
    ch["valid"] = np.asarray(frames.valid).astype(np.float32)
    for name, arr in (extra_channels or {}).items():
        if name in ch or name.startswith("frame_"):
            raise InputError(f"extra channel name {name!r} is taken by the frames")
        ch[name] = arr
    header = frames.header()
    header["software_version"] = __version__
    for k, v in (attrs or {}).items():
        header[k] = v if isinstance(v, (str, int, float, bool)) else json.dumps(v, default=str)
    return write_exr(path, ch, header)


def read_frames_exr(path: str | Path) -> tuple[Frames, dict, dict]:
    """Read frames written by :func:`write_frames_exr` (or by an instrument exporter using
    the same channels and header).

    Returns
    -------
    frames : Frames
    extra : dict of (H, W) arrays
        The other channels (``height_true``, ``accepted_fraction``, ...).
    attrs : dict
        The whole header.
    """
    ch, a = read_exr(path, what="frames file")
    if "intensity" not in ch and not any(k.startswith("frame_") for k in ch):
        raise InputError(f"{path}: no interferometer frames (channels: {sorted(ch)}); expected "
                         f"'frame_000', 'frame_001', ... or 'intensity'")
    for key in ("pixel_size_mm", "origin_mm", "wavelength_nm", "mode"):
        if key not in a:
            raise InputError(f"{path}: header lacks {key!r}, which measuring the frames needs")
    try:
        return _frames_from(path, ch, a)
    except (TypeError, ValueError, KeyError, IndexError) as err:
        raise InputError(f"frames file {str(path)!r}: a header attribute or channel is not what "
                         f"the frames need ({type(err).__name__}: {err})") from None


def _frames_from(path: str | Path, ch: dict, a: dict) -> tuple[Frames, dict, dict]:
    names = sorted(k for k in ch if k.startswith("frame_"))
    stack = np.stack([ch[k] for k in names]) if names else ch["intensity"][None]
    valid = ch["valid"] > 0.5 if "valid" in ch else np.ones(stack.shape[1:], dtype=bool)
    bw = float(a.get("bandwidth_nm", 0.0)) or None
    frames = Frames(
        frames=stack, valid=valid, pixel=float(a["pixel_size_mm"]),
        origin=(float(a["origin_mm"][0]), float(a["origin_mm"][1])), mode=str(a["mode"]),
        wavelength_nm=float(a["wavelength_nm"]),
        numerical_aperture=float(a.get("numerical_aperture", 0.0)),
        phase_steps=np.asarray(a.get("phase_steps_rad", []), dtype=np.float64),
        scan_positions=np.asarray(a.get("scan_positions_mm", []), dtype=np.float64),
        z_ref=float(a.get("z_ref_mm", 0.0)), bandwidth_nm=bw,
        objective=str(a.get("objective", "")),
        intensity_index=int(a.get("intensity_index", 0)),
        variant=str(a.get("mitsuba_variant", "")), subsamples=int(a.get("subsamples", 1)),
        seed=int(a.get("seed", 0)), noise=a.get("noise") in (True, "true"),
        meta={k: a[k] for k in ("scene", "surface") if k in a},
        effective_wavelength_nm=(float(a["effective_wavelength_nm"])
                                 if "effective_wavelength_nm" in a else None),
        settings=a["instrument"] if isinstance(a.get("instrument"), dict) else {})
    extra = {k: v for k, v in ch.items()
             if k not in FRAME_CHANNELS and not k.startswith("frame_")}
    return frames, extra, a
