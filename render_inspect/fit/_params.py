"""Free parameters of a fit: dotted scene keys, their start values and their bounds.

A key is a dotted path into the scene (``tool.nose_radius``, ``machine.z.delay_s``); a
number inside an array is reached by its index (``machine.errors.axial_sync.0.1`` is the
amplitude of the first synchronous axial error harmonic).  The key must name a real number
of the schema (not an integer, not a switch, not text).  Bounds come from the schema's
constraints (``gt``, ``ge``, ``lt``, ``le``) unless given; given bounds must lie inside the
schema's.  The schema is read from the validated scene object itself (a pydantic model), so
this module needs no import of the scene package.
"""

from __future__ import annotations

import math
import re
import typing
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pydantic import BaseModel

from ..core.annotations import annotation_bounds, unwrap_annotation
from ..core.errors import InputError

__all__ = ["FreeParameter", "parse_free", "parse_bounds", "free_parameters", "set_value",
           "get_value", "schema_range", "KEY_PATTERN"]

#: one part of a dotted key: a name or an array index
KEY_PATTERN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$|^[0-9]+$")
#: a number without a stated range must lie within this (the scene's own rule)
_MAX_MAGNITUDE = 1e9  # not a unit conversion
#: open bounds (gt / lt) are moved inside by this fraction of the value's scale
_OPEN_MARGIN = 1e-9  # not a unit conversion


@dataclass(frozen=True)
class FreeParameter:
    """One fitted scene key.

    Attributes
    ----------
    key : str
        Dotted scene key.
    start : float
        The scene's value (or the preset's, where the scene leaves the key to a preset).
    lower, upper : float
        Bounds of the fit (closed; an open schema bound is moved inside by a hair).
    scale : float
        The parameter's typical size: a step of one ``scale`` is a "large" change.  10 %
        of the start value, or a tenth of the bounds' width when the start is 0.
    schema : (lower, upper)
        The schema's range (None where open-ended).
    """

    key: str
    start: float
    lower: float
    upper: float
    scale: float
    schema: tuple = (None, None)

    def to_unit(self, value: float) -> float:
        """The value in the fit's scaled units: 1 at the start, one unit = ``scale``
        (the start at 1, not 0, gives the trust region of the optimiser a start size)."""
        return 1.0 + (value - self.start) / self.scale

    def from_unit(self, u: float) -> float:
        return self.start + (u - 1.0) * self.scale

    def narrowed(self, lower: float, upper: float) -> "FreeParameter":
        """The same key between ``lower`` and ``upper`` (around the start), its scale
        set by the rule of :func:`free_parameters`."""
        return FreeParameter(self.key, self.start, float(lower), float(upper),
                             _scale(self.start, lower, upper), self.schema)


def _scale(value: float, a: float, b: float, width: float | None = None) -> float:
    """A parameter's typical size: 10 % of its value, or a tenth of the bounds' width
    (``width``: of the range before an open bound was moved inside; default b - a) when
    the value is 0 or when that is more than half the width."""
    width = b - a if width is None else width
    scale = 0.1 * abs(value) if value != 0 else 0.1 * min(width, 2 * _MAX_MAGNITUDE)
    if not scale > 0 or scale > 0.5 * (b - a):
        scale = 0.1 * (b - a)
    return float(scale)


def _split(key: str) -> list:
    parts = key.split(".")
    if not key or not all(KEY_PATTERN.match(p) for p in parts) or len(parts) > 10 \
            or parts[0].isdigit():
        raise InputError(f"--free: a key is a dotted scene key like tool.nose_radius or "
                         f"machine.errors.axial_sync.0.1, received {key!r}")
    return [int(p) if p.isdigit() else p for p in parts]


def parse_free(items: Iterable[str]) -> list[str]:
    """``--free KEY[,KEY...]`` (one or several options) -> keys, in order, no duplicates."""
    keys = []
    for item in items if isinstance(items, (list, tuple)) else [items]:
        for k in str(item).split(","):
            k = k.strip()
            if not k:
                continue
            _split(k)
            if k in keys:
                raise InputError(f"--free names {k} twice")
            keys.append(k)
    if not keys:
        raise InputError("--free: name at least one scene key to fit, e.g. --free tool.nose_radius")
    return keys


def parse_bounds(items: Iterable[str]) -> dict:
    """``--bounds KEY=A,B`` (repeatable) -> {key: (A, B)}."""
    out = {}
    for item in items or ():
        if "=" not in str(item):
            raise InputError(f"--bounds expects KEY=A,B (two numbers), received {item!r}")
        key, text = str(item).split("=", 1)
        key = key.strip()
        _split(key)
        parts = text.split(",")
        try:
            a, b = (float(p) for p in parts)
        except ValueError:
            raise InputError(f"--bounds {key}: expects two numbers A,B, received "
                             f"{text!r}") from None
        if not (math.isfinite(a) and math.isfinite(b) and a < b):
            raise InputError(f"--bounds {key}: expects two finite numbers A < B, received {text!r}")
        if key in out:
            raise InputError(f"--bounds names {key} twice")
        out[key] = (a, b)
    return out


# ------------------------------------------------------------------------ the schema
def _is_model(obj: object) -> bool:
    return hasattr(type(obj), "model_fields") and not isinstance(obj, type)


def _walk(scene: BaseModel, parts: list, key: str) -> tuple[Any, list, Any]:
    """(annotation, constraints, value) of the key in the validated ``scene``."""
    node: Any
    meta: list
    node, ann, meta = scene, None, []
    for i, part in enumerate(parts):
        where = ".".join(str(p) for p in parts[:i]) or "the scene"
        if isinstance(part, str):
            if node is None and ann is not None and hasattr(ann, "model_fields"):
                node = None  # a section left to a preset: walk its class
                fields = ann.model_fields
            elif _is_model(node):
                fields = type(node).model_fields
            else:
                raise InputError(f"--free {key}: {where} is not a section (it has no key "
                                 f"{part!r})")
            if part not in fields:
                known = ", ".join(sorted(fields))
                raise InputError(f"--free {key}: unknown key {part!r} in {where} (keys there: "
                                 f"{known})")
            f = fields[part]
            ann, meta = unwrap_annotation(f.annotation)
            meta = list(f.metadata) + meta
            node = getattr(node, part) if node is not None else None
        else:
            base = ann
            origin = typing.get_origin(base)
            args = typing.get_args(base)
            if origin not in (list, tuple) and base not in (list, tuple):
                raise InputError(f"--free {key}: {where} is not an array (index {part} given)")
            if node is not None and part >= len(node):
                raise InputError(f"--free {key}: {where} has {len(node)} entries; index {part} "
                                 f"is out of range")
            if origin is tuple and args and args[-1] is not Ellipsis:
                if part >= len(args):
                    raise InputError(f"--free {key}: {where} holds {len(args)} values; index "
                                     f"{part} is out of range")
                ann = args[part]
            else:
                ann = args[0] if args else float
            ann, meta = unwrap_annotation(ann)
            node = node[part] if node is not None else None
    return ann, meta, node


def schema_range(scene: BaseModel, key: str
                 ) -> tuple[float | None, float | None, bool, bool, Any]:
    """(lower, upper, lower_open, upper_open, value) of a numeric key; None = no bound
    (the scene then allows +-1e9).  Raises :class:`InputError` for keys that are not
    real numbers."""
    ann, meta, value = _walk(scene, _split(key), key)
    if typing.get_origin(ann) is typing.Literal or ann is bool or ann is str:
        raise InputError(f"--free {key}: not a numeric key (it takes {_kind(ann)}); only real "
                         f"numbers can be fitted")
    if ann is int:
        raise InputError(f"--free {key}: an integer key; only real-valued keys can be fitted "
                         f"(set it with --set)")
    if ann is not float:
        raise InputError(f"--free {key}: not a numeric key (it takes {_kind(ann)}); only real "
                         f"numbers can be fitted")
    lo, hi, lo_open, hi_open = annotation_bounds(meta)
    return (None if lo is None else float(lo), None if hi is None else float(hi), lo_open,
            hi_open, value)


def _kind(ann) -> str:
    if typing.get_origin(ann) is typing.Literal:
        return "one of " + ", ".join(repr(a) for a in typing.get_args(ann))
    if ann is bool:
        return "true or false"
    if ann is str:
        return "text"
    if hasattr(ann, "model_fields"):
        return "a table of keys"
    return f"{getattr(ann, '__name__', str(ann))} values"


def _range_text(lo, hi, lo_open, hi_open) -> str:
    return (f"{'(' if lo_open or lo is None else '['}{'-inf' if lo is None else f'{lo:g}'}, "
            f"{'inf' if hi is None else f'{hi:g}'}{')' if hi_open or hi is None else ']'}")


def free_parameters(scene: BaseModel, keys: Sequence[str], bounds: dict | None = None, *,
                    defaults: Callable[[str], Any] | None = None) -> list[FreeParameter]:
    """The free parameters of a fit, checked against the schema.

    Parameters
    ----------
    scene : pydantic model
        The validated scene.
    keys : list of str
    bounds : dict key -> (lower, upper), optional
        Bounds given by the user (``--bounds``); must lie inside the schema's range.
    defaults : callable(key) -> float or None, optional
        The value of a key the scene leaves to a preset (``None`` in the scene).
    """
    bounds = dict(bounds or {})
    unknown = sorted(set(bounds) - set(keys))
    if unknown:
        raise InputError(f"--bounds {unknown[0]}: not among the free keys ({', '.join(keys)}); "
                         f"add it to --free")
    out = []
    for key in keys:
        lo, hi, lo_open, hi_open, value = schema_range(scene, key)
        if value is None and defaults is not None:
            value = defaults(key)
        if value is None and defaults is not None:
            parts = _split(key)
            for i, part in enumerate(parts):
                if isinstance(part, int):
                    arr = defaults(".".join(str(q) for q in parts[:i]))
                    if isinstance(arr, (list, tuple)) and part >= len(arr):
                        raise InputError(f"--free {key}: {'.'.join(str(q) for q in parts[:i])} "
                                         f"has {len(arr)} entries (the preset's); index {part} "
                                         f"is out of range")
                    break
        if value is None or isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"--free {key}: the scene sets no number there and its preset has "
                             f"none either; set a starting value with --set {key}=VALUE")
        value = float(value)
        rng = _range_text(lo, hi, lo_open, hi_open)
        if key in bounds:
            a, b = bounds[key]
            if (lo is not None and (a < lo or (lo_open and a <= lo))) or \
                    (hi is not None and (b > hi or (hi_open and b >= hi))):
                raise InputError(f"--bounds {key}={a:g},{b:g} lies outside the schema's range "
                                 f"{rng} of {key}")
        else:
            a = lo if lo is not None else -_MAX_MAGNITUDE
            b = hi if hi is not None else _MAX_MAGNITUDE
        width = b - a
        if lo_open and lo is not None and a == lo:
            a = lo + max(_OPEN_MARGIN * max(abs(value), width if math.isfinite(width) else 1.0),
                         1e-300)
        if hi_open and hi is not None and b == hi:
            b = hi - _OPEN_MARGIN * max(abs(value), width if math.isfinite(width) else 1.0)
        if not a <= value <= b:
            raise InputError(f"--free {key}: the scene's value {value:g} lies outside the fit's "
                             f"bounds [{a:g}, {b:g}]; widen --bounds or --set {key} inside them")
        out.append(FreeParameter(key, value, float(a), float(b), _scale(value, a, b, width),
                                 (lo, hi)))
    return out


# ------------------------------------------------------------------- scene dictionaries
def get_value(data: dict, key: str) -> Any:
    """The value at ``key`` in a scene dictionary (None where missing)."""
    node = data
    for part in _split(key):
        if isinstance(part, int):
            if not isinstance(node, (list, tuple)) or part >= len(node):
                return None
            node = node[part]
        else:
            if not isinstance(node, dict) or part not in node:
                return None
            node = node[part]
    return node


def set_value(data: dict, key: str, value: Any, *, fill: Any = None) -> dict:
    """Set ``key`` in a scene dictionary (in place; returns it).  A missing array along the
    way is taken from ``fill(prefix_key)`` (the preset's array, which the scene leaves
    unset)."""
    parts = _split(key)
    node: typing.Any = data
    for i, part in enumerate(parts[:-1]):
        nxt_is_index = isinstance(parts[i + 1], int)
        if isinstance(part, int):
            node = node[part]
            continue
        child = node.get(part)
        if child is None:
            prefix = ".".join(str(p) for p in parts[:i + 1])
            child = fill(prefix) if (fill is not None and nxt_is_index) else None
            if child is None:
                child = [] if nxt_is_index else {}
            node[part] = child
        if isinstance(child, tuple):
            child = node[part] = list(child)
        if nxt_is_index:
            child = node[part] = [list(c) if isinstance(c, tuple) else c for c in child]
        node = child
    last = parts[-1]
    if isinstance(last, int):
        if last >= len(node):
            raise InputError(f"{key}: index {last} is out of range ({len(node)} entries)")
        node[last] = float(value)
    else:
        node[last] = float(value)
    return data
