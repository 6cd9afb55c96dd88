"""The type check: mypy, with the configuration in pyproject.toml ([tool.mypy]: the
packages it covers and how strictly; docs/contributing.md), finds nothing."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _require_mypy() -> None:
    """mypy is in requirements.lock: an environment without it is not the project's (a
    failure that says so, not a skip)."""
    assert importlib.util.find_spec("mypy") is not None, (
        "mypy is not installed: run make setup (it installs requirements.lock)")


@pytest.fixture(scope="module")
def mypy_cache() -> Path:
    """mypy's own incremental cache, where ``mypy`` run in the checkout keeps it
    (``.mypy_cache``, not tracked): a run analyses again only the modules whose source
    changed and those whose view of a changed module's interface changed (mypy compares
    the files' hashes, its version and the configuration), and reports what a run without
    the cache reports.  The first run in a checkout analyses everything (about 30 s of
    CPU); the two tests here, and each later run, read that analysis (the second test
    checks only its own file)."""
    return REPO / ".mypy_cache"


@pytest.mark.slow
@pytest.mark.xdist_group("typing_mypy")
def test_mypy_finds_no_type_errors(mypy_cache):
    _require_mypy()
    r = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(mypy_cache)],
                       cwd=REPO, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    m = re.search(r"Success: no issues found in (\d+) source files", r.stdout)
    assert m and int(m.group(1)) > 0, r.stdout


def _typed_scene_example() -> str:
    """The example of docs/contributing.md's "The typed scene"."""
    text = (REPO / "docs" / "contributing.md").read_text()
    m = re.search(r"#### The typed scene\n.*?```python\n(.*?)```", text, re.S)
    assert m, "docs/contributing.md: the typed scene's example is missing"
    return m.group(1)


@pytest.mark.slow
@pytest.mark.xdist_group("typing_mypy")
def test_the_type_check_would_see_an_error(tmp_path, mypy_cache):
    """The same configuration reports a wrong type (the check above can fail), and the
    typed scene's example of docs/contributing.md passes it."""
    _require_mypy()
    bad = tmp_path / "bad.py"
    bad.write_text("from render_inspect.core.grid import grid_shape\n"
                   "from render_inspect.scene import Scene\n"
                   "n: str = grid_shape((0.0, 0.0, 1.0, 1.0), 0.1)\n"
                   "from render_inspect.processes import TurningInputs\n"
                   "def rpm(scene: Scene) -> float:\n"
                   "    return scene.machine.servo_rate_hzz + scene.tool.nose_radius\n"
                   "def nose(cfg: TurningInputs) -> float:\n"
                   "    return cfg.tool.nose_radiuss\n"
                   "from render_inspect.io._program_kernel import unwrap_c\n"
                   "steps, summed, negative, first = unwrap_c([0.0, 90.0])\n"
                   + _typed_scene_example())
    r = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(REPO / "pyproject.toml"),
                        "--cache-dir", str(mypy_cache), str(bad)],
                       cwd=REPO, capture_output=True, text=True)
    assert r.returncode == 1 and "Incompatible types in assignment" in r.stdout, r.stdout
    # a scene key misspelt where a function takes the typed Scene (the registered
    # [machine] section included)
    assert '"MachineConfig" has no attribute "servo_rate_hzz"' in r.stdout, r.stdout
    # a key of a process's typed inputs misspelt
    assert '"ToolSection" has no attribute "nose_radiuss"' in r.stdout, r.stdout
    # a numba kernel (core.lazy.njit) called with what its signature does not take
    assert 'Argument 1 to "__call__" of "LazyDispatcher" has incompatible type' in r.stdout, r.stdout
    assert "Found 4 errors" in r.stdout, r.stdout


def _counter():
    """tools/typed_count.py, imported (the count of typed public functions)."""
    spec = importlib.util.spec_from_file_location("typed_count", REPO / "tools" / "typed_count.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["typed_count"] = mod  # (its dataclass looks its module up)
    spec.loader.exec_module(mod)
    return mod


#: public functions of the package not yet typed on every argument and the return
#: (tools/typed_count.py; 782 of 1221 when the count began, none of 1252 now): a new public
#: function comes typed
MAX_UNTYPED_PUBLIC = 0


def test_public_functions_stay_typed():
    funcs = _counter().public_functions()
    untyped = [f"{f.path}:{f.line}: {f.name}" for f in funcs if not f.typed]
    assert len(funcs) > 1000, len(funcs)
    assert len(untyped) <= MAX_UNTYPED_PUBLIC, (
        f"{len(untyped)} public functions are not typed (at most {MAX_UNTYPED_PUBLIC}): type "
        f"the new ones (python tools/typed_count.py --list names them all)\n"
        + "\n".join(untyped))


def test_the_counter_sees_each_kind_of_function(tmp_path):
    """The rule of tools/typed_count.py on a module of known answers (so the test above
    can fail)."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "sub" / "_mod.py").write_text(
        "import typing\n"
        "def typed(a: int, *b: int, c: str = '', **d: float) -> None: ...\n"
        "def no_return(a: int): ...\n"
        "def one_untyped(a: int, b) -> int: ...\n"
        "def untyped_kwargs(**kw) -> None: ...\n"
        "def _private(a): ...\n"
        "if typing.TYPE_CHECKING:\n"
        "    def checked(a: int) -> int: ...\n"
        "class C:\n"
        "    def method(self, a: int) -> int: ...\n"
        "    @staticmethod\n"
        "    def static(a) -> int: ...\n"
        "    def __init__(self, a): ...\n"
        "    class Inner:\n"
        "        def deep(self) -> None: ...\n"
        "class _Hidden:\n"
        "    def public_name(self): ...\n"
        "def outer() -> None:\n"
        "    def inner(a): ...\n")
    got = {f.name: f.typed for f in _counter().public_functions(pkg)}
    assert got == {"typed": True, "no_return": False, "one_untyped": False,
                   "untyped_kwargs": False, "checked": True, "C.method": True,
                   "C.static": False, "C.Inner.deep": True, "outer": True}, got
