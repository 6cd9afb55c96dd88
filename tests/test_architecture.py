"""The package's layering, checked on the source (prysm keeps a test like it): a table of
which subpackage may import which, read from the AST of every module, imports inside
functions included, so a layer cannot be crossed unnoticed."""

import ast
import functools
import subprocess
import sys
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "render_inspect"
#: one worker runs the checks, so each module is parsed once per run (see _tree)
pytestmark = pytest.mark.xdist_group("architecture")
ENGINES = {"mitsuba", "drjit", "bpy"}

#: subpackage -> the subpackages it may import (besides itself and the package root's
#: ``__version__``).  Data flows one way: core <- io <- design ... <- pipeline <- cli.
ALLOWED = {
    "core": set(),
    "io": {"core"},
    "design": {"core", "io"},
    "toolpath": {"core"},
    "machining": {"core", "toolpath"},
    "mesh": {"core", "io"},
    "render": {"core", "io", "mesh"},
    "instruments": {"core", "io", "mesh", "render", "metrology"},
    "metrology": {"core"},
    "processes": {"core", "design", "toolpath", "machining"},
    "scene": {"core", "design", "processes", "instruments", "render"},
    "report": {"core", "io", "toolpath"},
    "batch": {"core", "io", "machining"},
    "fit": {"core", "io", "metrology"},
    "pipeline": {"core", "io", "design", "toolpath", "machining", "mesh", "render",
                 "instruments", "metrology", "processes", "scene", "report", "batch", "fit"},
    "errors": {"core"},
    "cli": {"core", "scene", "pipeline", "_early_signals"},
    # (the program's one-line Ctrl-C from its first statement; its process settings)
    "__init__": {"_early_signals", "_process_settings"},
    "_early_signals": set(),
    "_process_settings": set(),
    "__main__": {"cli"},
}
#: subpackages that may import the rendering engines (inside functions only)
ENGINE_USERS = {"render"}
#: the one subpackage that draws figures
DRAWING = {"matplotlib", "mpl_toolkits"}
#: what the pipeline may not ask of a scene: its process-specific sections (the process's
#: hooks read them), and of a process its kind or keys (its traits answer instead)
PROCESS_SECTIONS = {"process", "rcse", "machine", "material", "artifacts"}
PROCESS_KEYS = {"kind", "feed_per_rev", "workpiece_radius", "compensation", "spindle_rpm"}
#: pipeline modules that are no stage (the kernels' warm-up of ``make setup``)
NOT_STAGES = {"_warmup.py"}
#: the most lines a module of the package or of the Blender add-on may have
MAX_LINES = 600
#: modules allowed over MAX_LINES, each with the reason
OVERSIZED: dict[str, str] = {}
#: import cycles allowed, each a set of modules with the reason
CYCLES: dict[frozenset, str] = {}
ADDON = PKG.parent / "blender_addon"


def _unit(path: Path) -> str:
    rel = path.relative_to(PKG)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


@functools.lru_cache(maxsize=None)
def _tree(path: Path) -> ast.Module:
    """The module's syntax tree, parsed once per run: the checks below each walk every
    module, and parsing them is most of their time."""
    return ast.parse(path.read_text())


@functools.lru_cache(maxsize=None)
def _project_imports(path: Path) -> tuple:
    """(target unit, line, inside a function, top-level name) for every import."""
    return tuple(_scan_imports(path))


def _scan_imports(path: Path):
    """(target unit, line, inside a function) for every import of a project module."""
    rel = path.relative_to(PKG)
    pkg_parts = ["render_inspect", *rel.parts[:-1]]
    tree = _tree(path)
    funcs = [n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))]
    inner = {id(n) for f in funcs for n in ast.walk(f) if n is not f}
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg_parts[:len(pkg_parts) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            names = [mod] if node.module else [f"{mod}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        else:
            continue
        for name in names:
            parts = name.split(".")
            if parts[0] == "render_inspect":
                target = parts[1] if len(parts) > 1 else "__init__"
                if not ((PKG / target).is_dir() or (PKG / f"{target}.py").is_file()):
                    target = "__init__"  # a name defined in the package root (__version__)
                yield target, node.lineno, id(node) in inner, parts[0]
            else:
                yield None, node.lineno, id(node) in inner, parts[0]


def _modules():
    return sorted(p for p in PKG.rglob("*.py") if "__pycache__" not in p.parts)


def test_every_unit_is_in_the_table():
    units = {_unit(p) for p in _modules()}
    assert units <= set(ALLOWED), sorted(units - set(ALLOWED))


def test_imports_follow_the_layer_table():
    offenders = []
    for py in _modules():
        unit = _unit(py)
        allowed = ALLOWED[unit] | {unit, "__init__"}
        for target, line, _, _ in _project_imports(py):
            if target is not None and target not in allowed:
                offenders.append(f"{py.relative_to(PKG)}:{line} ({unit}) imports {target}")
    assert not offenders, "\n".join(offenders)


def test_no_function_local_project_imports_without_a_reason():
    """Imports between the project's modules sit at the top of each file; the few inside a
    function carry a comment on the line above saying why."""
    offenders = []
    for py in _modules():
        lines = py.read_text().splitlines()
        for target, line, inside, _ in _project_imports(py):
            if target is not None and inside:
                above = lines[line - 2].strip() if line >= 2 else ""
                if not above.startswith("#"):
                    offenders.append(f"{py.relative_to(PKG)}:{line}")
    assert not offenders, offenders


def test_engines_only_in_render_adapters_and_only_inside_functions():
    offenders = []
    for py in _modules():
        unit = _unit(py)
        for target, line, inside, top in _project_imports(py):
            if top in ENGINES and (unit not in ENGINE_USERS or not inside):
                offenders.append(f"{py.relative_to(PKG)}:{line} imports {top}")
    assert not offenders, offenders


@pytest.mark.slow
def test_help_imports_no_heavy_module():
    code = ("import sys\nfrom render_inspect.cli import build_parser\nbuild_parser()\n"
            "heavy = {'numba', 'scipy', 'mitsuba', 'drjit', 'bpy', 'matplotlib', 'OpenEXR', "
            "'pydantic', 'trimesh'}\nprint(sorted(heavy & set(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def _private_target(path: Path, node) -> str | None:
    """The ``render_inspect.<pkg>._module`` an import reaches, if any."""
    if isinstance(node, ast.ImportFrom):
        if node.level:
            rel = path.relative_to(PKG)
            base = ["render_inspect", *rel.parts[:-1]][:len(rel.parts) - node.level + 1]
            mods = [".".join(base + ([node.module] if node.module else []))]
            if not node.module:
                mods = [f"{mods[0]}.{a.name}" for a in node.names]
        else:
            mods = [node.module or ""]
    elif isinstance(node, ast.Import):
        mods = [a.name for a in node.names]
    else:
        return None
    for mod in mods:
        parts = mod.split(".")
        if parts[0] == "render_inspect" and len(parts) > 2 and parts[2].startswith("_") \
                and parts[1] != _unit(path):
            return mod
    return None


def test_no_module_reaches_into_another_subpackages_private_modules():
    """Subpackages meet through what their ``__init__`` exports."""
    offenders = []
    for py in _modules():
        for node in ast.walk(_tree(py)):
            target = _private_target(py, node)
            if target:
                offenders.append(f"{py.relative_to(PKG)}:{node.lineno} imports {target}")
    assert not offenders, "\n".join(offenders)


def test_the_pipeline_asks_a_process_nothing_but_its_hooks():
    """No ``hasattr``, no ``kind`` / ``process`` / ``feed_per_rev``... attributes, no
    ``isinstance`` of a machine program in pipeline/: what differs between processes is
    in their hooks and traits."""
    offenders = []
    for py in sorted((PKG / "pipeline").glob("*.py")):
        if py.name in NOT_STAGES:
            continue
        for node in ast.walk(_tree(py)):
            where = f"{py.name}:{getattr(node, 'lineno', 0)}"
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name):
                if node.func.id == "hasattr":
                    offenders.append(f"{where} hasattr")
                if node.func.id == "isinstance" and any(
                        isinstance(n, ast.Name) and n.id in ("ToolPath", "LinearProgram")
                        for n in ast.walk(node.args[1])):
                    offenders.append(f"{where} isinstance of a program")
            if isinstance(node, ast.Attribute):
                owner = node.value.attr if isinstance(node.value, ast.Attribute) else \
                    getattr(node.value, "id", "")
                if node.attr in PROCESS_SECTIONS or (node.attr in PROCESS_KEYS and (
                        owner in PROCESS_SECTIONS or (node.attr != "kind" and owner != "traits"))):
                    offenders.append(f"{where} .{node.attr}")
            if isinstance(node, ast.ImportFrom) and any(a.name in ("ToolPath", "LinearProgram")
                                                         for a in node.names):
                offenders.append(f"{where} imports a program class")
    assert not offenders, "\n".join(offenders)


def test_only_report_draws():
    """Figures are drawn in report/ only (the stages hand it data or figure specs)."""
    offenders = []
    for py in _modules():
        if _unit(py) == "report":
            continue
        for target, line, _, top in _project_imports(py):
            if top in DRAWING:
                offenders.append(f"{py.relative_to(PKG)}:{line} imports {top}")
        for node in ast.walk(_tree(py)):
            if isinstance(node, ast.ImportFrom) and node.module == "PIL" and any(
                    a.name in ("ImageDraw", "ImageFont") for a in node.names):
                offenders.append(f"{py.relative_to(PKG)}:{node.lineno} draws with PIL")
    assert not offenders, offenders


def test_metrics_json_is_written_in_one_place():
    """Every command's metrics.json goes through pipeline/_metrics.py (write_metrics)."""
    offenders = []
    for py in _modules():
        if py == PKG / "pipeline" / "_metrics.py":
            continue
        for node in ast.walk(_tree(py)):
            if isinstance(node, ast.Call) and getattr(node.func, "id", getattr(node.func, "attr", "")) \
                    in ("write_json", "atomic_write_text"):
                for sub in ast.walk(node):
                    if isinstance(sub, ast.Constant) and sub.value == "metrics.json":
                        offenders.append(f"{py.relative_to(PKG)}:{node.lineno}")
    assert not offenders, offenders


def _sized_modules():
    return _modules() + sorted(p for p in ADDON.rglob("*.py") if "__pycache__" not in p.parts)


def test_modules_stay_small():
    """Every module of the package and the add-on is at most MAX_LINES long, the few
    listed in OVERSIZED aside (which must still need it)."""
    big, stale = [], []
    for py in _sized_modules():
        name = py.relative_to(PKG.parent).as_posix()
        n = len(py.read_text().splitlines())
        if n > MAX_LINES and name not in OVERSIZED:
            big.append(f"{name}: {n} lines")
        if n <= MAX_LINES and name in OVERSIZED:
            stale.append(name)
    assert not big, big
    assert not stale, f"no longer over {MAX_LINES} lines, drop from OVERSIZED: {stale}"


def _module_name(path: Path) -> str:
    rel = path.relative_to(PKG.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _import_graph() -> dict:
    """Module -> the project modules it imports (at the top or inside functions), read from
    the AST: ``from X import y`` counts as an import of ``X.y`` where that is a module, else
    of ``X``."""
    files = {_module_name(p): p for p in _sized_modules()}
    graph = {}
    for name, path in files.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets = set()
        for node in ast.walk(_tree(path)):
            if isinstance(node, ast.Import):
                found = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join(up + ([node.module] if node.module else []))
                found = [f"{base}.{a.name}" if f"{base}.{a.name}" in files else base
                         for a in node.names]
            else:
                continue
            targets.update(f for f in found if f in files)
        graph[name] = targets - {name}
    return graph


def _cycles(graph: dict) -> list[frozenset]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(frozenset(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_cycles():
    """No two modules of the package or the add-on import each other, directly or through
    others (imports inside functions count: they only defer the cycle), the few listed in
    CYCLES aside (which must still be cycles)."""
    found = _cycles(_import_graph())
    unknown = [sorted(c) for c in found if c not in CYCLES]
    assert not unknown, unknown
    stale = [sorted(c) for c in CYCLES if c not in found]
    assert not stale, f"no longer a cycle, drop from CYCLES: {stale}"


def test_the_import_graph_sees_a_cycle():
    """The cycle finder itself, on a graph with one cycle of three and a tail."""
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a", "d"}, "d": set()}
    assert _cycles(graph) == [frozenset({"a", "b", "c"})]
    assert _cycles({"a": {"b"}, "b": set()}) == []
