"""``make test`` runs the suite on parallel workers with ``--dist loadgroup``: the tests of
one ``xdist_group`` run on one worker, so that what they share (a module fixture: the
Blender extension's build and each Blender's drive of it) is made once per run, not once
per worker.  Checked on a small suite beside this one, with this suite's conftest."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

GROUPED = '''
import os
import pytest

pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("shared")]


@pytest.fixture(scope="module", params=["a", "b", "c"])
def made(request):
    with open(os.environ["SETUPS"], "a") as f:
        f.write(f"setup {request.param} {os.environ['PYTEST_XDIST_WORKER']}\\n")
    return request.param


@pytest.mark.parametrize("n", range(3))
def test_uses_it(made, n, request):
    with open(os.environ["SETUPS"], "a") as f:
        f.write(f"test {request.node.nodeid} {os.environ['PYTEST_XDIST_WORKER']}\\n")
'''

#: no group named: the tests that use the module fixture get one of their own
SHARED = '''
import os
import time
import pytest


@pytest.fixture(scope="module")
def built():
    with open(os.environ["SETUPS"], "a") as f:
        f.write(f"built x {os.environ['PYTEST_XDIST_WORKER']}\\n")
    return 1


@pytest.mark.slow
@pytest.mark.parametrize("n", range(4))
def test_uses_the_build(built, n, request):
    time.sleep(0.2)
    with open(os.environ["SETUPS"], "a") as f:
        f.write(f"used {request.node.nodeid} {os.environ['PYTEST_XDIST_WORKER']}\\n")


@pytest.mark.slow
@pytest.mark.parametrize("n", range(6))
def test_other(n):
    time.sleep(0.2)
'''


@pytest.mark.slow
def test_a_group_runs_on_one_worker_and_its_module_fixture_is_made_once(tmp_path):
    import xdist  # noqa: F401  (the test extra's pytest-xdist: make test runs on it)
    suite = tmp_path / "suite"
    suite.mkdir()
    shutil.copy(REPO / "tests" / "conftest.py", suite / "conftest.py")
    (suite / "test_grouped.py").write_text(GROUPED)
    (suite / "test_shared.py").write_text(SHARED)
    setups = tmp_path / "setups.txt"
    env = {**os.environ, "SETUPS": str(setups), "PYTHONPATH": str(REPO)}
    res = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "--dist", "loadgroup",
                          "-p", "no:cacheprovider", "-o", "markers=slow", "--rootdir",
                          str(suite), str(suite)],
                         cwd=suite, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert "19 passed" in res.stdout, res.stdout[-2000:]
    lines = [line.split() for line in setups.read_text().splitlines()]
    # the named group: each parameter of its module fixture made once, all on one worker
    named = [line for line in lines if line[0] in ("setup", "test")]
    assert sorted(p for kind, p, _ in named if kind == "setup") == ["a", "b", "c"], lines
    assert len({w for _, _, w in named}) == 1, lines
    tests = [n for kind, n, _ in named if kind == "test"]
    assert len(tests) == 9 and all(n.endswith("@shared") for n in tests), tests
    # the module fixture's own group: made once, its four users on that worker
    shared = [line for line in lines if line[0] in ("built", "used")]
    assert [kind for kind, _, _ in shared].count("built") == 1, lines
    assert len({w for _, _, w in shared}) == 1, lines
    used = [n for kind, n, _ in shared if kind == "used"]
    assert len(used) == 4 and all(n.endswith("@test_shared.built") for n in used), used


def test_heavy_single_tests_are_handed_out_first():
    """On the workers of ``--dist loadgroup`` the single tests that carry a heavy mark are
    collected before the light ones (each keeping its order), the tests of a group keep
    theirs; a run in one process keeps the files' order."""
    from types import SimpleNamespace

    from conftest import _heavy_work_first

    class Item:
        def __init__(self, name, *marks):
            self.name, self.marks = name, marks

        def get_closest_marker(self, mark):
            return SimpleNamespace(name=mark) if mark in self.marks else None

    items = [Item("light"), Item("slow", "slow"), Item("grouped slow", "slow", "xdist_group"),
             Item("grouped light", "xdist_group"), Item("blender", "blender"),
             Item("light too")]
    got = list(items)
    _heavy_work_first(SimpleNamespace(option=SimpleNamespace(loadgroup=True)), got)
    assert [i.name for i in got] == ["slow", "blender", "light", "grouped slow",
                                     "grouped light", "light too"]
    for option in (SimpleNamespace(loadgroup=False), SimpleNamespace()):
        got = list(items)
        _heavy_work_first(SimpleNamespace(option=option), got)
        assert got == items
