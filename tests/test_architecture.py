"""The package's layering, checked on the source (prysm keeps a test like it): a table of
which subpackage may import which, read from the AST of every module, imports inside
functions included, so a layer cannot be crossed unnoticed."""

import ast
import subprocess
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "render_inspect"
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
    "instruments": {"core", "io", "mesh", "render"},
    "metrology": {"core"},
    "processes": {"core", "design", "toolpath", "machining"},
    "scene": {"core", "design", "processes", "instruments", "render"},
    "report": {"core", "io", "toolpath"},
    "batch": {"core", "io"},
    "fit": {"core", "io", "metrology"},
    "pipeline": {"core", "io", "design", "toolpath", "machining", "mesh", "render",
                 "instruments", "metrology", "processes", "scene", "report", "batch", "fit"},
    "errors": {"core"},
    "cli": {"core", "scene", "pipeline"},
    "__init__": set(),
    "__main__": {"cli"},
}
#: subpackages that may import the rendering engines (inside functions only)
ENGINE_USERS = {"render"}


def _unit(path: Path) -> str:
    rel = path.relative_to(PKG)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _project_imports(path: Path):
    """(target unit, line, inside a function) for every import of a project module."""
    rel = path.relative_to(PKG)
    pkg_parts = ["render_inspect", *rel.parts[:-1]]
    tree = ast.parse(path.read_text())
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


def test_help_imports_no_heavy_module():
    code = ("import sys\nfrom render_inspect.cli import build_parser\nbuild_parser()\n"
            "heavy = {'numba', 'scipy', 'mitsuba', 'drjit', 'bpy', 'matplotlib', 'OpenEXR', "
            "'pydantic', 'trimesh'}\nprint(sorted(heavy & set(sys.modules)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


_SADDLE = '''
from typing import Literal

from pydantic import Field

from ..core.section import Section
from ._base import Surface
from ._registry import register_design


class Saddle(Surface):
    kind = "saddle"

    def __init__(self, radius):
        self.radius = radius

    def height(self, x, y):
        return (x * x - y * y) / (2 * self.radius)


class SaddleConfig(Section):
    type: Literal["saddle"]
    radius: float = Field(..., gt=0)


register_design(SaddleConfig, Saddle)
'''

_FACING = '''
import time
from typing import Literal

from ._registry import Cut, Plan, register_process
from ._turning import (TurningProcessConfig, cut_turning, plan_spiral, toolpath_facts,
                       turning_memory)


class FacingProcessConfig(TurningProcessConfig):
    kind: Literal["facing"]


def plan(scene, surface, *, region=None):
    path = plan_spiral(scene, surface, region=region)
    return Plan(path, {"toolpath": toolpath_facts(path, scene)}, {})


def cut(scene, surface, plan):
    machined, design, timing, _ = cut_turning(scene, surface, plan.program)
    return Cut(machined, design, {"facing": {"ok": True}}, timing, {"process": "facing"})


register_process(FacingProcessConfig, plan=plan, cut=cut, estimate_memory=turning_memory)
'''

_CONFOCAL = '''
from pydantic import Field

from ..core.section import Section
from ._registry import register_instrument


class ConfocalConfig(Section):
    numerical_aperture: float = Field(0.8, gt=0, lt=1)


register_instrument("confocal", ConfocalConfig)
'''


def test_a_new_design_process_and_instrument_are_one_file_each(tmp_path):
    """Copy the package, drop one file into design/, processes/ and instruments/, and use
    the new design type, process kind and instrument section from a scene."""
    import shutil

    pkg = tmp_path / "render_inspect"
    shutil.copytree(PKG, pkg, ignore=shutil.ignore_patterns("__pycache__"))
    (pkg / "design" / "_saddle.py").write_text(_SADDLE)
    (pkg / "processes" / "_facing.py").write_text(_FACING)
    (pkg / "instruments" / "_confocal.py").write_text(_CONFOCAL)
    code = (
        "import render_inspect, json\n"
        f"assert render_inspect.__file__.startswith({str(tmp_path)!r})\n"
        "from render_inspect.scene import scene_from_dict\n"
        "from render_inspect.pipeline import simulate\n"
        "s = scene_from_dict({'design': {'type': 'saddle', 'radius': 200.0},\n"
        "    'process': {'kind': 'facing', 'workpiece_radius': 0.5},\n"
        "    'simulation': {'region': [0.1, 0.1, 0.14, 0.14], 'pixel': 0.002},\n"
        "    'render': {'confocal': {'numerical_aperture': 0.9}}})\n"
        "m = simulate(s).metrics\n"
        "print(json.dumps({'Sq': m['residual']['Sq_nm'], 'facing': m['facing'],\n"
        "                  'na': s.render.confocal.numerical_aperture}))\n")
    env = {k: v for k, v in __import__("os").environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(tmp_path)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, env=env)
    assert out.returncode == 0, out.stderr
    res = __import__("json").loads(out.stdout.strip().splitlines()[-1])
    assert res["facing"] == {"ok": True} and res["na"] == 0.9 and res["Sq"] > 0
