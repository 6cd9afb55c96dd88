"""How many of the package's public functions are typed on every argument and the return.

    python tools/typed_count.py            # the figure, package by package
    python tools/typed_count.py --list     # and every public function that is not typed
    python tools/typed_count.py --list io  # those of one subpackage

The rule (read from the source, nothing imported):

- a *function* is a ``def`` or ``async def`` at the top level of a module of
  ``render_inspect/`` (also under a module-level ``if`` / ``try``), or in the body of a
  class defined there (a class in a class included); functions defined inside functions
  are not counted;
- it is *public* when its name does not start with ``_`` and, for a method, neither does
  its class's name.  Private modules (``io/_nc_write.py``) count like public ones: most
  public names live in them and are re-exported by their subpackage's ``__init__``, and
  the others are what one module of the package calls in another;
- it is *typed* when every parameter (``*args`` and ``**kwargs`` included, a method's
  ``self`` / ``cls`` excepted) and the return carry an annotation: what mypy's
  ``disallow_untyped_defs`` and ``disallow_incomplete_defs`` ask for.

``tests/test_typing.py`` keeps the typed count from falling below the figure it states
(and mypy's strict modules, ``[[tool.mypy.overrides]]`` in pyproject.toml, need every
function typed, public or not).
"""

from __future__ import annotations

import argparse
import ast
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "render_inspect"


@dataclass(frozen=True)
class Function:
    """One public function: where it is and whether it is typed."""

    path: str       # relative to the repository, ``render_inspect/io/_png.py``
    line: int
    name: str       # ``read_png`` or ``Class.method``
    typed: bool

    @property
    def subpackage(self) -> str:
        """``io``, ``core``; ``render_inspect`` for a module at the package's top level."""
        parts = Path(self.path).parts
        return parts[1] if len(parts) > 2 else parts[0]


def _is_static(node: ast.FunctionDef | ast.AsyncFunctionDef) -> bool:
    return any(isinstance(d, ast.Name) and d.id == "staticmethod" for d in node.decorator_list)


def is_typed(node: ast.FunctionDef | ast.AsyncFunctionDef, method: bool) -> bool:
    """Every parameter (a method's first one excepted, unless a staticmethod) and the
    return annotated."""
    a = node.args
    params = [*a.posonlyargs, *a.args]
    if method and not _is_static(node) and params:
        params = params[1:]
    params += a.kwonlyargs
    params += [p for p in (a.vararg, a.kwarg) if p is not None]
    return node.returns is not None and all(p.annotation is not None for p in params)


def _functions(body: list[ast.stmt], owner: str | None) -> Iterator[tuple[ast.FunctionDef | ast.AsyncFunctionDef, str | None]]:
    """The functions of a module's or class's body, with the class they are methods of."""
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node, owner
        elif isinstance(node, ast.ClassDef):
            name = node.name if owner is None else f"{owner}.{node.name}"
            yield from _functions(node.body, name)
        elif isinstance(node, ast.If):
            yield from _functions(node.body, owner)
            yield from _functions(node.orelse, owner)
        elif isinstance(node, ast.Try):
            for block in (node.body, node.orelse, node.finalbody, *(h.body for h in node.handlers)):
                yield from _functions(block, owner)


def public_functions(package: Path = PACKAGE) -> list[Function]:
    """Every public function of the package (the rule of this module's docstring)."""
    out = []
    for path in sorted(package.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        rel = path.relative_to(package.parent).as_posix()
        for node, owner in _functions(tree.body, None):
            names = [node.name, *(owner.split(".") if owner else [])]
            if any(n.startswith("_") for n in names):
                continue
            qual = node.name if owner is None else f"{owner}.{node.name}"
            out.append(Function(rel, node.lineno, qual, is_typed(node, owner is not None)))
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--list", nargs="?", const="", metavar="SUBPACKAGE",
                   help="list the public functions that are not typed (of one subpackage)")
    args = p.parse_args(argv)
    funcs = public_functions()
    by: dict[str, list[Function]] = {}
    for f in funcs:
        by.setdefault(f.subpackage, []).append(f)
    print(f"{'subpackage':<16} {'typed':>6} {'public':>7}")
    for sub, fs in sorted(by.items(), key=lambda kv: -len(kv[1])):
        print(f"{sub:<16} {sum(f.typed for f in fs):>6} {len(fs):>7}")
    typed = sum(f.typed for f in funcs)
    print(f"{'all':<16} {typed:>6} {len(funcs):>7}  ({100 * typed / max(len(funcs), 1):.0f} % typed)")
    if args.list is not None:
        for f in funcs:
            if not f.typed and (not args.list or f.subpackage == args.list):
                print(f"{f.path}:{f.line}: {f.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
