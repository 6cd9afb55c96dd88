"""Helpers of the registries (design types, process kinds, instruments): a registered
schema class names its variants with a ``Literal`` field, and a package imports every
private module it holds so that one new file is all a new variant needs."""

from __future__ import annotations

import importlib
import pkgutil
import typing

__all__ = ["literal_values", "import_private_modules"]


def literal_values(config, field: str) -> tuple:
    """The values of ``config``'s ``Literal`` field ``field`` (e.g. a design's ``type``)."""
    ann = config.model_fields[field].annotation
    args = typing.get_args(ann)
    if typing.get_origin(ann) is not typing.Literal or not args:
        raise TypeError(f"{config.__name__}.{field} must be a typing.Literal of the names")
    return tuple(args)


def import_private_modules(package: str, path, *, skip=()) -> list[str]:
    """Import every ``_*.py`` module of ``package`` (found on ``path``, its ``__path__``)
    except those in ``skip``, in name order; return their names."""
    names = sorted(m.name for m in pkgutil.iter_modules(path)
                   if m.name.startswith("_") and m.name not in skip)
    for name in names:
        importlib.import_module(f"{package}.{name}")
    return names
