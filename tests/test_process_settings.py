"""The ``render-inspect`` program's own process settings (render_inspect._process_settings):
made in the program, never in a program that imports the package; OpenBLAS's thread
timeout and numpy's huge-page switch as the user set them when they did; large temporary
arrays reuse freed memory (the page faults of a growing temporary, measured); numpy asks
for no huge pages (the page faults of a fresh large array, measured)."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]

#: imports the package as the program (``argv[0]`` "render-inspect") or as a host, then
#: prints the settings seen, the minor page faults of a fresh 64 MiB array filled (the
#: system's choice of pages), and those of arrays of 1 to 24 MiB, each allocated, filled
#: and freed in turn (4 KiB pages)
_PROBE = r"""
import json, os, resource, sys
if sys.argv[1] == "program-numpy-first":  # (a start-up hook loaded numpy before the package)
    import numpy
if sys.argv[1].startswith("program"):
    sys.argv[0] = "render-inspect"
import render_inspect
import ctypes
import numpy as np
_mu = getattr(np, "_core", None) or np.core
hugepage = bool(_mu.multiarray._get_madvise_hugepage())
big = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
a = np.empty(64 * 1024 * 1024 // 8)
a.fill(1.0)
del a
big = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - big
# pages counted one by one (no transparent huge pages in this process, and numpy asks
# for none)
ctypes.CDLL(None).prctl(41, 1, 0, 0, 0)  # PR_SET_THP_DISABLE
_mu.multiarray._set_madvise_hugepage(False)
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for mib in range(1, 25):
    a = np.empty(mib * 1024 * 1024 // 8)
    a.fill(1.0)
    del a
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
print(json.dumps({"timeout": os.environ.get("OPENBLAS_THREAD_TIMEOUT"), "faults": faults,
                  "hugepage": hugepage, "big_faults": big}))
"""


def _probe(tmp_path, mode, **env):
    e = {k: v for k, v in os.environ.items()
         if k not in ("OPENBLAS_THREAD_TIMEOUT", "NUMPY_MADVISE_HUGEPAGE")}
    e.update(env, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", _PROBE, mode], capture_output=True, text=True,
                       check=True, env=e, cwd=tmp_path, timeout=120)
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="glibc's mallopt: Linux only")
def test_the_program_sets_its_process_and_a_host_keeps_its_own(tmp_path):
    program, host = _probe(tmp_path, "program"), _probe(tmp_path, "host")
    assert program["timeout"] == "4"
    assert host["timeout"] is None
    # 300 MiB of temporaries: fresh pages each time in a host (glibc raises its threshold
    # only past blocks already freed), the heap's own freed pages in the program
    assert host["faults"] > 4 * program["faults"], (program, host)
    # numpy's request for huge pages: off in the program, numpy's default in a host
    assert program["hugepage"] is False and host["hugepage"] is True
    # so the program's fresh 64 MiB array takes ordinary 4 KiB pages, one fault each (where
    # the system itself gives every large mapping huge pages, it does so whatever numpy asks)
    if "[always]" not in _thp_mode():
        assert program["big_faults"] >= 0.9 * 64 * 256, program


def _thp_mode() -> str:
    try:
        return Path("/sys/kernel/mm/transparent_hugepage/enabled").read_text()
    except OSError:  # (no transparent huge pages: ordinary pages)
        return ""


@pytest.mark.slow
def test_numpy_loaded_before_the_program_asks_for_no_huge_pages_either(tmp_path):
    seen = _probe(tmp_path, "program-numpy-first")
    assert seen["hugepage"] is False
    if "[always]" not in _thp_mode():
        assert seen["big_faults"] >= 0.9 * 64 * 256, seen


@pytest.mark.slow
def test_a_users_own_settings_are_kept(tmp_path):
    seen = _probe(tmp_path, "program", OPENBLAS_THREAD_TIMEOUT="20", NUMPY_MADVISE_HUGEPAGE="1")
    assert seen["timeout"] == "20"
    assert seen["hugepage"] is True


@pytest.mark.parametrize("argv0,program", [
    ("/usr/local/bin/render-inspect", True),
    (str(REPO / "render_inspect" / "cli" / "__main__.py"), True),  # python -m, once it runs
    ("-c", False),
    ("/somewhere/else/cli/__main__.py", False),
    ("", False),
])
def test_the_program_is_known_by_its_script_or_module(monkeypatch, argv0, program):
    from render_inspect import _early_signals

    monkeypatch.setattr(sys, "argv", [argv0, "simulate"])
    assert _early_signals.is_program() is program


def test_a_multiprocessing_worker_of_the_program_is_not_the_program(monkeypatch):
    # (a spawned worker is handed the program's sys.argv)
    from render_inspect import _early_signals

    monkeypatch.setattr(sys, "argv", ["/usr/local/bin/render-inspect"])
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "-c", "from multiprocessing.spawn import "
                                           "spawn_main; spawn_main(tracker_fd=5, pipe_handle=7)",
                                           "--multiprocessing-fork"], raising=False)
    assert _early_signals.is_program() is False
    monkeypatch.setattr(sys, "orig_argv", [sys.executable, "/usr/local/bin/render-inspect", "sweep"],
                        raising=False)
    assert _early_signals.is_program() is True


#: loads kernels from numba's cache as the program (``argv[0]`` "render-inspect") or as a
#: host: a lazy kernel, a kernel numba's own decorator built (threaded, ``parallel=True``)
#: and the phase unwrapper's; prints whether numba's compiler set-up (its library of numpy
#: functions) was imported by then, the results, and a kernel compiled afterwards
_NUMBA_PROBE = r"""
import hashlib, json, sys
import argparse
if sys.argv[1] == "program":
    sys.argv[0] = "render-inspect"
import numpy as np
import render_inspect
from render_inspect.cli._main import _run

_run(argparse.Namespace(command="(none: the program's start only)"))
from render_inspect.toolpath._kinematics import axis_derivatives
from render_inspect.instruments._kernels import filter_fold
from render_inspect.metrology._unwrap import unwrap_phase
from render_inspect.machining._interpolate import THREADED_TICKS, pvt_checked

t = np.linspace(0.0, 1.0, 50)
d = axis_derivatives(t, np.sin(3.0 * t))
rng = np.random.default_rng(5)
n = 16
spec = (rng.standard_normal((n, n)) + 1j * rng.standard_normal((n, n))).astype(np.complex64)
q2 = (np.arange(n, dtype=np.float32) / 7) ** 2
sep = np.exp(1j * np.arange(n) / 5).astype(np.complex64)
cols = np.arange(n, dtype=np.int64)
out = np.empty((n // 2, n // 2), dtype=np.complex64)
filter_fold(spec, np.ones(n, dtype=bool), q2, sep, cols, cols % (n // 2), q2, sep,
            np.linspace(1.0, 0.5, 8).astype(np.float32), np.float32(2.0), 2, out)
tp = np.cumsum(np.linspace(1e-3, 2e-3, 400))
pvt = pvt_checked(tp, np.stack([np.sin(tp), np.cos(3 * tp)]),
                  np.linspace(tp[0], tp[-1], THREADED_TICKS + 5))
# (what the simulation loads needs none of numba's library of numpy functions)
simulation_set_up = "numba.np.old_arraymath" in sys.modules
y, x = np.mgrid[0:40, 0:40]
phase = np.angle(np.exp(1j * (0.01 * (x - 20) ** 2 + 0.02 * (y - 15) ** 2)))
unwrapped = unwrap_phase(phase)[0]
set_up = "numba.np.arraymath" in sys.modules
h = hashlib.sha256()
for a in (*d, out, *pvt, unwrapped):
    h.update(np.ascontiguousarray(a).tobytes())
import numba

@numba.njit
def fresh(a):
    return np.sort(a)[::-1].sum() + np.linalg.norm(a)

v = float(fresh(np.arange(5.0)))
print(json.dumps({"set_up_before": set_up, "simulation_set_up": simulation_set_up, "hash": h.hexdigest(), "fresh": v,
                  "set_up_after": "numba.np.arraymath" in sys.modules}))
"""


def _numba_probe(tmp_path, mode):
    e = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", _NUMBA_PROBE, mode], capture_output=True, text=True,
                       env=e, cwd=tmp_path, timeout=300)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_the_program_loads_cached_kernels_without_numbas_compiler_set_up(tmp_path):
    _numba_probe(tmp_path, "host")  # (the kernels in numba's cache, compiled where absent)
    program, host = _numba_probe(tmp_path, "program"), _numba_probe(tmp_path, "host")
    # a host process: numba's own order (its set-up before the first load)
    assert host["set_up_before"] is True
    # the program: the loads alone, the same machine code (the same results bit for bit),
    # a lazy kernel, a threaded kernel of numba's own decorator and the unwrapper's alike
    assert program["set_up_before"] is False
    assert program["simulation_set_up"] is False
    assert program["hash"] == host["hash"]
    # a kernel compiled afterwards gets numba's set-up then, as numba always makes it
    assert program["set_up_after"] is True
    assert program["fresh"] == host["fresh"] == 10.0 + float(np.linalg.norm(np.arange(5.0)))


def test_a_host_keeps_numbas_own_order():
    from render_inspect.cli._main import _run
    from render_inspect.core import lazy

    # a host (the test process, even running a command in it): numba's own order
    _run(argparse.Namespace(command="(none)"))
    lazy.load_numba()
    from numba.core import caching

    assert not getattr(caching.Cache.load_overload, "_quick", False)


@pytest.mark.parametrize("version,checked", [("0.61.2", True), ("0.61.0rc1", True), ("0.62.0", False),
                                             ("0.60.0", False), ("1.0", False), ("", False),
                                             ("0.61", True), ("dev", False)])
def test_the_quick_cache_loads_are_made_only_for_the_numba_releases_checked(version, checked):
    from render_inspect.core.lazy import quick_loads_checked

    assert quick_loads_checked(version) is checked
