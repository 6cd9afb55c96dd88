"""What every process simulation returns."""

from __future__ import annotations

from dataclasses import dataclass, field

from ._heightmap import HeightMap


@dataclass
class SimulationResult:
    """heightmap: design / machined on the simulation grid;
    toolpath: the ToolPath (turning processes) or None;
    metrics: extra metrics.json entries (merged into the top level, e.g. ``toolpath``
    maxima, ``servo``, ``vibration``, ``lenslets``);
    timing_s: seconds per stage (``toolpath``, ``simulate``, ...);
    plots: extra figures, file name -> callable(path), drawn by ``simulate``."""

    heightmap: HeightMap
    toolpath: object | None = None
    metrics: dict = field(default_factory=dict)
    timing_s: dict = field(default_factory=dict)
    #: figures to draw into the output folder: file name -> callable(path)
    plots: dict = field(default_factory=dict)
