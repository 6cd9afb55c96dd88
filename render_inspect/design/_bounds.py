"""The design's true highest point over a part, not a sampled one.

A machine program's clearance plane must lie above every point of the part: a maximum
taken from samples misses a narrow peak between them.  :func:`max_height` bounds the
highest height over an outline from above:

* where the design has an analytic bound (:func:`height_interval`: an expression, a
  plane, a sinusoidal grid, a compound of those), by branch and bound: the outline is
  covered with boxes, each box's heights are bounded by interval arithmetic over the
  design's formula (every operation maps the intervals of its operands to an interval
  that holds all its values), boxes whose bound lies below the best height found at a
  point are dropped and the rest are split, until the bound is within ``tolerance`` of a
  height the design takes;
* otherwise by a dense evaluation with a slope bound: the highest of the heights on a
  grid of spacing h plus the steepest slope found on that grid times the largest
  distance of any point from the grid (h / sqrt(2)).

The first is a bound on the formula itself (less floating-point rounding, padded); the
second holds when no feature is narrower than the grid and steeper than its samples show
(a design of measured or tabulated heights, a lens or lenslet form).
"""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence
import ast
import math

import numpy as np
import numpy.typing as npt

from ..core.units import MIB_TO_BYTES
from ._analytic import Plane, SinusoidalGrid
from ._base import Surface
from ._compound import Compound
from ._expression import _ALIASES, _CONSTANTS, ExpressionSurface, _flatten, _literal

__all__ = ["height_interval", "max_height", "HeightBound"]

#: boxes the branch and bound keeps at a time; beyond that it stops splitting and takes
#: the (looser, still valid) bound of the boxes it holds
_MAX_BOXES = 1 << 18
#: splits of the branch and bound at most (a box then is 2^-40 of the outline's size)
_MAX_LEVELS = 40
#: grid of the dense evaluation (points along the outline's longer side)
_DENSE = 1025
#: relative and absolute padding of an interval bound for floating-point rounding
_PAD_REL = 1e-12  # not a unit conversion
_PAD_ABS = 1e-12  # not a unit conversion


class HeightBound(tuple):
    """(low, high, method): a height the design takes over the outline (``low``) and an
    upper bound on every height it takes there (``high``), mm; ``method`` says how the
    bound was found (``"interval"`` or ``"dense"``)."""

    def __new__(cls, low, high, method):
        return super().__new__(cls, (float(low), float(high), str(method)))

    def __getnewargs__(self):  # pickled (to Dask's workers) as its three values
        return tuple(self)

    low = property(lambda self: self[0])
    high = property(lambda self: self[1])
    method = property(lambda self: self[2])


# ----------------------------------------------------------------------- intervals
def _iv(lo, hi):
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    bad = np.isnan(lo) | np.isnan(hi)
    if bad.any():
        lo = np.where(bad, -np.inf, lo)
        hi = np.where(bad, np.inf, hi)
    return lo, hi


def _mul(a, b):
    with np.errstate(all="ignore"):
        p = [a[i] * b[j] for i in (0, 1) for j in (0, 1)]
    stack = np.stack(np.broadcast_arrays(*p))
    nan = np.isnan(stack).any(axis=0)  # 0 * inf: no bound
    return _iv(np.where(nan, -np.inf, stack.min(axis=0)), np.where(nan, np.inf, stack.max(axis=0)))


def _recip(b):
    lo, hi = b
    zero = (lo <= 0) & (hi >= 0)
    with np.errstate(all="ignore"):
        return _iv(np.where(zero, -np.inf, 1.0 / hi), np.where(zero, np.inf, 1.0 / lo))


def _mono(fn, a, lo_clip=None, hi_clip=None, decreasing=False):
    lo, hi = a
    if lo_clip is not None:
        lo, hi = np.maximum(lo, lo_clip), np.maximum(hi, lo_clip)
    if hi_clip is not None:
        lo, hi = np.minimum(lo, hi_clip), np.minimum(hi, hi_clip)
    with np.errstate(all="ignore"):
        f_lo, f_hi = fn(lo), fn(hi)
    return _iv(f_hi, f_lo) if decreasing else _iv(f_lo, f_hi)


def _sin(a):
    lo, hi = a
    with np.errstate(all="ignore"):
        s_lo, s_hi = np.sin(lo), np.sin(hi)
        wide = ~((hi - lo) < 2 * math.pi) | ~np.isfinite(lo) | ~np.isfinite(hi)
        k_max = np.ceil((lo - math.pi / 2) / (2 * math.pi))
        has_max = math.pi / 2 + 2 * math.pi * k_max <= hi
        k_min = np.ceil((lo + math.pi / 2) / (2 * math.pi))
        has_min = -math.pi / 2 + 2 * math.pi * k_min <= hi
    out_lo = np.where(has_min | wide, -1.0, np.minimum(s_lo, s_hi))
    out_hi = np.where(has_max | wide, 1.0, np.maximum(s_lo, s_hi))
    return _iv(out_lo, out_hi)


def _cos(a):
    return _sin((a[0] + math.pi / 2, a[1] + math.pi / 2))


def _tan(a):
    lo, hi = a
    with np.errstate(all="ignore"):
        k = np.ceil((lo - math.pi / 2) / math.pi)
        pole = (math.pi / 2 + math.pi * k <= hi) | ~np.isfinite(lo) | ~np.isfinite(hi)
        return _iv(np.where(pole, -np.inf, np.tan(lo)), np.where(pole, np.inf, np.tan(hi)))


def _abs(a):
    lo, hi = a
    m = np.maximum(np.abs(lo), np.abs(hi))
    low = np.where((lo <= 0) & (hi >= 0), 0.0, np.minimum(np.abs(lo), np.abs(hi)))
    return _iv(low, m)


def _even(fn, a):
    """An even function increasing on [0, inf) (cosh)."""
    lo, hi = _abs(a)
    with np.errstate(all="ignore"):
        return _iv(fn(lo), fn(hi))


def _pow_const(a, c):
    lo, hi = a
    if float(c).is_integer():
        n = int(c)
        if n == 0:
            return _iv(np.ones_like(lo), np.ones_like(hi))
        if n < 0:
            return _recip(_pow_const(a, -n))
        with np.errstate(all="ignore"):
            if n % 2:
                return _iv(lo ** n, hi ** n)
            m = _abs(a)
            return _iv(m[0] ** n, m[1] ** n)
    # a real power is defined for a >= 0 only (elsewhere the design is not finite and
    # refused where it is evaluated)
    with np.errstate(all="ignore"):
        lo, hi = np.maximum(lo, 0.0), np.maximum(hi, 0.0)
        if c > 0:
            return _iv(lo ** c, hi ** c)
        return _iv(np.where(hi > 0, hi ** c, np.inf), np.where(lo > 0, lo ** c, np.inf))


_UNARY = {
    "sin": _sin,
    "cos": _cos,
    "tan": _tan,
    "arcsin": lambda a: _mono(np.arcsin, a, -1.0, 1.0),
    "arccos": lambda a: _mono(np.arccos, a, -1.0, 1.0, decreasing=True),
    "arctan": lambda a: _mono(np.arctan, a),
    "sinh": lambda a: _mono(np.sinh, a),
    "cosh": lambda a: _even(np.cosh, a),
    "tanh": lambda a: _mono(np.tanh, a),
    "exp": lambda a: _mono(np.exp, a),
    "log": lambda a: _mono(np.log, a, 0.0),
    "log10": lambda a: _mono(np.log10, a, 0.0),
    "sqrt": lambda a: _mono(np.sqrt, a, 0.0),
    "abs": _abs,
    "sign": lambda a: _mono(np.sign, a),
}


def _hypot(a, b):
    ma, mb = _abs(a), _abs(b)
    return _iv(np.hypot(ma[0], mb[0]), np.hypot(ma[1], mb[1]))


_BINARY = {
    "arctan2": lambda a, b: _iv(np.full(np.broadcast(a[0], b[0]).shape, -math.pi),
                                np.full(np.broadcast(a[0], b[0]).shape, math.pi)),
    "hypot": _hypot,
    "minimum": lambda a, b: _iv(np.minimum(a[0], b[0]), np.minimum(a[1], b[1])),
    "maximum": lambda a, b: _iv(np.maximum(a[0], b[0]), np.maximum(a[1], b[1])),
}


def _expression_interval(surface, x, y):
    def ev(node):
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant):
            v = float(node.value)
            return _iv(v, v)
        if isinstance(node, ast.Name):
            if node.id == "x":
                return x
            if node.id == "y":
                return y
            v = surface.constants[node.id] if node.id in surface.constants else _CONSTANTS[node.id]
            return _iv(v, v)
        if isinstance(node, ast.UnaryOp):
            a = ev(node.operand)
            return _iv(-a[1], -a[0]) if isinstance(node.op, ast.USub) else a
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            a = ev(node.left)
            c = _literal(node.right)
            if c is not None:
                return _pow_const(a, c)
            b = ev(node.right)  # a ** b = exp(b log a), a > 0
            return _UNARY["exp"](_mul(b, _UNARY["log"](a)))
        if isinstance(node, ast.BinOp):
            first, ops = _flatten(node)
            if not ops:  # a lone binary operation of another family
                ops = [(node.op, node.right)]
                first = node.left
            acc = ev(first)
            for op, operand in ops:
                b = ev(operand)
                if isinstance(op, ast.Add):
                    acc = _iv(acc[0] + b[0], acc[1] + b[1])
                elif isinstance(op, ast.Sub):
                    acc = _iv(acc[0] - b[1], acc[1] - b[0])
                elif isinstance(op, ast.Mult):
                    acc = _mul(acc, b)
                else:
                    acc = _mul(acc, _recip(b))
            return acc
        fname = _ALIASES.get(node.func.id, node.func.id)
        args = [ev(a) for a in node.args]
        if fname in _UNARY:
            return _UNARY[fname](args[0])
        return _BINARY[fname](*args)

    with np.errstate(all="ignore"):
        return ev(surface._tree)


def height_interval(surface: Surface, x0: npt.ArrayLike, y0: npt.ArrayLike, x1: npt.ArrayLike,
                    y1: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray] | None:
    """(low, high): bounds on the heights of ``surface`` over each box [x0, x1] x [y0,
    y1] (arrays, mm), or None when the design has no analytic bound."""
    x0, y0, x1, y1 = (np.asarray(v, dtype=np.float64) for v in (x0, y0, x1, y1))
    if isinstance(surface, ExpressionSurface):
        lo, hi = _expression_interval(surface, (x0, x1), (y0, y1))
    elif isinstance(surface, Plane):
        ends = [surface.sx * x + surface.sy * y + surface.offset for x in (x0, x1) for y in (y0, y1)]
        lo, hi = np.minimum.reduce(ends), np.maximum.reduce(ends)
    elif isinstance(surface, SinusoidalGrid):
        cx = _cos((surface.kx * x0 + surface.px, surface.kx * x1 + surface.px))
        cy = _cos((surface.ky * y0 + surface.py, surface.ky * y1 + surface.py))
        ax, ay = _mul((surface.ax, surface.ax), cx), _mul((surface.ay, surface.ay), cy)
        lo, hi = ax[0] + ay[0] + surface.offset, ax[1] + ay[1] + surface.offset
    elif isinstance(surface, Compound):
        a = height_interval(surface.base, x0, y0, x1, y1)
        b = height_interval(surface.feature, x0, y0, x1, y1)
        if a is None or b is None:
            return None
        lo, hi = a[0] + b[0], a[1] + b[1]
    else:
        return None
    lo, hi = np.broadcast_arrays(np.asarray(lo, np.float64), np.asarray(hi, np.float64))
    pad_lo = _PAD_REL * np.abs(lo) + _PAD_ABS
    pad_hi = _PAD_REL * np.abs(hi) + _PAD_ABS
    with np.errstate(invalid="ignore"):
        return _iv(lo - pad_lo, hi + pad_hi)


# ----------------------------------------------------------------------- the maximum
def _outline_box(outline):
    if outline[0] == "disc":
        _, cx, cy, r = outline
        return cx - r, cy - r, cx + r, cy + r
    _, x0, y0, x1, y1 = outline
    return x0, y0, x1, y1


def _meets(outline, x0, y0, x1, y1):
    """Which boxes meet the outline."""
    if outline[0] == "disc":
        _, cx, cy, r = outline
        dx = np.maximum(np.maximum(x0 - cx, cx - x1), 0.0)
        dy = np.maximum(np.maximum(y0 - cy, cy - y1), 0.0)
        return dx * dx + dy * dy <= r * r
    return np.ones(np.shape(x0), dtype=bool)


def _inside(outline, x, y):
    if outline[0] == "disc":
        _, cx, cy, r = outline
        return (x - cx) ** 2 + (y - cy) ** 2 <= r * r
    _, x0, y0, x1, y1 = outline
    return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)


def _finite_heights(surface, x, y):
    try:
        with np.errstate(all="ignore"):
            z = np.asarray(surface.height(x, y), dtype=np.float64)
    except Exception:  # noqa: BLE001 - a design not defined there gives no lower bound
        return np.full(np.shape(x), -np.inf)
    return np.where(np.isfinite(z), z, -np.inf)


def _interval_max(surface, outline, tolerance):
    bx0, by0, bx1, by1 = _outline_box(outline)
    n = 64
    ex = np.linspace(bx0, bx1, n + 1)
    ey = np.linspace(by0, by1, n + 1)
    X0, Y0 = np.meshgrid(ex[:-1], ey[:-1])
    X1, Y1 = np.meshgrid(ex[1:], ey[1:])
    boxes = [a.ravel() for a in (X0, Y0, X1, Y1)]
    keep = _meets(outline, *boxes)
    boxes = [a[keep] for a in boxes]
    # the best height at a point of the part: the box centres inside the outline and a
    # grid over it
    gx, gy = np.meshgrid(np.linspace(bx0, bx1, 257), np.linspace(by0, by1, 257))
    inside = _inside(outline, gx, gy)
    z = _finite_heights(surface, gx[inside], gy[inside])
    low = float(z.max()) if z.size else -math.inf
    high_dropped = -math.inf
    for level in range(_MAX_LEVELS + 1):
        bound = height_interval(surface, *boxes)
        if bound is None:
            return None
        hi = bound[1]
        cx, cy = (boxes[0] + boxes[2]) / 2, (boxes[1] + boxes[3]) / 2
        ins = _inside(outline, cx, cy)
        if ins.any():
            low = max(low, float(_finite_heights(surface, cx[ins], cy[ins]).max()))
        live = hi > low + tolerance
        if (~live).any():
            high_dropped = max(high_dropped, float(hi[~live].max()))
        boxes = [a[live] for a in boxes]
        if not boxes[0].size:
            break
        if level == _MAX_LEVELS or 4 * boxes[0].size > _MAX_BOXES:
            high_dropped = max(high_dropped, float(hi[live].max()))
            boxes = None
            break
        # split each live box in four
        x0, y0, x1, y1 = boxes
        xm, ym = (x0 + x1) / 2, (y0 + y1) / 2
        boxes = [np.concatenate(v) for v in (
            (x0, xm, x0, xm), (y0, y0, ym, ym), (xm, x1, xm, x1), (ym, ym, y1, y1))]
        keep = _meets(outline, *boxes)
        boxes = [a[keep] for a in boxes]
    high = max(high_dropped, low)
    if not math.isfinite(high):
        return None
    return HeightBound(low, high, "interval")


def _dense_max(surface, outline):
    bx0, by0, bx1, by1 = _outline_box(outline)
    span = max(bx1 - bx0, by1 - by0, 1e-12)
    h = span / (_DENSE - 1)
    nx = int(math.ceil((bx1 - bx0) / h)) + 1
    ny = int(math.ceil((by1 - by0) / h)) + 1
    xs = bx0 + h * np.arange(nx)
    low, slope = -math.inf, 0.0
    rows = max(1, MIB_TO_BYTES // max(nx, 1))  # about a million samples a block
    for a in range(0, ny, rows):
        ys = by0 + h * np.arange(a, min(ny, a + rows))
        X, Y = np.meshgrid(xs, ys)
        inside = _inside(outline, X, Y)
        # points outside the outline but within one spacing of it stand for the edge
        near = inside | _inside(_grown(outline, h), X, Y)
        if not near.any():
            continue
        z = _finite_heights(surface, X[near], Y[near])
        if z.size:
            low = max(low, float(z.max()))
        try:
            with np.errstate(all="ignore"):
                gx, gy = surface.gradient(X[near], Y[near])
            g = np.hypot(gx, gy)
            g = g[np.isfinite(g)]
            if g.size:
                slope = max(slope, float(g.max()))
        except Exception:  # noqa: BLE001 - no gradient there: the heights stand alone
            pass
    if not math.isfinite(low):
        return None
    return HeightBound(low, low + slope * h / math.sqrt(2.0), "dense")


def _grown(outline, d):
    if outline[0] == "disc":
        _, cx, cy, r = outline
        return ("disc", cx, cy, r + d)
    _, x0, y0, x1, y1 = outline
    return ("box", x0 - d, y0 - d, x1 + d, y1 + d)


def max_height(surface: Surface, outline: Sequence[Any], *,
               tolerance: float = 1e-6) -> HeightBound | None:
    """A :class:`HeightBound` on the heights of ``surface`` over ``outline``
    (``("disc", cx, cy, r)`` or ``("box", x0, y0, x1, y1)``, mm): by branch and bound on
    the design's interval bound where it has one (to ``tolerance`` mm), by a dense
    evaluation with a slope bound otherwise.  None when the design has no finite height
    over the outline.  The answer is kept on the surface (a design does not change)."""
    key = (tuple(float(v) for v in outline[1:]), str(outline[0]), float(tolerance))
    cache = surface.__dict__.setdefault("_max_height_cache", {})
    if key not in cache:
        b = None
        if height_interval(surface, 0.0, 0.0, 0.0, 0.0) is not None:
            b = _interval_max(surface, outline, float(tolerance))
        cache[key] = b if b is not None else _dense_max(surface, outline)
    return cache[key]
