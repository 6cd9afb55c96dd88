"""The data types every stage shares, and the errors: plain numpy, no imports from the
rest of the package.  The pydantic base class of scene sections is
:class:`render_inspect.core.section.Section` (not imported here, so the errors stay cheap
to import)."""

from .errors import (
                     AccessibilityError,
                     InputError,
                     MemoryBudgetError,
                     RenderInspectError,
                     SceneError,
                     check_positive,
                     check_range,
)
from .frames import PHASE_CONVENTION, Frames
from .grid import Grid, GridCoordinates, grid_shape
from .heightmap import HeightMap
from .toolpath import LinearProgram, ToolPath

__all__ = ["RenderInspectError", "SceneError", "InputError", "MemoryBudgetError",
           "AccessibilityError", "check_range", "check_positive", "Frames", "PHASE_CONVENTION",
           "Grid", "GridCoordinates", "grid_shape", "HeightMap", "LinearProgram",
           "ToolPath"]
