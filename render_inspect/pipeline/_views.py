"""The height maps a render reads: the whole map when it is in memory, or, from a height-map
store (``heightmap.zarr``: the one ``simulate`` wrote into the output folder for the same
part, whatever its size, or one simulated tile by tile for a map too large for memory),
only the windows and area-averaged levels each view needs (float32 heights, as stored).

- an instrument (the interferometer, ...): its field (its ``field`` hook: the objective's
  field of view, resolved on the whole map exactly as for an in-memory map), read at full
  resolution with a 2-pixel margin;
- diffuse ``micro``: its window (``render.diffuse.window`` or the default centred one), at
  full resolution;
- diffuse ``macro``: the whole part from the finest pyramid level with at most
  ``2 x render.diffuse.resolution`` pixels a side (area averages: the feed marks average
  out instead of aliasing).
"""

from __future__ import annotations

import json
import logging
import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.errors import InputError
from ..core.grid import GridCoordinates
from ..core.heightmap import HeightMap
from ..io import ZarrHeightMap
from ..render import DiffuseConfig, default_window
from ._simulate_command import run_simulate_tiled

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["WholeMapViews", "BigMapViews", "big_map_store", "existing_store"]

log = logging.getLogger("render_inspect")

#: pixels read around a window (the mesh spans pixel centres; interpolation needs neighbours)
MARGIN_PX = 2


class WholeMapViews:
    """Every view of an in-memory height map is the map itself."""

    big = False

    def __init__(self, hm: HeightMap):
        self.hm = hm
        self.facts: dict[str, Any] = {}

    def instrument(self, entry: Any, cfg: Any) -> tuple[HeightMap, Any]:
        return self.hm, cfg

    def diffuse(self, dcfg: DiffuseConfig, view: str) -> tuple[HeightMap, DiffuseConfig]:
        return self.hm, dcfg


class _Grid(GridCoordinates):
    def __init__(self, shape, pixel, origin):
        self.shape, self.pixel, self.origin = tuple(shape), float(pixel), tuple(origin)


class BigMapViews:
    """Windows and levels of a height-map store (see the module notes); ``facts`` records
    what was read."""

    big = True

    def __init__(self, store: str | Path, cleanup: Path | None = None):
        self.store = ZarrHeightMap(store)
        self.grid = _Grid(self.store.shape, self.store.pixel, self.store.origin)
        self.cleanup = cleanup
        self.facts: dict[str, Any] = {"store_shape": list(self.store.shape), "read": {}}

    def _window(self, region, name: str) -> HeightMap:
        p = self.store.pixel
        x0, y0, x1, y1 = region
        m = MARGIN_PX * p
        design, machined, origin = self.store.window((x0 - m, y0 - m, x1 + m, y1 + m))
        self.facts["read"][name] = {"shape": list(design.shape), "origin_mm": list(origin)}
        return HeightMap(design, machined, p, origin, self.store.scene or None, self.store.meta)

    def _level(self, max_side: int, name: str) -> HeightMap:
        k = self.store.level_for(max_side)
        if k == 0:
            return self._window((self.grid.x[0], self.grid.y[0], self.grid.x[-1], self.grid.y[-1]), name)
        f = 2 ** k
        design = self.store.read("design", level=k).astype(np.float64)
        machined = self.store.read("machined", level=k).astype(np.float64)
        p = self.store.pixel
        origin = (self.store.origin[0] + (f - 1) / 2 * p, self.store.origin[1] + (f - 1) / 2 * p)
        self.facts["read"][name] = {"shape": list(design.shape), "level": k, "factor": f}
        return HeightMap(design, machined, p * f, origin, self.store.scene or None, self.store.meta)

    def instrument(self, entry: Any, cfg: Any) -> tuple[HeightMap, Any]:
        if entry.field is None:
            raise InputError(f"render.{entry.name}: the instrument states no field, so a map "
                             f"too large for memory cannot be read in part for it; shrink "
                             f"simulation.region or raise simulation.max_memory_gb")
        field = entry.field(self.grid, cfg)
        window = [float(v) for v in field["window"]]
        return self._window(window, entry.name), field.get("settings", cfg)

    def diffuse(self, dcfg: DiffuseConfig, view: str) -> tuple[HeightMap, DiffuseConfig]:
        if view == "macro":
            return self._level(2 * int(dcfg.resolution), "diffuse_macro"), dcfg
        window = list(dcfg.window) if dcfg.window is not None else default_window(self.grid)
        return self._window(window, f"diffuse_{view}"), dcfg.model_copy(update={"window": tuple(window)})

    def close(self) -> None:
        if self.cleanup is not None:
            shutil.rmtree(self.cleanup, ignore_errors=True)


def _same_scene(a: dict, b: dict) -> bool:
    a, b = json.loads(json.dumps(a)), json.loads(json.dumps(b))
    for d in (a, b):
        d.get("simulation", {}).pop("max_memory_gb", None)
        d.pop("render", None)
    return a == b


def existing_store(scene: Scene, out: str | Path) -> Path | None:
    """``out/heightmap.zarr`` when ``simulate`` wrote it there for the same part (the
    scene's keys equal, the memory budget and the render settings aside), else None."""
    existing = Path(out) / "heightmap.zarr"
    if not existing.is_dir():
        return None
    z = ZarrHeightMap(existing)
    if not _same_scene(z.scene, scene.to_dict()):
        return None
    log.info("reading the windows to render from %s", existing)
    return existing


def big_map_store(scene: Scene, out: str | Path) -> tuple[Path, Path | None]:
    """The store of ``scene``'s machined map: ``out/heightmap.zarr`` when ``simulate``
    wrote it there for the same part, else a tiled simulation into a temporary folder
    (returned second, to be removed after use)."""
    existing = existing_store(scene, out)
    if existing is not None:
        return existing, None
    tmp = Path(tempfile.mkdtemp(prefix="render_inspect_map_"))
    log.info("the map does not fit in memory: simulating it tile by tile first")
    run_simulate_tiled(scene, tmp / "sim")
    return tmp / "sim" / "heightmap.zarr", tmp
