"""The registry of design types: ``design.type`` -> (its scene schema class, a factory
that builds the :class:`~render_inspect.design.Surface`).

Each design module registers its own types with :func:`register_design`; the scene's
``[design]`` section is the union of the registered schema classes
(:func:`design_config_union`), so a new design type is one new module.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Callable, TypeVar, Union, overload

from pydantic import Field, TypeAdapter, ValidationError

from ..core.errors import SceneError
from ..core.plugins import Registry, literal_values
from ..core.section import Section
from ._base import Surface

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

#: a Surface class or a function ``factory(config) -> Surface`` (returned as it is)
_F = TypeVar("_F", bound=Callable[..., Surface])


@overload
def register_design(config: type[Section], factory: None = None) -> Callable[[_F], _F]: ...


@overload
def register_design(config: type[Section], factory: _F) -> _F: ...


def register_design(config: type[Section], factory: _F | None = None) -> _F | Callable[[_F], _F]:
    """Register a design schema class (a :class:`~render_inspect.core.Section` whose
    ``type`` field is a ``Literal`` of names) with ``factory(config) -> Surface``.
    Usable as a decorator on the Surface class, which then is the factory, called with
    the config's fields as keyword arguments."""
    def deco(target: _F) -> _F:
        build: Callable[..., Surface]
        if isinstance(target, type):
            def build(cfg: Section, cls: type[Surface] = target) -> Surface:
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


def design_config_union() -> Any:
    """The pydantic type of a ``[design]`` section: the registered schema classes,
    discriminated by ``type``."""
    # Any: a type form made at run time (``Annotated[Union[...], Field(...)]``), which
    # has no static type (the checker sees ``render_inspect.design.DesignSection``)
    return _DESIGNS.union(_union_of, _rebuild_nesting)


def _union_of(configs: list[type[Section]]) -> Any:  # (a type form made at run time)
    return Annotated[Union[tuple(configs)], Field(discriminator="type")]


def _rebuild_nesting(union: Any, configs: list[type[Section]]) -> None:
    for c in configs:  # schema classes that nest a design (compound) refer to the union
        if getattr(c, "nests_design", False) or not c.__pydantic_complete__:
            c.model_rebuild(force=True, _types_namespace={"DesignConfig": union})


def make_surface(cfg: Section | dict[str, Any]) -> Surface:
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
