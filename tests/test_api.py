"""docs/api.md, the public API: every name it lists exists and is importable from where it
says, and every name of the package that the Blender add-on or an example of the docs
calls is listed there (so a name users' scripts rely on cannot drop out of the page, nor
the page name something that is gone)."""

from __future__ import annotations

import ast
import importlib
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PKG = "render_inspect"
DOC = REPO / "docs" / "api.md"

#: the page's sections (``## `render_inspect.io` ...``) and rows (``| `name` | ... |``)
_SECTION = re.compile(r"^## `render_inspect\.([\w.]+)`", re.M)
_ROW = re.compile(r"^\| `([\w.]+)` \|", re.M)


def listed() -> dict[str, list[str]]:
    """Module (``io``, ``core``) -> the names docs/api.md lists under it, in order (a
    dotted name, ``section.Section``, is a public module of it and a name there)."""
    text = DOC.read_text()
    heads = list(_SECTION.finditer(text))
    out: dict[str, list[str]] = {}
    for i, h in enumerate(heads):
        end = heads[i + 1].start() if i + 1 < len(heads) else len(text)
        out[h.group(1)] = _ROW.findall(text, h.end(), end)
    return out


def resolve(module: str, name: str) -> object:
    """``render_inspect.<module>``'s ``name`` (``a.b``: the attribute ``b`` of its public
    module ``a``), imported."""
    *sub, attr = name.split(".")
    mod = importlib.import_module(".".join([PKG, module, *sub]))
    return getattr(mod, attr)


# ------------------------------------------------------------------ who calls what
def _python_blocks(md: Path) -> Iterator[tuple[str, str | None]]:
    """(code, the file an example creates or None) of each ```python block of ``md``."""
    text = md.read_text()
    for m in re.finditer(r"(?:Create\s+`(render_inspect/[\w/]+\.py)`:\n)?```python\n(.*?)```",
                         text, re.S):
        yield m.group(2), m.group(1)


def _module_of_relative(level: int, module: str | None, path: str) -> str | None:
    """The absolute module of ``from <dots><module> import`` written in the file ``path``
    (``render_inspect/io/_xyz.py``)."""
    parts = path[:-3].split("/")[:-1]  # the package the file lives in
    if level > len(parts):
        return None
    base = parts[:len(parts) - level + 1]
    return ".".join(base + ([module] if module else []))


def _uses_in(code: str, path: str | None = None) -> set[tuple[str, str]]:
    """(module, name) pairs of the package that the Python source ``code`` uses: imported
    names (``from render_inspect.io import read_surface``, relative imports of an example
    that is a file of the package at ``path``), and attributes of the package's modules
    bound to a name (``from render_inspect import pipeline``, ``import render_inspect.io as
    rio``, the add-on's ``_lib.module("pipeline")`` and the functions that return it)."""
    tree = ast.parse(code)
    uses: set[tuple[str, str]] = set()
    bound: dict[str, str] = {}     # local name -> module of the package (dotted, no prefix)
    returns: dict[str, str] = {}   # function name -> module of the package it returns

    def module_call(node: ast.AST) -> str | None:
        # _lib.module("sub") / importlib.import_module("render_inspect.sub") / f() -> module
        if not isinstance(node, ast.Call):
            return None
        f = node.func
        arg = node.args[0] if node.args else None
        text = arg.value if isinstance(arg, ast.Constant) and isinstance(arg.value, str) else None
        if isinstance(f, ast.Attribute) and f.attr == "module" and text is not None:
            return text or None
        if isinstance(f, ast.Attribute) and f.attr == "import_module" and text:
            return text[len(PKG) + 1:] if text.startswith(PKG + ".") else None
        if isinstance(f, ast.Name):
            return returns.get(f.id)
        return None

    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            for r in ast.walk(fn):
                if isinstance(r, ast.Return) and r.value is not None:
                    sub = module_call(r.value)
                    if sub:
                        returns[fn.name] = sub
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = node.module
            if node.level:
                mod = _module_of_relative(node.level, node.module, path) if path else None
            if mod is None or not (mod == PKG or mod.startswith(PKG + ".")):
                continue
            sub = mod[len(PKG) + 1:]
            for a in node.names:
                if sub == "":  # from render_inspect import pipeline
                    bound[a.asname or a.name] = a.name
                else:
                    uses.add((sub, a.name))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(PKG + ".") and a.asname:
                    bound[a.asname] = a.name[len(PKG) + 1:]
        elif isinstance(node, ast.Assign) and len(node.targets) == 1 \
                and isinstance(node.targets[0], ast.Name):
            sub = module_call(node.value)
            if sub:
                bound[node.targets[0].id] = sub
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute):
            v = node.value
            if isinstance(v, ast.Name) and v.id in bound:
                uses.add((bound[v.id], node.attr))
            elif module_call(v):
                uses.add((module_call(v), node.attr))  # type: ignore[arg-type]
            elif isinstance(v, ast.Attribute):  # render_inspect.io.read_surface
                chain = []
                x: ast.AST = v
                while isinstance(x, ast.Attribute):
                    chain.append(x.attr)
                    x = x.value
                if isinstance(x, ast.Name) and x.id == PKG:
                    uses.add((".".join(reversed(chain)), node.attr))
    return uses


def public(module: str, name: str) -> tuple[str, str] | None:
    """Where a use of ``module``'s ``name`` is listed: (the subpackage or top-level module,
    the name as the page writes it), or None for a name that is no part of the API (a
    private module's own helper, a name with an underscore)."""
    parts = module.split(".")
    top = parts[0]
    if name.startswith("_") or top.startswith("_"):
        return None
    rest = parts[1:]
    if not rest:
        return top, name
    # a module of a subpackage: the name the subpackage exports, else (a public module's
    # own name, core.section.Section) the module's; a private module's other names are not
    # the API
    exported = getattr(importlib.import_module(f"{PKG}.{top}"), "__all__", ())
    if name in exported:
        return top, name
    return None if rest[0].startswith("_") else (top, ".".join([*rest, name]))


def addon_uses() -> set[tuple[str, str]]:
    """What the Blender add-on calls of the package."""
    uses: set[tuple[str, str]] = set()
    for f in sorted((REPO / "blender_addon").glob("*.py")):
        uses |= _uses_in(f.read_text())
    return uses


def docs_example_uses() -> set[tuple[str, str]]:
    """What the Python examples of README.md and docs/*.md call of the package."""
    uses: set[tuple[str, str]] = set()
    for md in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for code, path in _python_blocks(md):
            try:
                uses |= _uses_in(code, path)
            except SyntaxError:  # a signature summary, not a program (docs/blender.md)
                continue
    return uses


# ------------------------------------------------------------------ tests
def test_the_page_lists_modules_of_the_package():
    pages = listed()
    assert len(pages) >= 10 and sum(len(v) for v in pages.values()) >= 100, pages
    for module in pages:
        importlib.import_module(f"{PKG}.{module}")


@pytest.mark.parametrize("module", sorted(listed()))
def test_every_listed_name_is_importable(module):
    names = listed()[module]
    assert len(names) == len(set(names)), f"{module}: a name listed twice"
    mod = importlib.import_module(f"{PKG}.{module}")
    exported = set(getattr(mod, "__all__", ()))
    for name in names:
        resolve(module, name)  # AttributeError / ImportError name what is gone
        if "." not in name:  # a subpackage's own name is in its __all__ (public)
            assert name in exported, f"render_inspect.{module}.{name} is not in __all__"


def _missing(uses: set[tuple[str, str]]) -> list[str]:
    pages = {m: set(v) for m, v in listed().items()}
    missing = []
    for module, name in sorted(uses):
        where = public(module, name)
        if where is not None and where[1] not in pages.get(where[0], set()):
            missing.append(f"render_inspect.{where[0]}.{where[1]}")
    return missing


def test_what_the_blender_addon_calls_is_listed():
    uses = addon_uses()
    assert ("pipeline", "simulate_variants") in uses and ("errors", "RenderInspectError") in uses
    assert _missing(uses) == []


def test_what_the_docs_examples_call_is_listed():
    uses = docs_example_uses()
    # the page's own examples: run_sweep (batch.md), a new instrument's imports (contributing.md)
    assert ("pipeline", "run_sweep") in uses and ("io", "table_csv") in uses
    assert _missing(uses) == []


def test_the_usage_reader_sees_each_way_of_calling():
    """The reader above finds every form the add-on and the examples use (so the two tests
    before it can fail)."""
    code = '''
import importlib
from render_inspect.io import read_surface
from render_inspect import pipeline
import render_inspect.metrology as met
from . import _lib


def _pl():
    return _lib.module("pipeline")


def f():
    p = _pl()
    e = _lib.module("errors").RenderInspectError
    q = importlib.import_module("render_inspect.report")
    return p.render_variant, pipeline.run_fit, met.areal_parameters, q.draw_figure, e
'''
    assert _uses_in(code) == {("io", "read_surface"), ("pipeline", "render_variant"),
                              ("pipeline", "run_fit"), ("metrology", "areal_parameters"),
                              ("report", "draw_figure"), ("errors", "RenderInspectError")}
    rel = "from ..core.section import Section\nfrom ._registry import register_instrument\n"
    assert _uses_in(rel, "render_inspect/instruments/_x.py") == {
        ("core.section", "Section"), ("instruments._registry", "register_instrument")}
    assert public("core.section", "Section") == ("core", "section.Section")
    assert public("core.errors", "InputError") == ("core", "InputError")  # core exports it
    assert public("instruments._registry", "register_instrument") == (
        "instruments", "register_instrument")
    assert _missing({("pipeline", "no_such_name")}) == ["render_inspect.pipeline.no_such_name"]


#: the line of a section that names its exported but internal names
_INTERNAL = re.compile(r"^Internal \(exported, may change\): (.*)$", re.M)


@pytest.mark.parametrize("module", sorted(listed()))
def test_the_page_names_every_exported_name(module):
    """What a subpackage exports (its ``__all__``) is exactly what its section names: the
    table (public) and the line of internal names; nothing exported goes unmentioned and
    nothing is mentioned that is no longer exported."""
    text = DOC.read_text()
    heads = list(_SECTION.finditer(text))
    i = next(k for k, h in enumerate(heads) if h.group(1) == module)
    body = text[heads[i].end():heads[i + 1].start() if i + 1 < len(heads) else len(text)]
    internal = _INTERNAL.search(body)
    named = {n for n in _ROW.findall(body) if "." not in n}
    if internal:
        named |= set(re.findall(r"`([\w.]+)`", internal.group(1)))
    exported = set(importlib.import_module(f"{PKG}.{module}").__all__)
    assert sorted(exported - named) == [], f"render_inspect.{module}: exported, not on the page"
    assert sorted(named - exported) == [], f"render_inspect.{module}: on the page, not exported"


def test_the_pipeline_names_where_each_of_its_exports_lives():
    """``render_inspect.pipeline`` imports a stage's module when one of its names is first
    used: the table of where each name lives covers exactly what it exports, and each name
    resolves."""
    from render_inspect import pipeline

    assert set(pipeline._WHERE) == set(pipeline.__all__)
    for name in pipeline.__all__:
        assert getattr(pipeline, name) is not None
