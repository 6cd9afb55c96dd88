"""``heightmap.exr``: the design, machined and residual channels of a
:class:`~render_inspect.core.HeightMap` and its placement (docs/formats.md)."""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import json
from pathlib import Path

import numpy as np

from .. import __version__
from ..core.errors import InputError
from ..core.heightmap import HeightMap
from ._exr import exr_placement, read_exr, write_height_channels
from ._registry import register_writer

__all__ = ["write_heightmap_exr", "read_heightmap_exr", "heightmap_attrs", "grid_attrs"]


def grid_attrs(pixel: float, origin: Sequence[float], scene: dict | None,
               meta: dict | None) -> dict:
    """Header attributes of a height map on a grid (``heightmap.exr``, ``heightmap.zarr``)."""
    return {"pixel_size_mm": float(pixel),
            "origin_mm": [float(origin[0]), float(origin[1])],
            "units": "mm",
            "scene": json.dumps(scene or {}, sort_keys=True),
            "software_version": __version__,
            "meta": json.dumps(meta or {}, sort_keys=True, default=str)}


def heightmap_attrs(hm: HeightMap) -> dict:
    """Header attributes of ``heightmap.exr`` (and of the other stores of a height map)."""
    return grid_attrs(hm.pixel, hm.origin, hm.scene, hm.meta)


@register_writer("heightmap", ".exr")
def write_heightmap_exr(path: str | Path, hm: HeightMap, *, overview: dict | None = None,
                        **_: Any) -> Path:
    """Write float32 channels ``design``, ``machined``, ``residual`` (mm; the residual formed
    in float64, then rounded) and the header of :func:`heightmap_attrs`, tiled, with an
    area-averaged overview part for maps larger than 1024 pixels a side (atomic; see
    ``render_inspect.io._exr``).  ``overview``: see
    :func:`~render_inspect.io._exr.write_height_channels`."""
    return write_height_channels(path, hm.design, hm.machined, heightmap_attrs(hm), overview=overview)


def read_heightmap_exr(path: str | Path) -> HeightMap:
    """Read a ``heightmap.exr`` written by :func:`write_heightmap_exr`."""
    ch, attrs = read_exr(path)
    for name in ("design", "machined"):
        if name not in ch:
            raise InputError(f"{path}: EXR has no channel {name!r} (channels: {sorted(ch)})")
    pixel, origin = exr_placement(attrs, what="height map", path=path)
    if ch["design"].shape != ch["machined"].shape:
        raise InputError(f"{path}: channels design and machined differ in shape")
    scene = attrs.get("scene")
    meta = attrs.get("meta", {})
    return HeightMap(ch["design"].astype(np.float64), ch["machined"].astype(np.float64),
                     pixel, origin,
                     scene if isinstance(scene, dict) else None,
                     meta if isinstance(meta, dict) else {})
