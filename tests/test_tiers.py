"""The quick tier's rules (tests/conftest.py) catch what they are for: a test without a
heavy mark fails when it starts a process or takes more CPU than the quick tier allows
(in its call or in its set-up), and says which mark to add; the same work under
``@pytest.mark.slow`` passes, and so do waiting (wall time, no CPU) and numba's
compilations.  Checked on a small suite beside this one, with this suite's conftest."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: the limit the small suite runs under (RENDER_INSPECT_QUICK_CPU_S), and the CPU its heavy
#: tests burn: well apart, so that neither side is a close call
LIMIT_S, HEAVY_S = 0.5, 1.2

SUITE = '''
import os
import subprocess
import sys
import time

import pytest

import render_inspect.pipeline._simulate  # noqa: F401  (the conftest's first import, here)


def _burn(seconds):
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_light():
    assert sum(range(1000)) == 499500


def test_waits_without_working():
    time.sleep(1.5)


def test_heavy_unmarked():
    _burn(HEAVY_S)


@pytest.mark.slow
def test_heavy_marked():
    _burn(HEAVY_S)


@pytest.fixture(scope="module")
def built():
    _burn(HEAVY_S)
    return 1


def test_heavy_set_up_unmarked(built):
    assert built == 1


def test_numba_compilations_are_not_counted():
    import numpy as np
    from numba import njit

    start = time.process_time()
    dtypes = (np.float64, np.float32, np.int64, np.int32, np.int16, np.uint8)
    # fresh functions compiled until their compilations are well over the limit, however
    # fast the machine compiles (each is a new function, so each call compiles)
    for n in range(400):
        if time.process_time() - start > 3 * LIMIT_S:
            break

        @njit(cache=False)
        def total(a):
            s = 0.0
            for v in a:
                s += v * v
            return s

        assert total(np.arange(4, dtype=dtypes[n % len(dtypes)])) == 14
    with open(os.environ["SPENT"], "w") as f:
        f.write(str(time.process_time() - start))


def test_starts_a_process_unmarked():
    subprocess.run([sys.executable, "-c", "pass"], check=True)


@pytest.mark.slow
def test_starts_a_process_marked():
    subprocess.run([sys.executable, "-c", "pass"], check=True)
'''.replace("HEAVY_S", repr(HEAVY_S)).replace("LIMIT_S", repr(LIMIT_S))


def _run(suite: Path, tmp_path: Path, limit: str, *args: str) -> dict:
    """Run the small suite; test name -> its failure message ("" when it passed)."""
    junit = tmp_path / f"junit-{limit}.xml"
    env = {**os.environ, "PYTHONPATH": str(REPO), "RENDER_INSPECT_QUICK_CPU_S": limit,
           "SPENT": str(tmp_path / "spent.txt")}
    res = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "-p", "no:xdist", "-o", "markers=slow", "--rootdir", str(suite),
                          f"--junitxml={junit}", *args, str(suite)],
                         cwd=suite, env=env, capture_output=True, text=True, timeout=300)
    assert junit.is_file(), res.stdout[-3000:] + res.stderr[-3000:]
    out = {}
    for case in ET.parse(junit).iter("testcase"):
        bad = case.find("failure")
        if bad is None:
            bad = case.find("error")
        out[case.get("name")] = "" if bad is None else (bad.get("message") or "") + (bad.text or "")
    return out


@pytest.mark.slow
def test_the_quick_tier_fails_heavy_unmarked_tests_and_names_the_mark(tmp_path):
    suite = tmp_path / "suite"
    suite.mkdir()
    shutil.copy(REPO / "tests" / "conftest.py", suite / "conftest.py")
    (suite / "test_small.py").write_text(SUITE)
    got = _run(suite, tmp_path, str(LIMIT_S))
    assert set(got) == {"test_light", "test_waits_without_working", "test_heavy_unmarked",
                        "test_heavy_marked", "test_heavy_set_up_unmarked",
                        "test_numba_compilations_are_not_counted",
                        "test_starts_a_process_unmarked", "test_starts_a_process_marked"}, got
    passed = {k for k, v in got.items() if not v}
    assert passed == {"test_light", "test_waits_without_working", "test_heavy_marked",
                      "test_numba_compilations_are_not_counted",
                      "test_starts_a_process_marked"}, got
    # the CPU rule: the call, or the set-up (a module fixture), with the figures and the mark
    heavy = got["test_heavy_unmarked"]
    assert "test_heavy_unmarked took" in heavy and "s of CPU in its call" in heavy, heavy
    assert f"(more than {LIMIT_S:g} s)" in heavy and "@pytest.mark.slow" in heavy, heavy
    assert "make test-quick" in heavy
    spent = float(heavy.split(" took ")[1].split(" s of CPU")[0])
    assert HEAVY_S <= spent < 10 * HEAVY_S, heavy
    setup = got["test_heavy_set_up_unmarked"]
    assert "s of CPU in its setup" in setup and "@pytest.mark.slow" in setup, setup
    # the numba test passed although its compilations took more than the limit
    assert float((tmp_path / "spent.txt").read_text()) > LIMIT_S
    # the process rule
    proc = got["test_starts_a_process_unmarked"]
    assert "starts a process" in proc and "@pytest.mark.slow" in proc, proc
    # RENDER_INSPECT_QUICK_CPU_S=0 turns the CPU rule off, not the process rule
    off = _run(suite, tmp_path, "0", "-k", "heavy_unmarked or starts_a_process_unmarked")
    assert off["test_heavy_unmarked"] == "" and "starts a process" in \
        off["test_starts_a_process_unmarked"], off
