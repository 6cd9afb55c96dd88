"""How the ``render-inspect`` program ends after a stop (SIGINT / SIGTERM): with its code
and its one line, the threads that are not daemons waited for (what they write is
complete), and without the interpreter's teardown, which stops the daemon threads still
at work (the figures' library being imported while the part is cut) wherever they are:
inside native code that may abort the process (SIGABRT) or crash it instead."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: the program (``main()`` with the command line in ``sys.argv``), stopped by SIGTERM from
#: a thread once its temporary output folder exists; meanwhile a daemon thread is at work,
#: a worker thread (not a daemon) is writing a file, and an audit hook says on stderr
#: when the interpreter's teardown begins
_SCRIPT = """
import os, signal, sys, threading, time
from pathlib import Path
out = Path(sys.argv[1])

def audit(event, args, write=os.write):  # the interpreter's teardown announces itself
    if event in ("cpython.PyInterpreterState_Clear", "cpython._PySys_ClearAuditHooks"):
        write(2, b"the interpreter's teardown ran\\n")

sys.addaudithook(audit)

def busy():  # a daemon thread at work when the process ends
    while True:
        sum(range(1000))

def worker():  # a thread that is not a daemon, finishing what it writes after the stop
    time.sleep(1.0)
    (out.parent / "worker.txt").write_text("complete")

def stopper():
    while not any(".partial-" in p.name for p in out.parent.iterdir()):
        time.sleep(0.02)
    threading.Thread(target=busy, daemon=True).start()
    threading.Thread(target=worker, daemon=False).start()
    time.sleep(0.3)
    os.kill(os.getpid(), signal.SIGTERM)

threading.Thread(target=stopper, daemon=True).start()
sys.argv = ["render-inspect", "simulate", "sts_sinusoidal_grid", "--out", str(out), "-q"]
from render_inspect.cli import main
sys.exit(main())
"""


@pytest.mark.slow
def test_a_stopped_program_ends_without_the_teardown(tmp_path):
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", _SCRIPT, str(tmp_path / "out")], cwd=tmp_path,
                       capture_output=True, text=True, env=env, timeout=300)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 143, (r.returncode, r.stderr[-800:])
    assert len(lines) == 1 and "terminated" in lines[0], r.stderr[-800:]
    # the worker's file is complete, nothing else is left
    assert (tmp_path / "worker.txt").read_text() == "complete"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["worker.txt"]

