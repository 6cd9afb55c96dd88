"""``[render]``: the virtual instruments (``[render.<instrument>]``, from the instrument
registry) and the diffuse-light images (``[render.diffuse]``)."""

from __future__ import annotations

from typing import Any

from pydantic import Field, create_model

from ..core.section import Section
from ..instruments import instrument_types
from ..render import DiffuseConfig

__all__ = ["render_config_class"]


def render_config_class() -> type[Section]:
    """The ``[render]`` section class: one field per registered instrument plus
    ``diffuse``, each with its defaults."""
    fields: dict[str, Any] = {name: (entry.config, Field(default_factory=entry.config))
              for name, entry in sorted(instrument_types().items())}
    fields["diffuse"] = (DiffuseConfig, Field(default_factory=DiffuseConfig))
    return create_model("RenderConfig", __base__=Section,
                        __doc__="``[render]``: virtual instruments and diffuse-light images.",
                        **fields)
