"""The ``render-inspect`` program's own process settings (render_inspect._process_settings):
made in the program, never in a program that imports the package; OpenBLAS's thread
timeout as the user set it when they did; and large temporary arrays reuse freed memory
(the page faults of a growing temporary, measured)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: imports the package as the program (``argv[0]`` "render-inspect") or as a host, then
#: prints the settings seen and the minor page faults of arrays of 1 to 24 MiB, each
#: allocated, filled and freed in turn (4 KiB pages)
_PROBE = r"""
import json, os, resource, sys
if sys.argv[1] == "program":
    sys.argv[0] = "render-inspect"
import render_inspect
import ctypes
import numpy as np
# pages counted one by one (no transparent huge pages in this process, and numpy asks
# for none)
ctypes.CDLL(None).prctl(41, 1, 0, 0, 0)  # PR_SET_THP_DISABLE
_mu = getattr(np, "_core", None) or np.core
_mu.multiarray._set_madvise_hugepage(False)
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for mib in range(1, 25):
    a = np.empty(mib * 1024 * 1024 // 8)
    a.fill(1.0)
    del a
faults = resource.getrusage(resource.RUSAGE_SELF).ru_minflt - faults
print(json.dumps({"timeout": os.environ.get("OPENBLAS_THREAD_TIMEOUT"), "faults": faults}))
"""


def _probe(tmp_path, mode, **env):
    e = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
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


@pytest.mark.slow
def test_a_users_openblas_timeout_is_kept(tmp_path):
    assert _probe(tmp_path, "program", OPENBLAS_THREAD_TIMEOUT="20")["timeout"] == "20"


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
