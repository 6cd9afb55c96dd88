"""Helpers of the registries (design types, process kinds, instruments): a registered
schema class names its variants with a ``Literal`` field, a :class:`Registry` holds the
entries under those names with the union of their schema classes, and a package imports
every private module it holds so that one new file is all a new variant needs."""

from __future__ import annotations

import importlib
import pkgutil
import types
import typing
from collections.abc import Container, Iterable, Iterator, Mapping
from typing import Any, Callable

from .errors import SceneError

__all__ = ["literal_values", "import_private_modules", "Registry"]


def literal_values(config: Any, field: str) -> tuple:
    """The values of ``config``'s ``Literal`` field ``field`` (e.g. a design's ``type``)."""
    ann = config.model_fields[field].annotation
    args = typing.get_args(ann)
    if typing.get_origin(ann) is not typing.Literal or not args:
        raise TypeError(f"{config.__name__}.{field} must be a typing.Literal of the names")
    return tuple(args)


def import_private_modules(package: str, path: Iterable[str], *, skip: Container[str] = ()) -> list[str]:
    """Import every ``_*.py`` module of ``package`` (found on ``path``, its ``__path__``)
    except those in ``skip``, in name order; return their names."""
    names = sorted(m.name for m in pkgutil.iter_modules(path)
                   if m.name.startswith("_") and m.name not in skip)
    for name in names:
        importlib.import_module(f"{package}.{name}")
    return names


class Registry:
    """Entries registered under names (``design.type``, ``process.kind``): each entry has
    the schema class of its scene section (``config``) and is found under the names its
    ``Literal`` field gives; registering a name again replaces its entry.  The union of the
    registered schema classes (the type a scene's section is validated as) is made when it
    is first asked for after a registration (:meth:`union`).

    ``key`` is the scene key that names an entry, for the message of :meth:`lookup`."""

    def __init__(self, key: str):
        self.key = key
        self._entries: dict = {}
        self._union = None

    def add(self, names: Iterable[str], entry: Any) -> Any:
        """Register ``entry`` under each of ``names``; return it."""
        for name in names:
            self._entries[name] = entry
        self._union = None
        return entry

    def entries(self) -> dict:
        """Name -> entry (a copy)."""
        return dict(self._entries)

    def view(self) -> Mapping[str, Any]:
        """Name -> entry, read only and live: later registrations show in it."""
        return types.MappingProxyType(self._entries)

    def get(self, name: str) -> Any:
        """The entry of ``name``, or None."""
        return self._entries.get(name)

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def lookup(self, name: str | None) -> Any:
        """The entry of ``name``; :class:`~render_inspect.core.errors.SceneError` naming the
        registered names when there is none."""
        entry = self._entries.get(name)
        if entry is None:
            raise SceneError(f"{self.key} must be one of {sorted(self._entries)}, received "
                             f"{name!r}")
        return entry

    def configs(self) -> list:
        """The registered schema classes, each once, in the order of registration."""
        configs = []
        for entry in self._entries.values():
            if entry.config not in configs:
                configs.append(entry.config)
        return configs

    def union(self, make: Callable, then: Callable | None = None) -> Any:
        """``make(configs)``, the pydantic type of the section (:meth:`configs`), made once
        after each registration; ``then(union, configs)`` runs after it is made (schema
        classes that refer to the union are rebuilt there)."""
        if self._union is None:
            configs = self.configs()
            self._union = make(configs)
            if then is not None:
                then(self._union, configs)
        return self._union
