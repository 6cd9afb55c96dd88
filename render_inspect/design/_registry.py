"""The registry of design types: ``design.type`` -> (its scene schema class, a factory
that builds the :class:`~render_inspect.design.Surface`).

Each design module registers its own types with :func:`register_design`; the scene's
``[design]`` section is the union of the registered schema classes
(:func:`design_config_union`), so a new design type is one new module.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Callable, Union

from pydantic import Field, TypeAdapter, ValidationError

from ..core.errors import SceneError
from ..core.plugins import Registry, literal_values

__all__ = ["DesignType", "register_design", "design_types", "make_surface",
           "design_config_union"]


@dataclass(frozen=True)
class DesignType:
    """One registered design type: the values of its ``type`` key, its schema class and
    the factory ``factory(config) -> Surface``."""

    names: tuple[str, ...]
    config: type
    factory: Callable


_DESIGNS = Registry("design.type")


def register_design(config, factory: Callable | None = None):
    """Register a design schema class (a :class:`~render_inspect.core.Section` whose
    ``type`` field is a ``Literal`` of names) with ``factory(config) -> Surface``.
    Usable as a decorator on the Surface class, which then is the factory, called with
    the config's fields as keyword arguments."""
    def deco(target):
        if isinstance(target, type):
            def build(cfg, cls=target):
                return cls(**cfg.model_dump(exclude={"type"}))
        else:
            build = target
        entry = DesignType(literal_values(config, "type"), config, build)
        _DESIGNS.add(entry.names, entry)
        return target
    return deco if factory is None else deco(factory)


def design_types() -> dict[str, DesignType]:
    """``design.type`` name -> :class:`DesignType`."""
    return _DESIGNS.entries()


def design_config_union():
    """The pydantic type of a ``[design]`` section: the registered schema classes,
    discriminated by ``type``."""
    return _DESIGNS.union(_union_of, _rebuild_nesting)


def _union_of(configs):
    return Annotated[Union[tuple(configs)], Field(discriminator="type")]


def _rebuild_nesting(union, configs) -> None:
    for c in configs:  # schema classes that nest a design (compound) refer to the union
        if getattr(c, "nests_design", False) or not c.__pydantic_complete__:
            c.model_rebuild(force=True, _types_namespace={"DesignConfig": union})


def make_surface(cfg):
    """Build the :class:`~render_inspect.design.Surface` a ``[design]`` section (schema
    object or dict) describes."""
    if isinstance(cfg, dict):
        try:
            cfg = TypeAdapter(design_config_union()).validate_python(cfg)
        except ValidationError as err:
            first = err.errors()[0]
            loc = ".".join(str(p) for p in first["loc"] if str(p) not in _DESIGNS)
            raise SceneError(f"invalid [design]: design.{loc}: {first['msg']}") from None
    return _DESIGNS.lookup(getattr(cfg, "type", None)).factory(cfg)
