"""Readers and writers registered by (product, extension), trimesh's habit.

A product names what a file holds: ``"heightmap"`` (design / machined / residual),
``"measured"`` (a measured height map from an instrument or exchange format),
``"profile"`` (a measured profile: a stylus trace or an interferometer's 2-D slice),
``"toolpath"`` (a turning program), ``"program"`` (a sculpturing program), ``"frames"``
(interferometer frames).  Each format module registers its functions with
:func:`register_reader` / :func:`register_writer`; callers look them up with
:func:`reader` / :func:`writer`, which name the supported extensions when one is missing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

from ..core.errors import InputError

__all__ = ["register_reader", "register_writer", "reader", "writer", "formats"]

_READERS: dict[tuple[str, str], Callable] = {}
_WRITERS: dict[tuple[str, str], Callable] = {}


def _norm(ext: str) -> str:
    ext = ext.lower()
    return ext if ext.startswith(".") else "." + ext


def register_reader(product: str, *extensions: str) -> Callable[[Callable], Callable]:
    """Decorator: register ``fn(path, **options)`` as the reader of ``product`` files."""
    def deco(fn):
        for e in extensions:
            _READERS[(product, _norm(e))] = fn
        return fn
    return deco


def register_writer(product: str, *extensions: str) -> Callable[[Callable], Callable]:
    """Decorator: register ``fn(path, obj, **options)`` as the writer of ``product`` files."""
    def deco(fn):
        for e in extensions:
            _WRITERS[(product, _norm(e))] = fn
        return fn
    return deco


def formats(product: str, *, kind: str = "read") -> list[str]:
    """Extensions registered for ``product`` (``kind`` "read" or "write")."""
    table = _READERS if kind == "read" else _WRITERS
    return sorted(e for p, e in table if p == product)


def reader(product: str, path: str | Path) -> Callable:
    """The reader registered for ``path``'s extension (InputError naming the known ones)."""
    ext = Path(path).suffix.lower()
    fn = _READERS.get((product, ext))
    if fn is None:
        raise InputError(f"{path}: unknown {product} file format {ext!r}; supported: "
                         f"{', '.join(formats(product))}")
    return fn


def writer(product: str, extension: str) -> Callable:
    """The writer registered for ``product`` files with ``extension``."""
    fn = _WRITERS.get((product, _norm(extension)))
    if fn is None:
        raise InputError(f"no {product} writer for {_norm(extension)!r}; supported: "
                         f"{', '.join(formats(product, kind='write'))}")
    return fn
