"""The errors render_inspect raises on purpose (defined in :mod:`render_inspect.core.errors`).

Every message names the parameter, the allowed range and the value received, and says
what to do."""

from .core.errors import (
                          AccessibilityError,
                          InputError,
                          MemoryBudgetError,
                          RenderInspectError,
                          SceneError,
                          check_positive,
                          check_range,
)

__all__ = ["RenderInspectError", "SceneError", "InputError", "MemoryBudgetError",
           "AccessibilityError", "check_range", "check_positive"]
