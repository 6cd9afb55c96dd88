"""The bounds of a fit's free tool keys against the measured cutting edge, before any
evaluation.

A measured edge (``tool.edge_profile``, ``tool.waviness``) is refused by the cut where its
deviation exceeds 1 % of the nose radius or where it folds back over the radial offset
(:meth:`~render_inspect.toolpath.EdgeProfile.check`).  A fit whose free ``tool.nose_radius``,
``tool.edge_scale``, ``tool.included_angle_deg`` or waviness amplitude
(``tool.waviness.K.0``) may go where the edge is refused would see its evaluations there
fail one by one.  The bounds are checked first: a bound the user gave (``--bounds``) that
reaches there is refused in one line with the value the edge allows; a bound the user did
not give (the schema's range) is narrowed to that value, and a warning says so.

Each check is linear in the deviation's scale and amplitudes and in the nose radius for a
given angle along the edge (the deviation times the scale, against 1 % of the radius; the
radial offset's step), so along one key the values the edge allows form one interval
around the start, and over a box of several keys the worst cases lie at its corners: the
keys are taken in turn, each one's limit found by bisection (below a thousandth of its
sixth significant digit, then given to six digits on the allowed side) with the keys
before it at each corner of their bounds."""

from __future__ import annotations

import copy
import itertools
import logging
import math
import re
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..core.errors import InputError
from ..fit import FreeParameter, set_value
from ..report import key_unit
from ..toolpath import Tool
from ._toolpath import check_tool_edge

if TYPE_CHECKING:
    from ..scene import Scene

__all__ = ["edge_bounds", "EDGE_KEYS"]

log = logging.getLogger("render_inspect")

#: the free keys whose bounds are checked against the measured edge (a pattern each)
EDGE_KEYS = (r"tool\.nose_radius", r"tool\.edge_scale", r"tool\.included_angle_deg",
             r"tool\.waviness\.\d+\.0")
#: most halvings of the interval between a start and a refused bound (they stop below a
#: thousandth of the limit's sixth significant digit)
_STEPS = 200
#: the bisection stops once its interval is below this fraction of the sixth digit
_FINER = 1e-3  # not a unit conversion


def _edge_key(key: str) -> bool:
    return any(re.fullmatch(p, key) for p in EDGE_KEYS)


def _refusal(scene: Scene, tool: dict, values: dict) -> str | None:
    """Why the measured edge is refused with the tool keys set to ``values``, or None."""
    d = {"tool": copy.deepcopy(tool)}
    for k, v in values.items():
        set_value(d, k, v)
    try:
        Tool.from_config(type(scene.tool).model_validate(d["tool"]))
    except InputError as err:
        return str(err)
    except ValueError as err:  # (the section's own rule: a waviness amplitude's range)
        errors = getattr(err, "errors", None)
        return str(errors()[0]["msg"]) if callable(errors) else str(err)
    return None


def edge_bounds(scene: Scene, params: Sequence[FreeParameter], given: dict
                ) -> tuple[list[FreeParameter], list[dict]]:
    """(the free parameters, with the bounds of their tool keys narrowed to what the
    scene's measured cutting edge allows; one record per narrowed bound: ``key``,
    ``bound`` ("lower" or "upper"), ``from``, ``to``, ``why``).  A bound in ``given``
    (``--bounds``: key -> (lower, upper)) that reaches where the edge is refused is an
    :class:`InputError` in one line naming the key, its bound and the value the edge
    allows; a bound from the schema is narrowed, with a warning.  A scene without a
    measured edge, or without a free tool key the edge depends on, keeps its bounds."""
    out = list(params)
    keys = [i for i, p in enumerate(out) if _edge_key(p.key)]
    if not keys or check_tool_edge(scene) is None:
        return out, []
    tool = scene.to_dict()["tool"]
    done: list[FreeParameter] = []
    narrowed: list[dict] = []
    for i in keys:
        p = out[i]
        corners = [dict(zip([q.key for q in done], c))
                   for c in itertools.product(*[(q.lower, q.upper) for q in done])]

        def refused(value: float) -> tuple[str, dict] | None:
            for c in corners:
                why = _refusal(scene, tool, {**c, p.key: value})
                if why is not None:
                    return why, c
            return None

        bounds = [p.lower, p.upper]
        for side, b in ((0, p.lower), (1, p.upper)):
            bad = refused(b)
            if bad is None:
                continue
            if refused(p.start) is not None:  # (the keys before it at a corner of theirs)
                raise InputError(f"--free {p.key}: the measured cutting edge is refused at the "
                                 f"scene's {p.key} = {p.start:g} with {_corner(bad[1], done)} "
                                 f"({bad[0]}): narrow the bounds of those keys")
            ok, no = p.start, b
            for _ in range(_STEPS):
                if abs(no - ok) <= _FINER * _quantum(ok, p.start):
                    break
                mid = 0.5 * (ok + no)
                if refused(mid) is None:
                    ok = mid
                else:
                    no = mid
            # to six significant digits (the nearest, else rounded toward the start): a
            # value the edge allows
            ok = next((v for v in (_rounded(ok, p.start, nearest=True), _rounded(ok, p.start))
                       if refused(v) is None), ok)
            why, corner = bad
            unit = f" {key_unit(p.key)}" if key_unit(p.key) else ""
            word = ("smallest", "lower", "above") if side == 0 else ("largest", "upper", "below")
            with_ = f" with {_corner(corner, done)}" if corner else ""
            if p.key in given:
                a, c = given[p.key]
                raise InputError(f"--bounds {p.key}={a:g},{c:g}: the measured cutting edge is "
                                 f"refused at {p.key} = {b:g}{unit}{with_} ({why}); the "
                                 f"{word[0]} value it allows is {ok:.6g}{unit}: set the "
                                 f"{word[1]} bound there or {word[2]}")
            bounds[side] = ok
            narrowed.append({"key": p.key, "bound": word[1], "from": b, "to": ok, "why": why})
            log.warning("warning: fit: the %s bound of %s, %g%s (the schema's), narrowed to "
                        "%.6g%s%s, the %s value the measured cutting edge allows (at %g%s: "
                        "%s); give --bounds %s=A,B to choose others", word[1], p.key, b, unit,
                        ok, unit, with_, word[0], b, unit, why, p.key)
        if bounds != [p.lower, p.upper]:
            out[i] = p.narrowed(*bounds)
        done.append(out[i])
    return out, narrowed


def _quantum(value: float, start: float) -> float:
    """The sixth significant digit of the larger of |value| and |start|."""
    m = max(abs(value), abs(start))
    return 10.0 ** (math.floor(math.log10(m)) - 5) if m > 0 else 1e-300


def _rounded(value: float, start: float, *, nearest: bool = False) -> float:
    """``value`` to six significant digits of the larger of it and ``start`` (a limit near
    0 is 0): the nearest such number, or (``nearest`` false) the one toward ``start``."""
    q = _quantum(value, start)
    n = round(value / q) if nearest else (math.ceil(value / q) if start > value
                                          else math.floor(value / q))
    r = float(f"{n * q:.6g}")
    return min(r, start) if start > value else max(r, start)


def _corner(values: dict[str, Any], params: Sequence[FreeParameter]) -> str:
    """The keys of a corner of the bounds, each at its bound: "KEY at its lower bound V"."""
    lower = {q.key: q.lower for q in params}
    return ", ".join(f"{k} at its {'lower' if v == lower.get(k) else 'upper'} bound {v:g}"
                     + (f" {key_unit(k)}" if key_unit(k) else "") for k, v in values.items())
