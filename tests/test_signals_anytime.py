"""Signals at any moment end with one line and the documented exit code: during start-up
(while the package and its libraries are imported, before the command's own handlers are
in place), right after the command returns, and in the middle of a threaded tiled
simulation, whose tiles already running are waited for before the output folder is
removed (so that none of them writes into it again after it was removed)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: runs the program as ``python -m render_inspect.cli`` does, and sends itself the signal
#: argv[1] at the argv[2]-th import after the command line's module began importing the
#: package's core (an audit hook; the module counted from is $START_AT if set)
_AT_IMPORT = """
import os, runpy, signal, sys
sig, k = getattr(signal, sys.argv[1]), int(sys.argv[2])
start = os.environ.get("START_AT", "render_inspect.core")
seen = {"n": 0, "on": False}
def hook(event, args):
    if event == "import" and args[0] == start:
        seen["on"] = True
    elif event == "import" and seen["on"]:
        seen["n"] += 1
        if seen["n"] == k:
            os.kill(os.getpid(), sig)
sys.addaudithook(hook)
if os.environ.get("COUNT_TO"):  # the imports of a whole run, counted (k = 0: no signal)
    import atexit
    atexit.register(lambda: open(os.environ["COUNT_TO"], "w").write(str(seen["n"])))
sys.argv = ["render-inspect", *sys.argv[3:]]
runpy.run_module("render_inspect.cli", run_name="__main__", alter_sys=True)
"""

#: the program's handlers as the console script has them, a command run to its end, then
#: the signal argv[1]
_AFTER_MAIN = """
import os, signal, sys, time
from render_inspect import _early_signals
_early_signals.install()
from render_inspect import cli
rc = cli.main(sys.argv[2:])
assert rc == 0, rc
os.kill(os.getpid(), getattr(signal, sys.argv[1]))
time.sleep(5)
sys.exit(rc)
"""


def _env():
    return dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))


@pytest.mark.slow
@pytest.mark.parametrize("sig,code", [("SIGTERM", 143), ("SIGINT", 130)])
@pytest.mark.parametrize("k", [1, 40, 400])
def test_a_signal_during_start_up_is_one_line(tmp_path, sig, code, k):
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-c", _AT_IMPORT, sig, str(k), "toolpath",
                        "sts_sinusoidal_grid", "--out", str(out), "-q"], capture_output=True,
                       text=True, timeout=300, env=_env(), cwd=tmp_path)
    err = r.stderr.strip().splitlines()
    assert r.returncode == code, (k, r.returncode, r.stderr[-800:])
    assert "Traceback" not in r.stderr and len(err) == 1, r.stderr[-800:]
    assert ("interrupted" if sig == "SIGINT" else "terminated") in err[0]
    assert err[0].startswith("render-inspect"), err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if ".partial" in p.name]


@pytest.fixture(scope="module")
def core_imports(tmp_path_factory) -> int:
    """How many imports a whole ``toolpath`` run makes after the package's core (it
    depends on what the run needs and on the installed libraries, so the moments below
    are fractions of it)."""
    d = tmp_path_factory.mktemp("count")
    count = d / "count.txt"
    r = subprocess.run([sys.executable, "-c", _AT_IMPORT, "SIGINT", "0", "toolpath",
                        "sts_sinusoidal_grid", "--out", str(d / "o"), "-q"], capture_output=True,
                       text=True, timeout=300, env={**_env(), "COUNT_TO": str(count)}, cwd=d)
    assert r.returncode == 0, r.stderr[-800:]
    return int(count.read_text())


@pytest.mark.slow
@pytest.mark.parametrize("start,at", [("render_inspect", 3), ("render_inspect", 6),
                                      ("render_inspect.core", 0.2), ("render_inspect.core", 0.45),
                                      ("render_inspect.core", 0.7), ("render_inspect.core", 0.95)])
def test_ctrl_c_at_any_moment_of_the_start_up_is_one_line(tmp_path, start, at, core_imports):
    # from the package's first statement (the 3rd import from the package's own: the
    # handler is in place once the package's first module, standard library only, is
    # imported) through the scene's schema being imported and checked, the pipeline, SciPy,
    # and numba imported when the first kernel runs (fractions of all the imports a whole
    # run makes after the core): one line, exit 130, nothing written
    k = at if isinstance(at, int) else max(1, int(at * core_imports))
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-c", _AT_IMPORT, "SIGINT", str(k), "toolpath",
                        "sts_sinusoidal_grid", "--out", str(out)], capture_output=True,
                       text=True, timeout=300, env={**_env(), "START_AT": start}, cwd=tmp_path)
    err = [line for line in r.stderr.strip().splitlines() if line.strip()]
    assert r.returncode == 130, (k, r.returncode, r.stderr[-800:])
    assert "Traceback" not in r.stderr, r.stderr[-800:]
    assert len(err) == 1 and "interrupted" in err[0], r.stderr[-800:]
    assert err[0].startswith("render-inspect toolpath:"), err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if ".partial" in p.name]


@pytest.mark.slow
@pytest.mark.parametrize("sig,code", [("SIGTERM", 143), ("SIGINT", 130)])
def test_a_late_signal_prints_its_message(tmp_path, sig, code):
    out = tmp_path / "o"
    r = subprocess.run([sys.executable, "-c", _AFTER_MAIN, sig, "toolpath",
                        "sts_sinusoidal_grid", "--out", str(out), "-q"], capture_output=True,
                       text=True, timeout=300, env=_env(), cwd=tmp_path)
    err = r.stderr.strip().splitlines()
    assert r.returncode == code, (r.returncode, r.stderr[-800:])
    assert len(err) == 1 and "the run had finished" in err[0], r.stderr[-800:]
    assert err[0].startswith("render-inspect toolpath:")
    assert (out / "toolpath.npz").is_file()  # the run's folder is whole


def test_a_stopped_threaded_tile_run_waits_for_the_tiles_it_is_cutting():
    """The stop reaches the main thread while the pool's threads cut their tiles: the run
    raises only once every tile that had started has ended."""
    from render_inspect.batch import _tiled

    state = {"started": 0, "ended": 0}
    lock = threading.Lock()

    def tile(i):
        with lock:
            state["started"] += 1
        time.sleep(0.2)
        with lock:
            state["ended"] += 1
        return i

    def progress(done, total, dt):  # the stop arrives as the first tile ends
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        _tiled._run(tile, [(i,) for i in range(8)], (), workers=4, progress=progress)
    assert state["started"] >= 2 and state["ended"] == state["started"], state


@pytest.mark.slow
def test_sigterm_during_the_tiled_simulation_leaves_no_partial_folder(tmp_path):
    out = tmp_path / "o"
    args = ["simulate", "sts_sinusoidal_grid", "--tiled", "--set", "material.preset='ideal'",
            "--set", "simulation.region=[-1.5,-1.5,1.5,1.5]", "--out", str(out), "-q"]
    proc = subprocess.Popen([sys.executable, "-m", "render_inspect.cli", *args], cwd=tmp_path,
                            env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0 = time.monotonic()
    store = None
    while proc.poll() is None and time.monotonic() - t0 < 300:
        parts = [p for p in tmp_path.iterdir() if ".partial-" in p.name]
        # tiles are being written: the store has chunks
        if parts and any(parts[0].rglob("c/*")):
            store = parts[0]
            break
        time.sleep(0.05)
    assert store is not None, "the tiled simulation ended before its tiles were written"
    proc.send_signal(signal.SIGTERM)
    proc.wait(timeout=120)
    err = proc.stderr.read().strip().splitlines()
    assert proc.returncode == 143 and len(err) == 1 and "left as it was" in err[0], err
    time.sleep(1.0)  # a tile still running would write now
    assert not [p.name for p in tmp_path.iterdir() if ".partial-" in p.name or ".lock" in p.name]
    assert not out.exists()
