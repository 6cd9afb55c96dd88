"""A user expression z = F(x, y), parsed with :mod:`ast` and evaluated safely.

Nothing is passed to ``eval`` or ``exec``: the expression is parsed into a syntax tree,
every node is checked against a whitelist (numbers, the names ``x``, ``y``, ``pi``, ``e``
and the user's constants, the operators ``+ - * / **`` and unary ``-``/``+``, calls of the
whitelisted numpy functions), and the tree is evaluated by a small interpreter.  The same
interpreter carries second-order derivatives forward (a two-variable Taylor "jet"), so
the gradient and Hessian are exact, not finite differences.
"""

from __future__ import annotations

import ast
import math
from typing import Literal

import numpy as np
from pydantic import Field

from ..core.errors import InputError
from ..core.section import Section
from ._base import Surface
from ._registry import register_design

__all__ = ["ExpressionSurface", "parse_expression", "ALLOWED_FUNCTIONS"]

MAX_LENGTH = 10000     # characters
MAX_NODES = 5000       # syntax-tree nodes
MAX_DEPTH = 60         # nesting depth: parentheses and calls (a flat sum or product is one level)
MAX_EXPONENT = 64.0    # |constant exponent| of **
MAX_LITERAL = 1e12     # |numeric literal|  # not a unit conversion

_NAME = "design.expr"


# ---- jets: value, gradient (x, y), Hessian (xx, xy, yy) -----------------------------------
class _Jet:
    """A value with its first and (optionally) second derivatives in x and y."""
    __slots__ = ("v", "g", "h")

    def __init__(self, v, g=None, h=None):
        self.v, self.g, self.h = v, g, h

    @property
    def order(self):
        return 0 if self.g is None else (1 if self.h is None else 2)


def _const(v, order):
    v = np.float64(v)  # numpy arithmetic: 1/0 -> inf, (-8)**(1/3) -> nan (checked at the end)
    if order == 0:
        return _Jet(v)
    if order == 1:
        return _Jet(v, (0.0, 0.0))
    return _Jet(v, (0.0, 0.0), (0.0, 0.0, 0.0))


def _chain1(f, p0, p1, p2):
    """phi(f) given phi(f.v) = p0, phi'(f.v) = p1, phi''(f.v) = p2 (p2 only for order 2)."""
    if f.g is None:
        return _Jet(p0)
    fx, fy = f.g
    g = (p1 * fx, p1 * fy)
    if f.h is None:
        return _Jet(p0, g)
    fxx, fxy, fyy = f.h
    h = (p2 * fx * fx + p1 * fxx, p2 * fx * fy + p1 * fxy, p2 * fy * fy + p1 * fyy)
    return _Jet(p0, g, h)


def _chain2(a, b, p0, pa, pb, paa, pab, pbb):
    """phi(a, b) from its partial derivatives at (a.v, b.v)."""
    if a.g is None:
        return _Jet(p0)
    (ax, ay), (bx, by) = a.g, b.g
    g = (pa * ax + pb * bx, pa * ay + pb * by)
    if a.h is None:
        return _Jet(p0, g)
    (axx, axy, ayy), (bxx, bxy, byy) = a.h, b.h

    def second(ai, aj, bi, bj, aij, bij):
        return paa * ai * aj + pab * (ai * bj + aj * bi) + pbb * bi * bj + pa * aij + pb * bij

    h = (second(ax, ax, bx, bx, axx, bxx), second(ax, ay, bx, by, axy, bxy),
         second(ay, ay, by, by, ayy, byy))
    return _Jet(p0, g, h)


def _add(a, b, sign=1.0):
    g = None if a.g is None else (a.g[0] + sign * b.g[0], a.g[1] + sign * b.g[1])
    h = None if a.h is None else tuple(p + sign * q for p, q in zip(a.h, b.h))
    return _Jet(a.v + sign * b.v, g, h)


def _mul(a, b):
    return _chain2(a, b, a.v * b.v, b.v, a.v, 0.0, 1.0, 0.0)


def _neg(a):
    return _chain1(a, -a.v, -1.0, 0.0)


def _recip(a):
    v = 1.0 / a.v
    return _chain1(a, v, -v * v, 2 * v * v * v)


def _pow(a, b, const_exp):
    if const_exp is not None:           # a ** c: defined for negative a with integer c
        c = const_exp
        v = a.v ** c
        p1 = c * a.v ** (c - 1) if c != 0 else 0.0 * a.v
        p2 = c * (c - 1) * a.v ** (c - 2) if c not in (0, 1) else 0.0 * a.v
        return _chain1(a, v, p1, p2)
    # a ** b = exp(b log a), a > 0
    la = np.log(a.v)
    v = a.v ** b.v
    pa = b.v * a.v ** (b.v - 1)
    pb = v * la
    paa = b.v * (b.v - 1) * a.v ** (b.v - 2)
    pab = a.v ** (b.v - 1) * (1 + b.v * la)
    pbb = v * la * la
    return _chain2(a, b, v, pa, pb, paa, pab, pbb)


def _unary(fn):
    """Jet rule from (phi, phi', phi'') as functions of the value t."""
    f0, f1, f2 = fn

    def apply(a):
        t = a.v
        return _chain1(a, f0(t), f1(t) if a.order >= 1 else None, f2(t) if a.order == 2 else None)
    return apply


_UNARY = {
    "sin": (np.sin, np.cos, lambda t: -np.sin(t)),
    "cos": (np.cos, lambda t: -np.sin(t), lambda t: -np.cos(t)),
    "tan": (np.tan, lambda t: 1 / np.cos(t) ** 2, lambda t: 2 * np.tan(t) / np.cos(t) ** 2),
    "arcsin": (np.arcsin, lambda t: 1 / np.sqrt(1 - t * t), lambda t: t / (1 - t * t) ** 1.5),
    "arccos": (np.arccos, lambda t: -1 / np.sqrt(1 - t * t), lambda t: -t / (1 - t * t) ** 1.5),
    "arctan": (np.arctan, lambda t: 1 / (1 + t * t), lambda t: -2 * t / (1 + t * t) ** 2),
    "sinh": (np.sinh, np.cosh, np.sinh),
    "cosh": (np.cosh, np.sinh, np.cosh),
    "tanh": (np.tanh, lambda t: 1 / np.cosh(t) ** 2, lambda t: -2 * np.tanh(t) / np.cosh(t) ** 2),
    "exp": (np.exp, np.exp, np.exp),
    "log": (np.log, lambda t: 1 / t, lambda t: -1 / (t * t)),
    "log10": (np.log10, lambda t: 1 / (t * math.log(10)), lambda t: -1 / (t * t * math.log(10))),
    "sqrt": (np.sqrt, lambda t: 0.5 / np.sqrt(t), lambda t: -0.25 / t ** 1.5),
    "abs": (np.abs, np.sign, lambda t: 0.0 * t),
    "sign": (np.sign, lambda t: 0.0 * t, lambda t: 0.0 * t),
}
_ALIASES = {"asin": "arcsin", "acos": "arccos", "atan": "arctan", "atan2": "arctan2",
            "fabs": "abs"}


def _arctan2(a, b):
    r2 = a.v * a.v + b.v * b.v
    r4 = r2 * r2
    return _chain2(a, b, np.arctan2(a.v, b.v), b.v / r2, -a.v / r2,
                   -2 * a.v * b.v / r4, (a.v * a.v - b.v * b.v) / r4, 2 * a.v * b.v / r4)


def _hypot(a, b):
    r = np.hypot(a.v, b.v)
    r3 = r ** 3
    return _chain2(a, b, r, a.v / r, b.v / r, b.v * b.v / r3, -a.v * b.v / r3, a.v * a.v / r3)


def _select(mask, a, b):
    g = None if a.g is None else tuple(np.where(mask, p, q) for p, q in zip(a.g, b.g))
    h = None if a.h is None else tuple(np.where(mask, p, q) for p, q in zip(a.h, b.h))
    return _Jet(np.where(mask, a.v, b.v), g, h)


_BINARY = {
    "arctan2": _arctan2,
    "hypot": _hypot,
    "minimum": lambda a, b: _select(a.v <= b.v, a, b),
    "maximum": lambda a, b: _select(a.v >= b.v, a, b),
}

#: function names an expression may call
ALLOWED_FUNCTIONS = tuple(sorted(set(_UNARY) | set(_BINARY) | set(_ALIASES)))
_CONSTANTS = {"pi": math.pi, "e": math.e}


_ADDITIVE = (ast.Add, ast.Sub)
_MULTIPLICATIVE = (ast.Mult, ast.Div)


def _family(op):
    if isinstance(op, _ADDITIVE):
        return _ADDITIVE
    if isinstance(op, _MULTIPLICATIVE):
        return _MULTIPLICATIVE
    return None


def _flatten(node):
    """A left-leaning chain ``a + b - c + ...`` (or ``a * b / c ...``) as (first operand,
    [(op, operand), ...]): a flat sum of many terms is one level of nesting, not one per
    term, and is evaluated by a loop, not by recursion."""
    fam = _family(node.op)
    ops = []
    while isinstance(node, ast.BinOp) and fam is not None and isinstance(node.op, fam):
        ops.append((node.op, node.right))
        node = node.left
    ops.reverse()
    return node, ops


# ---- parsing and checking -----------------------------------------------------------------
def _reject(msg, expr):
    shown = expr if len(expr) <= 80 else expr[:77] + "..."
    return InputError(f"{_NAME} {msg}; received {shown!r}.  Allowed: numbers, x, y, pi, e, "
                      f"design.constants, + - * / ** and unary -, and calls of "
                      f"{', '.join(ALLOWED_FUNCTIONS)}")


def parse_expression(expr: str, constants: dict | None = None) -> ast.Expression:
    """Parse and check ``expr``; return its syntax tree or raise :class:`InputError`
    naming ``design.expr`` and what is wrong."""
    if not isinstance(expr, str):
        raise InputError(f"{_NAME} must be a string, received {type(expr).__name__}")
    if not expr.strip():
        raise InputError(f"{_NAME} must not be empty")
    if len(expr) > MAX_LENGTH:
        raise InputError(f"{_NAME} must be at most {MAX_LENGTH} characters, received "
                         f"{len(expr)} characters")
    names = set(constants or ()) | {"x", "y"} | set(_CONSTANTS)
    try:
        tree = ast.parse(expr.strip(), mode="eval")
    except (RecursionError, MemoryError):
        raise _reject("is too long or nested too deeply for the parser (split long products "
                      "into parenthesised groups)", expr) from None
    except (SyntaxError, ValueError) as err:
        raise _reject(f"is not a valid expression ({type(err).__name__}: "
                      f"{getattr(err, 'msg', err)})", expr) from None
    count = 0

    def check(node, depth):
        nonlocal count
        count += 1
        if count > MAX_NODES:
            raise _reject(f"has more than {MAX_NODES} terms", expr)
        if depth > MAX_DEPTH:
            raise _reject(f"is nested deeper than {MAX_DEPTH} levels", expr)
        if isinstance(node, ast.Expression):
            return check(node.body, depth + 1)
        if isinstance(node, ast.Constant):
            v = node.value
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise _reject(f"may contain only real numbers as literals, not {v!r}", expr)
            try:
                fv = float(v)
            except OverflowError:
                fv = math.inf
            if not (math.isfinite(fv) and abs(fv) <= MAX_LITERAL):
                raise _reject(f"literal {v!r} is outside [-{MAX_LITERAL:g}, {MAX_LITERAL:g}]", expr)
            return
        if isinstance(node, ast.Name):
            if node.id not in names:
                raise _reject(f"uses the unknown name {node.id!r} (define it in design.constants)",
                              expr)
            return
        if isinstance(node, ast.UnaryOp):
            if not isinstance(node.op, (ast.USub, ast.UAdd)):
                raise _reject(f"may not use the operator {type(node.op).__name__}", expr)
            return check(node.operand, depth + 1)
        if isinstance(node, ast.BinOp):
            if not isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)):
                raise _reject(f"may not use the operator {type(node.op).__name__}", expr)
            if isinstance(node.op, ast.Pow):
                c = _literal(node.right)
                if c is not None and abs(c) > MAX_EXPONENT:
                    raise _reject(f"exponent {c:g} is outside [-{MAX_EXPONENT:g}, "
                                  f"{MAX_EXPONENT:g}]", expr)
                if c is None and _literal(node.left) is not None and isinstance(node.right, ast.BinOp) \
                        and isinstance(node.right.op, ast.Pow):
                    raise _reject("may not chain powers of numbers (a ** b ** c)", expr)
            if _family(node.op) is not None:
                first, ops = _flatten(node)
                check(first, depth + 1)
                for _, operand in ops:
                    check(operand, depth + 1)
                return
            check(node.left, depth + 1)
            return check(node.right, depth + 1)
        if isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name):
                raise _reject("may call only plain function names (no attribute access)", expr)
            fname = _ALIASES.get(node.func.id, node.func.id)
            if fname not in _UNARY and fname not in _BINARY:
                raise _reject(f"calls the function {node.func.id!r}, which is not allowed", expr)
            if node.keywords:
                raise _reject("may not use keyword arguments", expr)
            want = 1 if fname in _UNARY else 2
            if len(node.args) != want or any(isinstance(a, ast.Starred) for a in node.args):
                raise _reject(f"calls {node.func.id}() with {len(node.args)} arguments, "
                              f"expected {want}", expr)
            for a in node.args:
                check(a, depth + 1)
            return
        raise _reject(f"may not contain {type(node).__name__} ("
                      f"{ast.unparse(node)[:40] if hasattr(ast, 'unparse') else ''})", expr)

    try:
        check(tree, 0)
    except RecursionError:
        raise _reject(f"is nested deeper than {MAX_DEPTH} levels", expr) from None
    return tree


def _literal(node):
    """The numeric value of a literal (with unary signs), else None."""
    sign = 1.0
    while isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        sign = -sign if isinstance(node.op, ast.USub) else sign
        node = node.operand
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
            and not isinstance(node.value, bool):
        return sign * float(node.value)
    return None


# ---- the surface --------------------------------------------------------------------------
class ExpressionSurface(Surface):
    """``z = F(x, y)`` from a user expression (mm in, mm out).

    Parameters
    ----------
    expr : str
        E.g. ``"2e-3*cos(2*pi*x/2.5) + 2e-3*cos(2*pi*y/2.5)"``.  Allowed: numbers, ``x``,
        ``y``, ``pi``, ``e``, the names in ``constants``, ``+ - * / **``, unary minus and
        the functions in :data:`ALLOWED_FUNCTIONS` (numpy names; ``asin``/``acos``/
        ``atan``/``atan2`` are accepted as aliases).
    constants : dict of str to float, optional
        Named constants the expression may use (e.g. ``{"r1": 1000.0}``).

    Gradient and Hessian are exact (forward-mode differentiation of the syntax tree).
    Evaluating to NaN or infinity anywhere raises :class:`InputError`.
    """
    kind = "expression"

    def __init__(self, expr: str, constants: dict | None = None):
        constants = dict(constants or {})
        for k, v in constants.items():
            if not (isinstance(k, str) and k.isidentifier()) or k in ("x", "y") \
                    or k in _CONSTANTS or k in ALLOWED_FUNCTIONS:
                raise InputError(f"design.constants: {k!r} is not allowed as a name (use an "
                                 f"identifier other than x, y, pi, e and the function names)")
            try:
                fv = float(v)
            except (TypeError, ValueError):
                raise InputError(f"design.constants.{k} must be a number, received {v!r}") from None
            if not math.isfinite(fv):
                raise InputError(f"design.constants.{k} must be finite, received {v!r}")
            constants[k] = fv
        self.expr = expr
        self.constants = constants
        self._tree = parse_expression(expr, constants)
        self._check_constant_parts()

    def _check_constant_parts(self):
        """Evaluate every largest part without x and y once: a constant that is not a
        finite number (``1/0``, ``1e12**64``, ``(-8)**(1/3)``) is named at once."""
        stack = [self._tree.body]
        while stack:
            node = stack.pop()
            if not any(isinstance(n, ast.Name) and n.id in ("x", "y") for n in ast.walk(node)):
                if isinstance(node, (ast.Constant, ast.Name)) or not isinstance(node, ast.expr):
                    continue
                with np.errstate(all="ignore"):
                    v = self._eval(node, np.float64(0.0), np.float64(0.0), 0).v
                if not np.all(np.isfinite(v)):
                    part = ast.unparse(node)
                    raise _reject(f"has a constant part that is not a finite number: "
                                  f"{part[:60]!r} = {float(np.ravel(v)[0])!r}", self.expr)
                continue
            stack.extend(c for c in ast.iter_child_nodes(node) if isinstance(c, ast.expr))

    # interpreter
    def _eval(self, node, x, y, order):
        if isinstance(node, ast.Expression):
            return self._eval(node.body, x, y, order)
        if isinstance(node, ast.Constant):
            return _const(float(node.value), order)
        if isinstance(node, ast.Name):
            if node.id == "x":
                return _Jet(x, *(((1.0, 0.0),) if order == 1 else
                                 ((1.0, 0.0), (0.0, 0.0, 0.0)) if order == 2 else ()))
            if node.id == "y":
                return _Jet(y, *(((0.0, 1.0),) if order == 1 else
                                 ((0.0, 1.0), (0.0, 0.0, 0.0)) if order == 2 else ()))
            value = self.constants[node.id] if node.id in self.constants else _CONSTANTS[node.id]
            return _const(value, order)
        if isinstance(node, ast.UnaryOp):
            a = self._eval(node.operand, x, y, order)
            return _neg(a) if isinstance(node.op, ast.USub) else a
        if isinstance(node, ast.BinOp) and _family(node.op) is not None:
            first, ops = _flatten(node)
            acc = self._eval(first, x, y, order)
            for op, operand in ops:
                b = self._eval(operand, x, y, order)
                if isinstance(op, ast.Add):
                    acc = _add(acc, b)
                elif isinstance(op, ast.Sub):
                    acc = _add(acc, b, -1.0)
                elif isinstance(op, ast.Mult):
                    acc = _mul(acc, b)
                else:
                    acc = _mul(acc, _recip(b))
            return acc
        if isinstance(node, ast.BinOp):
            a = self._eval(node.left, x, y, order)
            op = node.op
            if isinstance(op, ast.Pow):
                c = _literal(node.right)
                if c is not None:
                    return _pow(a, None, c)
                return _pow(a, self._eval(node.right, x, y, order), None)
            b = self._eval(node.right, x, y, order)
            if isinstance(op, ast.Add):
                return _add(a, b)
            if isinstance(op, ast.Sub):
                return _add(a, b, -1.0)
            if isinstance(op, ast.Mult):
                return _mul(a, b)
            return _mul(a, _recip(b))      # ast.Div (checked in parse_expression)
        # ast.Call (checked in parse_expression)
        fname = _ALIASES.get(node.func.id, node.func.id)
        args = [self._eval(a, x, y, order) for a in node.args]
        if fname in _UNARY:
            return _unary(_UNARY[fname])(args[0])
        return _BINARY[fname](*args)

    def _run(self, x, y, order):
        x = np.asarray(x, dtype=np.float64)
        y = np.asarray(y, dtype=np.float64)
        x, y = np.broadcast_arrays(x, y)
        with np.errstate(all="ignore"):
            jet = self._eval(self._tree, x, y, order)
        parts = [jet.v] + list(jet.g or ()) + list(jet.h or ())
        parts = [np.broadcast_to(np.asarray(p, dtype=np.float64), x.shape).copy() for p in parts]
        bad = ~np.isfinite(parts[0])
        for p in parts[1:]:
            bad |= ~np.isfinite(p)
        if np.any(bad):
            k = np.flatnonzero(bad.ravel())[0]
            what = "F" if not np.isfinite(parts[0].ravel()[k]) else "a derivative of F"
            raise InputError(f"{_NAME} = {self.expr!r}: {what} is not finite at "
                             f"{int(bad.sum())} point(s), e.g. x = {x.ravel()[k]:.6g}, "
                             f"y = {y.ravel()[k]:.6g} mm; change the expression or shrink "
                             "simulation.region")
        return parts

    def height(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        return self._run(x, y, 0)[0]

    def gradient(self, x: np.ndarray | float,
                 y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
        _, gx, gy = self._run(x, y, 1)
        return gx, gy

    def hessian(self, x: np.ndarray | float,
                y: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        _, _, _, hxx, hxy, hyy = self._run(x, y, 2)
        return hxx, hxy, hyy

    def __repr__(self):
        return f"ExpressionSurface({self.expr!r}, constants={self.constants!r})"


# ------------------------------------------------------------------ scene schema
class ExpressionConfig(Section):
    """A user expression in x and y (mm), evaluated safely (whitelisted functions)."""
    type: Literal["expression"]
    expr: str = Field(..., min_length=1, max_length=MAX_LENGTH)
    constants: dict[str, float] = Field(default_factory=dict, max_length=1000)


register_design(ExpressionConfig, ExpressionSurface)
