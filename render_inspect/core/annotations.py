"""Reading a scene key's type and limits from its schema annotation (pydantic fields):
the base type under ``Optional``/``Annotated`` and its ``gt``/``ge``/``lt``/``le`` bounds."""

from __future__ import annotations

import types
import typing
from collections.abc import Iterable
from typing import Any

__all__ = ["unwrap_annotation", "annotation_bounds"]


def unwrap_annotation(annotation: Any) -> tuple[Any, list]:
    """(base annotation, constraint metadata) of a field's annotation: unwraps
    ``Annotated`` (collecting its constraints, pydantic's grouped ones flattened) and
    ``Optional`` (a union with None and one other type)."""
    meta: list = []
    while True:
        origin = typing.get_origin(annotation)
        args = typing.get_args(annotation)
        if origin is typing.Annotated:
            annotation = args[0]
            for m in args[1:]:
                meta.extend(getattr(m, "metadata", None) or [m])
        elif origin in (typing.Union, types.UnionType) and type(None) in args:
            rest = [a for a in args if a is not type(None)]
            if len(rest) != 1:
                return annotation, meta
            annotation = rest[0]
        else:
            return annotation, meta


def annotation_bounds(meta: Iterable[Any]) -> tuple[float | None, float | None, bool, bool]:
    """(lo, hi, lo_open, hi_open) of the constraints ``meta`` (None: unbounded)."""
    lo = hi = None
    lo_open = hi_open = False
    for m in meta:
        for attr, is_lo, is_open in (("gt", True, True), ("ge", True, False),
                                     ("lt", False, True), ("le", False, False)):
            v = getattr(m, attr, None)
            if v is not None:
                if is_lo:
                    lo, lo_open = v, is_open
                else:
                    hi, hi_open = v, is_open
    return lo, hi, lo_open, hi_open
