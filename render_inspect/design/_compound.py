"""Compound surface: a base form plus a feature surface.

References
----------
.. [1] "Compound sinusoidal grid surface" machined by slow tool servo diamond turning
       (a paraboloidal base plus a sinusoidal grid; the project's copy lacks authors,
       journal and year: docs/references.md).
.. [2] L. Kong, Y. Ma, M. Ren, M. Xu, C.-F. Cheung, "Generation and characterization of
       ultra-precision compound freeform surfaces," Science Progress 103(1), 1-12 (2020).
       :DOI:`10.1177/0036850419880112`
"""

from __future__ import annotations

import numpy as np
from typing import ClassVar, Literal

from ..core.errors import InputError
from ..core.section import Section
from ._base import Surface
from ._registry import make_surface, register_design

__all__ = ["Compound", "CompoundConfig"]


class Compound(Surface):
    """``F = base + feature``: heights, gradients and Hessians add.

    The compound sinusoidal grid paper [1]_: a base of two orthogonal circular sections
    (r1 = r2 = 1000 mm) plus the sinusoidal grid ``h1 sin(w1 x) + h2 sin(w2 y)``; Kong et
    al. (2020) [2]_: a toric base plus a lenslet array.

    Parameters
    ----------
    base, feature : Surface
        The two parts (any :class:`Surface`, compounds included).
    """
    kind = "compound"

    def __init__(self, base: Surface, feature: Surface):
        for name, s in (("base", base), ("feature", feature)):
            if not isinstance(s, Surface):
                raise InputError(f"design.{name} must be a Surface, received {type(s).__name__}")
        self.base, self.feature = base, feature

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        return self.base.height(x, y) + self.feature.height(x, y)

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        bx, by = self.base.gradient(x, y)
        fx, fy = self.feature.gradient(x, y)
        return bx + fx, by + fy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        b = self.base.hessian(x, y)
        f = self.feature.hessian(x, y)
        return tuple(bi + fi for bi, fi in zip(b, f))

    def lateral_scale(self) -> float | None:
        """The feature's lateral scale (mm)."""
        return self.feature.lateral_scale()

    def centers(self) -> list[tuple[int, int, float, float]]:
        """The feature's lenslet centres (only when the feature is a lenslet array)."""
        if not hasattr(self.feature, "centers"):
            raise InputError(f"design.feature ({type(self.feature).__name__}) has no lenslet centres")
        return self.feature.centers()

    def __repr__(self) -> str:
        return f"Compound(base={self.base!r}, feature={self.feature!r})"


# ------------------------------------------------------------------ scene schema
class CompoundConfig(Section):
    """Base + feature (the compound sinusoidal grid paper; Kong et al. 2020): heights add."""
    nests_design: ClassVar[bool] = True
    type: Literal["compound"]
    base: "DesignConfig"  # type: ignore[name-defined]  # noqa: F821  (the [design] union, resolved by the registry)
    feature: "DesignConfig"  # type: ignore[name-defined]  # noqa: F821


def _compound(cfg: CompoundConfig) -> Compound:
    return Compound(make_surface(cfg.base), make_surface(cfg.feature))


register_design(CompoundConfig, _compound)
