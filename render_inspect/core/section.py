"""Shared pydantic base of every scene section: unknown keys are errors, types are strict,
numbers are finite.

* strict types: a number field takes an int or a float, never ``true``/``false`` or a
  string (``spindle_rpm = true`` and ``spindle_rpm = "100"`` are errors, not 1 and 100);
  an integer field takes an integer only; arrays of TOML become tuples where the schema
  says tuple;
* finite: NaN and +-inf are refused in every number field (``inf`` only where the schema
  gives it a meaning, :data:`OrInfinity`);
* magnitude: a number without a stated range must lie within +-:data:`MAX_MAGNITUDE`;
  lengths that are positions or heights use :data:`Length` (+-:data:`MAX_LENGTH_MM`),
  beyond which double precision cannot resolve nanometres.
"""

from __future__ import annotations

import math
import types
import typing
from collections.abc import Iterator
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, ValidationError, model_validator

from .errors import SceneError
from .messages import bound_text

__all__ = ["Section", "Length", "Region", "Phase", "OrInfinity", "MAX_LENGTH_MM",
           "MAX_MAGNITUDE"]

#: largest |position| or |height| in mm (10 m): a double then still resolves 1e-12 mm
MAX_LENGTH_MM = 1e4
#: largest |value| of a number field that states no range of its own
MAX_MAGNITUDE = 1e9  # not a unit conversion

#: a position or height in mm (finite, within +-MAX_LENGTH_MM)
Length = Annotated[float, Field(ge=-MAX_LENGTH_MM, le=MAX_LENGTH_MM)]
#: [x0, y0, x1, y1], mm
Region = tuple[Length, Length, Length, Length]
#: a phase angle in rad (within +-MAX_LENGTH_MM rad: sin keeps 12 digits there)
Phase = Annotated[float, Field(ge=-MAX_LENGTH_MM, le=MAX_LENGTH_MM)]


def _not_nan(v: float) -> float:
    if math.isnan(v):
        raise ValueError("must be a number, not nan")
    return v


#: a number for which +inf means something (a closed-loop bandwidth: inf = ideal): the one
#: kind of number field that takes ``inf`` (never ``nan``)
OrInfinity = Annotated[float, Field(allow_inf_nan=True), AfterValidator(_not_nan)]


def _has_tuple(annotation: Any) -> bool:
    origin = typing.get_origin(annotation)
    if origin is tuple or annotation is tuple:
        return True
    return any(_has_tuple(a) for a in typing.get_args(annotation)
               if not isinstance(a, (str, int, float)))


def _as_tuples(annotation: Any, value: Any) -> Any:
    """``value`` with TOML / JSON arrays turned into tuples wherever ``annotation`` says
    tuple (inside lists, dicts, optionals and annotated types too); other values as they
    are (the validation that follows judges them)."""
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin is typing.Annotated:
        return _as_tuples(args[0], value)
    if origin is typing.Union or origin is types.UnionType:
        for a in args:
            if a is type(None):
                continue
            a_origin = typing.get_origin(a)
            if (isinstance(value, (list, tuple)) and (a is tuple or a_origin in (tuple, list))) \
                    or (isinstance(value, dict) and a_origin is dict):
                return _as_tuples(a, value)
        return value
    if (origin is tuple or annotation is tuple) and isinstance(value, (list, tuple)):
        if args and args[-1] is not Ellipsis and len(args) == len(value):
            return tuple(_as_tuples(a, v) for a, v in zip(args, value))
        if args and args[-1] is Ellipsis:
            return tuple(_as_tuples(args[0], v) for v in value)
        return tuple(value)
    if origin is list and isinstance(value, list) and args:
        return [_as_tuples(args[0], v) for v in value]
    if origin is dict and isinstance(value, dict) and len(args) == 2:
        return {k: _as_tuples(args[1], v) for k, v in value.items()}
    return value


def _bounds(field: Any) -> tuple[str | None, str | None]:
    """The field's own ends as a range shows them (``"[0"``, ``"1)"``; None: no end)."""
    lo = hi = None
    for m in field.metadata:
        if getattr(m, "gt", None) is not None:
            lo = f"({bound_text(m.gt)}"
        elif getattr(m, "ge", None) is not None:
            lo = f"[{bound_text(m.ge)}"
        if getattr(m, "lt", None) is not None:
            hi = f"{bound_text(m.lt)})"
        elif getattr(m, "le", None) is not None:
            hi = f"{bound_text(m.le)}]"
    return lo, hi


def _numbers(value: Any, name: str) -> Iterator[tuple[str, float]]:
    """(dotted name, value) of every float inside ``value`` (tuples, lists: by index;
    dicts: by key)."""
    if isinstance(value, bool):
        return
    if isinstance(value, float):
        yield name, value
    elif isinstance(value, (tuple, list)):
        for i, v in enumerate(value):
            yield from _numbers(v, f"{name}.{i}")
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from _numbers(v, f"{name}.{k}")


class Section(BaseModel):
    """A scene section.  Unknown keys are rejected; values are validated on assignment;
    types are strict and numbers finite (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", validate_assignment=True, frozen=False,
                              strict=True, allow_inf_nan=False)

    @model_validator(mode="before")
    @classmethod
    def _arrays_as_tuples(cls, data: Any) -> Any:
        """TOML and JSON have arrays, not tuples: accept a list where a tuple is due
        (strict mode would refuse it)."""
        if not isinstance(data, dict):
            return data
        out = None
        for name, field in cls.model_fields.items():
            key = field.alias or name
            v = data.get(key)
            if isinstance(v, (list, dict)) and _has_tuple(field.annotation):
                if out is None:
                    out = dict(data)
                out[key] = _as_tuples(field.annotation, v)
        return data if out is None else out

    def __setattr__(self, name: str, value: Any) -> None:
        # the same on assignment (validated too: validate_assignment)
        field = type(self).model_fields.get(name)
        if isinstance(value, (list, dict)) and field is not None and _has_tuple(field.annotation):
            value = _as_tuples(field.annotation, value)
        try:
            super().__setattr__(name, value)
        except ValidationError as err:
            e = err.errors()[0]
            loc = ".".join(str(p) for p in e["loc"]) or name
            shown = repr(value)
            shown = shown if len(shown) <= 80 else shown[:77] + "..."
            raise SceneError(f"{type(self).__name__}.{loc}: {e['msg']}; received {shown}") from None

    @model_validator(mode="after")
    def _magnitudes(self) -> "Section":
        for name, field in type(self).model_fields.items():
            lo, hi = _bounds(field)
            if lo and hi:
                continue
            for where, v in _numbers(getattr(self, name, None), name):
                if math.isfinite(v) and ((not hi and v > MAX_MAGNITUDE)
                                         or (not lo and v < -MAX_MAGNITUDE)):
                    raise ValueError(f"{where} must be within {lo or f'[-{MAX_MAGNITUDE:g}'}, "
                                     f"{hi or f'{MAX_MAGNITUDE:g}]'}, received {v!r}")
        return self
