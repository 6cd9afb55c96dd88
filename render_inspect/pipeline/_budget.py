"""Where a variant's deepest cut below the design comes from: the commanded geometry and
each part of the model the process names beyond it (its traits' ``contributions``: for
turning, the lathe and the material).

The variant is simulated again over a small window around its deepest point with each
contribution on its own (the others turned off by the scene values the process gives),
and with none, so the report can say in numbers why a compensated path still overcuts:
"the commanded geometry alone leaves 0 nm there, the lathe alone -15 nm, the material
alone -1.3 nm".  A turning path's nose envelope over a window equals the whole map's
there; the machine's model follows the whole path either way; the material's random
grooves are a new draw of the same statistics on the smaller grid.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.progress import task
from ..core.units import MM_TO_NM
from ..processes import Variant, process_of
from ..scene import variant_scene
from ._simulate import simulate
from ..core.heightmap import HeightMap

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["overcut_budget", "BUDGET_WINDOW_PIXELS", "BUDGET_MIN_OVERCUT_NM"]

#: side of the window simulated again around the deepest point (pixels of the grid)
BUDGET_WINDOW_PIXELS = 64
#: a variant whose deepest point is less than this below the design is not split (nm)
BUDGET_MIN_OVERCUT_NM = 0.5


def _window(hm, at, pixels: int) -> list[float]:
    """A square of ``pixels`` grid pixels around ``at``, inside the map."""
    side = pixels * hm.pixel
    x_lo, x_hi, y_lo, y_hi = hm.extent
    x0 = min(max(at[0] - side / 2, x_lo + hm.pixel), x_hi - side - hm.pixel)
    y0 = min(max(at[1] - side / 2, y_lo + hm.pixel), y_hi - side - hm.pixel)
    return [float(x0), float(y0), float(x0 + side), float(y0 + side)]


def _deepest(scene: Scene, values: dict, window) -> float:
    sc = variant_scene(scene, Variant("budget", "budget", {**values, "simulation.region": window}))
    r = simulate(sc).heightmap.residual
    return float(np.nanmin(r)) * MM_TO_NM if np.isfinite(r).any() else math.nan


def overcut_budget(scene: Scene, hm: HeightMap, *,
                   pixels: int = BUDGET_WINDOW_PIXELS) -> dict | None:
    """The deepest point of ``hm`` below the design, split into its contributions.

    Parameters
    ----------
    scene : Scene
        The variant's scene.
    hm : HeightMap
        Its simulated map.
    pixels : int
        Side of the window simulated again, in grid pixels.

    Returns
    -------
    dict or None
        ``at_mm`` (x, y of the deepest point), ``window_mm``, ``min_nm`` (its depth as
        simulated, < 0), ``geometry_nm`` (the deepest point of the window with every
        contribution off: the commanded geometry), ``alone_nm`` (contribution -> the
        deepest point with that one on and the others off), ``labels`` (contribution ->
        text); None when the process names no contribution or the map does not go more
        than :data:`BUDGET_MIN_OVERCUT_NM` below the design.
    """
    process = process_of(scene)
    contributions = process.traits(process.inputs_of(scene)).contributions
    res = hm.residual
    if not contributions or not np.isfinite(res).any():
        return None
    i, j = np.unravel_index(np.nanargmin(res), res.shape)
    deepest = float(res[i, j]) * MM_TO_NM
    if deepest > -BUDGET_MIN_OVERCUT_NM:
        return None
    at = (float(hm.origin[0] + j * hm.pixel), float(hm.origin[1] + i * hm.pixel))
    n = max(8, min(int(pixels), min(res.shape) - 3))
    window = _window(hm, at, n)
    names = list(contributions)
    out: dict[str, Any] = {"at_mm": list(at), "window_mm": window, "min_nm": deepest,
           "labels": {k: contributions[k]["label"] for k in names}, "alone_nm": {}}
    with task("why the deepest cut", total=len(names) + 1) as t:
        off_all = {}
        for k in names:
            off_all.update(contributions[k]["off"])
        out["geometry_nm"] = _deepest(scene, off_all, window)
        t.advance()
        for k in names:
            if len(names) == 1:
                out["alone_nm"][k] = deepest  # the one contribution is all there is
            else:
                others = {}
                for o in names:
                    if o != k:
                        others.update(contributions[o]["off"])
                out["alone_nm"][k] = _deepest(scene, others, window)
            t.advance()
    return out
