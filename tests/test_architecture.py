"""Layering rules, checked on the source (as prysm does): only render/ and the Blender
add-on import the engines; the numerical core stays plain numpy/scipy/numba."""

import ast
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "render_inspect"
ENGINES = {"mitsuba", "drjit", "bpy"}


def _imports(path: Path):
    tree = ast.parse(path.read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                yield a.name.split(".")[0], node
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            yield node.module.split(".")[0], node


def test_engines_only_in_render_adapters():
    offenders = []
    for py in PKG.rglob("*.py"):
        rel = py.relative_to(PKG)
        if rel.parts[0] == "render":
            continue
        for mod, node in _imports(py):
            if mod in ENGINES:
                offenders.append(f"{rel}:{node.lineno} imports {mod}")
    assert not offenders, offenders


def test_engines_imported_lazily_in_render():
    # module-level engine imports would make `import render_inspect.render` start Mitsuba
    offenders = []
    for py in (PKG / "render").rglob("*.py"):
        tree = ast.parse(py.read_text())
        for node in tree.body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                if any(n.split(".")[0] in ENGINES for n in names):
                    offenders.append(f"{py.name}:{node.lineno}")
    assert not offenders, offenders
