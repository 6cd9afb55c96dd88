"""The ``render-inspect`` program's own process settings (render_inspect._process_settings):
made in the program, never in a program that imports the package; OpenBLAS's thread
timeout and numpy's huge-page switch as the user set them when they did; large temporary
arrays reuse freed memory (the page faults of a growing temporary, measured); numpy asks
for no huge pages (the page faults of a fresh large array, measured)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

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
