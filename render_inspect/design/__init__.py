"""Design surfaces z = F(x, y) (mm): height, gradient, Hessian, curvature.

Build one from a scene's ``[design]`` section with :func:`make_surface`.  Every design
type is one module of this package holding its :class:`Surface` and its scene schema
class, registered with :func:`register_design`; the modules are found and imported here,
so adding a file ``_mytype.py`` is all a new design type needs (docs/contributing.md).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Union

from ..core.plugins import import_private_modules
from ._analytic import (
    Biconic,
    BiconicConfig,
    Plane,
    PlaneConfig,
    SinusoidalGrid,
    SinusoidalGridConfig,
    Sphere,
    SphereConfig,
    Toric,
    ToricConfig,
)
from ._base import Surface
from ._bounds import HeightBound, height_interval, max_height
from ._compound import Compound, CompoundConfig
from ._expression import ExpressionConfig, ExpressionSurface
from ._heightmap import HeightMapConfig, HeightMapSurface
from ._lenslets import (
    LensletArray,
    LensletArrayConfig,
    LensletRings,
    LensletRingsConfig,
)
from ._registry import (
    DesignType,
    design_config_union,
    design_types,
    make_surface,
    register_design,
)

# variants added as modules of this package register themselves on import
import_private_modules(__name__, __path__, skip=("_base", "_registry"))

#: the schema classes of the design types, as a type checker knows a ``[design]`` section
#: (the registry's, listed: a design type added to the registry is added here too)
DesignSection = Union[SinusoidalGridConfig, PlaneConfig, SphereConfig, ToricConfig, BiconicConfig,
                      CompoundConfig, ExpressionConfig, HeightMapConfig, LensletArrayConfig,
                      LensletRingsConfig]

if TYPE_CHECKING:
    DesignConfig = DesignSection
else:
    #: the pydantic type of a scene's [design] section
    DesignConfig = design_config_union()

__all__ = ["Surface", "SinusoidalGrid", "Plane", "Sphere", "Toric", "Biconic", "Compound",
           "LensletArray", "LensletRings", "ExpressionSurface", "HeightMapSurface",
           "make_surface", "register_design", "design_types", "design_config_union",
           "DesignType", "DesignConfig", "DesignSection", "SinusoidalGridConfig", "PlaneConfig", "SphereConfig",
           "ToricConfig", "BiconicConfig", "CompoundConfig", "ExpressionConfig",
           "HeightMapConfig", "LensletArrayConfig", "LensletRingsConfig",
           "HeightBound", "height_interval", "max_height"]
