"""The whole part as a height map, for the views that show all of it: the design over the
part's outline with the simulated residual (area-averaged onto the part's grid) added
where it was simulated."""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import numpy as np

from ..core.errors import InputError
from ..core.heightmap import HeightMap
from ._design_grid import design_grid

__all__ = ["part_heightmap"]


def part_heightmap(surface: Any, hm: HeightMap, outline: dict, *, region: Sequence[float],
                   cells: int = 1024,
                   layer: str = "machined") -> HeightMap:
    """The whole part: the design ``surface`` over a disc ``outline`` (``{"shape": "disc",
    "center", "radius"}``; ``cells`` samples across; NaN outside the disc) with the
    residual of ``hm`` added inside the simulated region (``layer = "machined"``; the
    design alone for ``"design"``).  A part whose outline is a rectangle, or a design
    that does not cover the whole disc (a height map file), gets ``hm`` itself back (with
    its outline the simulated ``region``, (x0, y0, x1, y1) mm)."""
    if outline.get("shape") != "disc":
        return hm
    r = outline["radius"]
    pixel = 2 * r / cells
    region = (-r, -r, r, r)
    try:
        z = design_grid(surface, region, pixel)
    except InputError:
        # a design that does not cover the whole part (a height map file): the region
        return HeightMap(hm.design, hm.machined, hm.pixel, hm.origin, hm.scene,
                         {**hm.meta, "part": {"shape": "rect",
                                              "rect": [float(v) for v in region]}})
    x = -r + pixel * np.arange(z.shape[1])
    y = -r + pixel * np.arange(z.shape[0])
    machined = z.copy()
    if layer == "machined":
        res = hm.residual
        f = max(1, int(round(pixel / hm.pixel)))
        if f > 1:
            ny, nx = (res.shape[0] // f) * f, (res.shape[1] // f) * f
            b = res[:ny, :nx].reshape(ny // f, f, nx // f, f)
            ok = np.isfinite(b)
            with np.errstate(invalid="ignore"):
                res = np.where(ok.any(axis=(1, 3)), np.where(ok, b, 0).sum(axis=(1, 3))
                               / np.maximum(ok.sum(axis=(1, 3)), 1), np.nan)
        rp = hm.pixel * f
        ox = hm.origin[0] + (f - 1) / 2 * hm.pixel
        oy = hm.origin[1] + (f - 1) / 2 * hm.pixel
        j = np.rint((x - ox) / rp).astype(int)
        i = np.rint((y - oy) / rp).astype(int)
        jin = (j >= 0) & (j < res.shape[1])
        iin = (i >= 0) & (i < res.shape[0])
        if jin.any() and iin.any():
            patch = res[np.ix_(i[iin], j[jin])]
            sub = machined[np.ix_(iin, jin)]
            machined[np.ix_(iin, jin)] = np.where(np.isfinite(patch), sub + patch, sub)
    xx, yy = np.meshgrid(x, y)
    outside = xx * xx + yy * yy > r * r
    z[outside] = np.nan
    machined[outside] = np.nan
    return HeightMap(z, machined, pixel, (-r, -r), meta={"part": outline})
