"""Unit conversions live in ``render_inspect.core.units`` and nowhere else.

The package keeps millimetres, seconds, rpm and mm/min inside; any other unit is a
boundary that multiplies by a named factor (``MM_TO_NM``, ``PER_MIN_TO_PER_S`` ...).  This
test reads every module of the package with the AST and fails on

(a) a module-level (re)definition of one of ``core.units``' names (``MM_TO_NM = 1e6``);
(b) a module-level constant whose value is a bare conversion literal (``_NM = 1e-6``);
(c) a bare conversion literal (1e6, 1e-6, 1e3, 1e-3, 1e9, 1e-9, 60 ...) multiplied or
    divided by something (``z * 1e6``, ``rpm / 60``, ``x *= 1e3``), and a binary byte
    factor (``2**30``, ``1024**3``, ``1 << 20``).

A number that happens to equal one of those but is no unit conversion (a tolerance, a
sample count, a time-out) says so with a trailing ``# not a unit conversion`` comment on
its line, or better, gets a name of its own.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from render_inspect.core import units

PACKAGE = Path(__file__).resolve().parents[1] / "render_inspect"
ALLOW = "# not a unit conversion"

#: values of a bare literal that is almost always a unit conversion when it scales something
CONVERSION_LITERALS = (1e6, 1e-6, 1e3, 1e-3, 1e9, 1e-9, 1e12, 1e-12, 60.0)
#: binary byte factors written as powers or shifts: (base, exponent)
BYTE_POWERS = {(2, 10), (2, 20), (2, 30), (2, 40), (1024, 2), (1024, 3), (1024, 4)}
BYTE_LITERALS = (1024**2, 1024**3, 1024**4)

#: modules (paths relative to render_inspect/) that other changes are still cleaning: the
#: test does not read them yet.  Shrink this list to empty as they are cleaned.
NOT_YET_CLEANED: tuple[str, ...] = ()

#: the one module allowed to write the factors
UNITS_MODULE = "core/units.py"


def _modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel == UNITS_MODULE or rel.startswith(NOT_YET_CLEANED):
            continue
        yield rel, path


def _is_conversion_literal(node) -> bool:
    if not isinstance(node, ast.Constant) or isinstance(node.value, bool):
        return False
    if not isinstance(node.value, (int, float)):
        return False
    v = float(node.value)
    return any(v == c for c in CONVERSION_LITERALS) or node.value in BYTE_LITERALS


def _is_byte_power(node) -> bool:
    if not (isinstance(node, ast.BinOp) and isinstance(node.left, ast.Constant)
            and isinstance(node.right, ast.Constant)):
        return False
    pair = (node.left.value, node.right.value)
    if isinstance(node.op, ast.Pow):
        return pair in BYTE_POWERS
    if isinstance(node.op, ast.LShift):
        return node.left.value == 1 and node.right.value in (10, 20, 30, 40)
    return False


def _allowed(lines, node) -> bool:
    end = getattr(node, "end_lineno", node.lineno) or node.lineno
    return any(ALLOW in lines[i - 1] for i in range(node.lineno, end + 1))


def _violations(rel, source):
    tree = ast.parse(source)
    lines = source.splitlines()
    names = set(units.__all__)
    found = []

    def report(node, what):
        if not _allowed(lines, node):
            found.append(f"render_inspect/{rel}:{node.lineno}: {what}: "
                         f"{lines[node.lineno - 1].strip()}")

    for stmt in tree.body:  # module level
        targets, value = [], None
        if isinstance(stmt, ast.Assign):
            targets, value = stmt.targets, stmt.value
        elif isinstance(stmt, ast.AnnAssign) and stmt.value is not None:
            targets, value = [stmt.target], stmt.value
        redefined = [n.id for t in targets for n in ast.walk(t)
                     if isinstance(n, ast.Name) and n.id in names]
        if redefined:
            report(stmt, f"redefines core.units.{redefined[0]}")
        elif (value is not None and _is_conversion_literal(value)
              and not (isinstance(value.value, int) and value.value == 60)):
            # (an int 60 alone is a count or a time-out; a byte power is caught below)
            report(stmt, "module constant with a bare conversion factor (use core.units)")

    for node in ast.walk(tree):
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Mult, ast.Div)):
            for side in (node.left, node.right):
                if _is_conversion_literal(side):
                    report(node, f"bare conversion literal {ast.unparse(side)}")
        elif isinstance(node, ast.AugAssign) and isinstance(node.op, (ast.Mult, ast.Div)):
            if _is_conversion_literal(node.value):
                report(node, f"bare conversion literal {ast.unparse(node.value)}")
        if _is_byte_power(node):
            report(node, f"bare byte factor {ast.unparse(node)}")
    return found


def test_units_module_names_read_from_unit_to_unit():
    assert units.MM_TO_NM * units.NM_TO_MM == 1.0
    assert units.MM_TO_UM * units.UM_TO_MM == 1.0
    assert units.UM_TO_NM * units.NM_TO_UM == 1.0
    assert units.M_TO_MM * units.MM_TO_M == 1.0
    assert units.MIN_TO_S * units.PER_MIN_TO_PER_S == 1.0
    assert units.RPM_TO_RAD_PER_S == pytest.approx(2 * 3.141592653589793 * units.RPM_TO_HZ)
    assert units.S_TO_MS == 1000.0 and units.S_TO_US == 1_000_000.0
    assert units.GIB_TO_BYTES * units.BYTES_TO_GIB == 1.0
    assert units.STANDARD_GRAVITY_MM_S2 == pytest.approx(9.80665 * units.M_TO_MM)
    for name in units.__all__:
        assert isinstance(getattr(units, name), (int, float)), name


def test_the_scanner_finds_what_it_should():
    bad = ("MM_TO_NM = 1e6\n_NM = 1e-6\nGIB = 2**30\n"
           "def f(z, rpm, b):\n    z *= 1e3\n    return z * 1e6, rpm / 60, 2 * 3.14 / 60.0, "
           "b / 1024**3, b >> 0 / (1 << 20)\n")
    msgs = _violations("x.py", bad)
    assert len(msgs) == 9, msgs
    ok = ("N = 60\nTOL = 1e-3  # not a unit conversion\n"
          "def f(z):\n    return z * 2.0, z / 7, z + 1e6, (z < 1e-3), z * 1e-3  # not a unit conversion\n")
    assert _violations("y.py", ok) == []


def test_no_bare_unit_conversions_in_the_package():
    found = []
    for rel, path in _modules():
        found += _violations(rel, path.read_text(encoding="utf-8"))
    assert not found, ("unit conversions belong in render_inspect/core/units.py (or mark a "
                       f"non-conversion with '{ALLOW}'):\n" + "\n".join(found))
