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


@pytest.mark.slow
def test_mypy_finds_no_type_errors(tmp_path):
    _require_mypy()
    r = subprocess.run([sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path / "cache")],
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
def test_the_type_check_would_see_an_error(tmp_path):
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
                   + _typed_scene_example())
    r = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(REPO / "pyproject.toml"),
                        "--cache-dir", str(tmp_path / "cache"), str(bad)],
                       cwd=REPO, capture_output=True, text=True)
    assert r.returncode == 1 and "Incompatible types in assignment" in r.stdout, r.stdout
    # a scene key misspelt where a function takes the typed Scene (the registered
    # [machine] section included)
    assert '"MachineConfig" has no attribute "servo_rate_hzz"' in r.stdout, r.stdout
    # a key of a process's typed inputs misspelt
    assert '"ToolSection" has no attribute "nose_radiuss"' in r.stdout, r.stdout
    assert "Found 3 errors" in r.stdout, r.stdout
