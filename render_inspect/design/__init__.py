"""Design surfaces z = F(x, y) (mm): height, gradient, Hessian, curvature.

Build one from a scene's ``[design]`` section with :func:`make_surface`.
"""

from __future__ import annotations

from ._analytic import Biconic, Plane, SinusoidalGrid, Sphere, Toric
from ._base import Surface
from ._compound import Compound
from ._expression import ExpressionSurface
from ._heightmap import HeightMapSurface
from ._lenslets import LensletArray, LensletRings

__all__ = ["Surface", "SinusoidalGrid", "Plane", "Sphere", "Toric", "Biconic", "Compound",
           "LensletArray", "LensletRings", "ExpressionSurface", "HeightMapSurface",
           "make_surface"]


def make_surface(cfg) -> Surface:
    """Build the :class:`Surface` described by a ``[design]`` config (pydantic model or dict)."""
    if isinstance(cfg, dict):
        from pydantic import TypeAdapter, ValidationError

        from ..scene import _format_error
        from ..scene._design import DesignConfig

        try:
            cfg = TypeAdapter(DesignConfig).validate_python(cfg)
        except ValidationError as err:  # -> SceneError naming the key and the value
            raise _format_error(err, "[design]") from None
    params = cfg.model_dump(exclude={"type"})
    t = cfg.type
    if t == "sinusoidal_grid":
        return SinusoidalGrid(**params)
    if t == "plane":
        return Plane(**params)
    if t == "sphere":
        return Sphere(**params)
    if t == "toric":
        return Toric(**params)
    if t in ("biconic", "paraboloid"):
        return Biconic(**params)
    if t == "compound":
        from ._compound import Compound

        return Compound(make_surface(cfg.base), make_surface(cfg.feature))
    if t == "lenslet_array":
        from ._lenslets import LensletArray

        return LensletArray(**params)
    if t == "lenslet_rings":
        from ._lenslets import LensletRings

        return LensletRings(**params)
    if t == "expression":
        from ._expression import ExpressionSurface

        return ExpressionSurface(**params)
    if t == "heightmap":
        from ._heightmap import HeightMapSurface

        return HeightMapSurface(**params)
    raise ValueError(f"design.type {t!r} is unsupported")
