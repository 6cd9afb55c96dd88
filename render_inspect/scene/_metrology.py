"""``[metrology]``: how measured or simulated maps are characterised."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from ._base import Section


class MetrologyConfig(Section):
    form_removal: Literal["none", "plane", "polynomial", "design"] = "plane"
    polynomial_degree: int = Field(2, ge=1, le=10)
    s_filter: float | None = Field(None, gt=0, description="mm, ISO 16610-61 S-filter nesting index")
    l_filter: float | None = Field(None, gt=0, description="mm, L-filter nesting index")
