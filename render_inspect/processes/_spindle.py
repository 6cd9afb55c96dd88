"""A program cut with the spindle turning counter-clockwise (M04).

A lathe turning the other way cuts the mirror image: the part a path cuts turning M04
is the mirror (y -> -y; the spindle axis along z, x along the slide) of the part the
same path cuts turning M03 on the mirrored design.  The cutting kernels take paths whose
angle increases, so an M04 path (:func:`~render_inspect.core.toolpath.turns_m04`: its
``theta`` the angle the spindle turned through) is cut as that M03 run: the design
sampled mirrored (:class:`MirroredSurface`), over the mirrored region
(:func:`mirrored_region`), and the maps and figures flipped back
(:func:`~render_inspect.core.grid.flip_rows`, :func:`part_figure`), so that every output
is in the part's own coordinates.  Everything the cut draws at random (the lathe's error
motions, the material's texture, grooves and burrs) is drawn in the mirrored run: the M04
part is that run's mirror image exactly.  Tile by tile the same: the tiles cut the
mirrored run into the store, whose rows are then turned over
(:func:`~render_inspect.batch.run_tiles` with ``flip``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..core.grid import grid_shape
from ..core.toolpath import SPINDLE_KEY, turns_m04
from ..design import Surface

__all__ = ["MirroredSurface", "mirrored_region", "part_figure", "spindle_meta", "turns_m04"]


class MirroredSurface(Surface):
    """The design ``surface`` mirrored about the x axis: height(x, y) = surface(x, -y)."""

    def __init__(self, surface: Any):
        self.surface = surface
        self.kind = f"mirrored {getattr(surface, 'kind', 'surface')}"
        self.fd_step = getattr(surface, "fd_step", Surface.fd_step)
        base = getattr(surface, "base", None)
        if base is not None:  # a compound design's base (the slow slide's share)
            self.base = MirroredSurface(base)

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        return self.surface.height(x, -np.asarray(y, dtype=np.float64))

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        gx, gy = self.surface.gradient(x, -np.asarray(y, dtype=np.float64))
        return gx, -gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        hxx, hxy, hyy = self.surface.hessian(x, -np.asarray(y, dtype=np.float64))
        return hxx, -hxy, hyy

    def lateral_scale(self) -> float | None:
        return self.surface.lateral_scale()


def mirrored_region(region: Sequence[float], pixel: float) -> tuple[float, float, float, float]:
    """The mirror (y -> -y) of the grid of ``region`` at ``pixel``: its row k is row
    ny - 1 - k of the grid mirrored (the grid's last row, not ``region[3]``, sets it)."""
    x0, y0, x1, _ = (float(v) for v in region)
    ny, _ = grid_shape(region, pixel)
    top = y0 + pixel * (ny - 1)
    return (x0, -top, x1, -y0)


def part_figure(spec: dict, region: Sequence[float]) -> dict:
    """A map figure spec made on the mirrored grid (``x_nm``, ``z_nm``, ``extent``) on the
    part's own grid of ``region``; other specs as they are."""
    if "extent" not in spec:
        return spec
    out = dict(spec)
    for k in ("x_nm", "z_nm"):
        if k in out:
            out[k] = np.ascontiguousarray(np.asarray(out[k])[::-1])
    x0, x1, y0, y1 = spec["extent"]
    out["extent"] = (x0, x1, float(region[1]), float(region[1]) + (y1 - y0))
    return out


def spindle_meta(path: Any) -> dict:
    """What the maps' metadata say of the spindle: ``{"spindle_direction": "M04"}`` for a
    path cut turning M04, nothing otherwise."""
    return {SPINDLE_KEY: "M04"} if turns_m04(path) else {}
