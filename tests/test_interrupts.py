"""Every command stops when asked: SIGINT or SIGTERM sent while the command works (its
temporary output folder exists, or its computation before that folder is under way, and
it has been busy for a moment) ends it within
:data:`LATENCY_S` with exit 130 / 143, one line on stderr and no traceback, the output
folder as it was before the run (here: an earlier run's files, untouched) and no
temporary folder left behind.  The latency of each command is printed (``-s``).

The long steps run in blocks and stop between them (:mod:`render_inspect.core.cancel`);
the bound leaves room for a loaded machine (the target is about 2 s)."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from render_inspect.io import atomic_output_dir

REPO = Path(__file__).resolve().parents[1]
#: the largest stop latency accepted, s
LATENCY_S = float(os.environ.get("RENDER_INSPECT_STOP_LATENCY_S", "3.5"))
#: how long the command works before the signal, s (after its temporary folder appears)
BUSY_S = 1.5


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    d = tmp_path_factory.mktemp("inputs")
    z = np.random.default_rng(0).normal(0, 1e-5, (3000, 3000))
    np.save(d / "big.npy", z)
    (d / "big.json").write_text('{"pixel_mm": 0.00025}')
    # interferometer frames: a CSI scan of a tilted plane, large enough to take a while
    from render_inspect.instruments import Microscope, artefacts, csi_frames, led, objective
    from render_inspect.io import write_frames_exr

    p = 0.5e-3
    # large enough that measure works for several seconds after reading them on a quiet
    # machine (1000 x 1000 took 6.4 s in all): 1400 x 1400 pixels, the scan of a 200-row
    # strip repeated along y (the lines run along y: the same surface, the camera noise of
    # the strip repeated; rendering the whole field took 8 s of CPU)
    h, nrm = artefacts.sinusoid((200, 1400), p, period=0.05, amplitude=2e-5)
    fr = csi_frames(h + 2e-3, nrm, pixel=p, origin=(0.0, 0.0),
                    microscope=Microscope(objective=objective("20x"), source=led()))
    fr = dataclasses.replace(fr, frames=np.tile(fr.frames, (1, 7, 1)),
                             valid=np.tile(fr.valid, (7, 1)))
    assert fr.frames.shape[1:] == (1400, 1400)
    write_frames_exr(d / "frames.exr", fr)
    # a measured height map (as measure writes it) for fit: turning marks of 10 um about
    # the part's axis, seen where the field lies (origin: the lower left pixel), so that
    # the fit passes its checks of the measurement and works until it is stopped
    from render_inspect.io import write_measurement_exr

    n, px = 128, 0.00087890625
    x = np.arange(n) * px
    r = np.hypot(x[None, :] + 0.3, x[:, None] - 0.05)
    u = (r / 0.0101 - np.round(r / 0.0101)) * 0.0101
    z = 0.514 - np.sqrt(0.514 ** 2 - u ** 2) + 1e-5 * np.arange(n)[None, :]
    write_measurement_exr(d / "height.exr", z, np.ones_like(z, bool), pixel=px,
                          origin=(0.3, -0.05), attrs={"objective": "20x", "mode": "psi"})
    return d


# (name, arguments, signal); the output folder is added as --out
COMMANDS = [
    ("simulate", ["simulate", "sts_sinusoidal_grid", "--set", "simulation.region=[-1,-1,1,1]",
                  "--set", "material.preset='ideal'", "--set", "simulation.pixel=0.0004"], "SIGINT"),
    ("simulate-material", ["simulate", "sts_sinusoidal_grid", "--set", "simulation.pixel=0.00025"],
     "SIGTERM"),
    ("simulate-tiled", ["simulate", "sts_sinusoidal_grid", "--tiled", "--set",
                        "material.preset='ideal'", "--set", "simulation.region=[-1.5,-1.5,1.5,1.5]"],
     "SIGTERM"),
    ("toolpath", ["toolpath", "rcse_circular_array", "--format", "nc"], "SIGINT"),
    ("render", ["render", "sts_sinusoidal_grid"], "SIGTERM"),
    ("compare", ["compare", "sts_sinusoidal_grid"], "SIGINT"),
    ("analyze", ["analyze", "{inputs}/big.npy", "--filter", "0.0025,0.5"], "SIGTERM"),
    ("measure", ["measure", "{inputs}/frames.exr"], "SIGINT"),
    ("characterise", ["characterise", "--objective", "20x"], "SIGTERM"),
    ("sweep", ["sweep", "fig15_small"], "SIGINT"),
    ("regress", ["regress", "--only", "fig16_overcut_z,hts_toric_z,fts_toric_z,mla_2x2_z"], "SIGTERM"),
    ("demo", ["demo", "--quick"], "SIGINT"),
    ("fit", ["fit", "{inputs}/height.exr", "--scene", "sts_sinusoidal_grid", "--free",
             "tool.nose_radius", "--window", "0.11"], "SIGTERM"),
]
#: commands that compute before they open their output folder: busy this long after the
#: start, s (analyze: the Gaussian L-filter of the 3000 x 3000 map; measure: the frames'
#: demodulation after reading them)
STARTED_AFTER_S = {"analyze": 4.0, "measure": 6.0}


def _tree(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


def _working(name: str, out: Path, t0: float) -> bool:
    """Whether the command is at work: its temporary output folder exists (a sweep's folder
    is locked, not swapped; fit writes its evaluations to ``<out>.cache`` and its folder only
    at the end), or it has run for :data:`STARTED_AFTER_S`."""
    if name == "fit":
        return any(out.parent.glob(f"{out.name}.cache/*.npz"))
    if name in STARTED_AFTER_S:
        return time.monotonic() - t0 >= STARTED_AFTER_S[name]
    return any(".partial-" in p.name for p in out.parent.iterdir()) or (out / ".lock").exists()


def _stop_once_busy(name, args, out: Path, sig: str, cwd: Path):
    # (PYTHONFAULTHANDLER: a command that hangs is ended with SIGABRT, which prints every
    # thread's stack into the failure.  Its errors go to a temporary file, not a pipe: a
    # pipe that nobody reads while the command works would block its writes once full)
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               PYTHONFAULTHANDLER="1")
    err_file = tempfile.TemporaryFile("w+")
    with err_file, open(os.devnull, "w") as so:
        proc = subprocess.Popen([sys.executable, "-m", "render_inspect.cli", *args, "--out", str(out),
                                 "-q"], cwd=cwd, env=env, stdout=so, stderr=err_file, text=True)
        return _stopped(proc, name, args, out, sig, err_file)


def _stopped(proc, name, args, out: Path, sig: str, err_file):
    """:func:`_stop_once_busy` once the command runs, its errors written into ``err_file``."""
    def err_text() -> str:
        err_file.seek(0)
        return err_file.read()

    t0 = time.monotonic()
    busy_since = None
    while proc.poll() is None and time.monotonic() - t0 < 400:
        started = _working(name, out, t0)
        if started and busy_since is None:
            busy_since = time.monotonic()
        if busy_since is not None and time.monotonic() - busy_since >= BUSY_S:
            break
        time.sleep(0.05)
    if proc.poll() is not None or not _working(name, out, t0):
        proc.wait()
        pytest.fail(f"{args[0]} finished its work before it was stopped (rc {proc.returncode}): "
                    f"{err_text()[-500:]}; give it more to do")
    ts = time.monotonic()
    proc.send_signal(getattr(signal, sig))
    try:
        proc.wait(timeout=120)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGABRT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        pytest.fail(f"{args[0]} did not stop within 120 s of {sig}; its threads then:\n"
                    f"{err_text()[-6000:]}")
    latency = time.monotonic() - ts
    return proc.returncode, latency, err_text()


def _needs_inputs(args) -> bool:
    return any("{inputs}" in a for a in args)


#: the commands that read the inputs run on one worker, which makes them once
_PARAMS = [pytest.param(*c, id=c[0], marks=[pytest.mark.xdist_group("interrupts_inputs")]
                        if _needs_inputs(c[1]) else []) for c in COMMANDS]


@pytest.mark.parametrize("name,args,sig", _PARAMS)
@pytest.mark.slow
def test_command_stops_within_seconds(name, args, sig, request, tmp_path):
    if _needs_inputs(args):
        inputs = request.getfixturevalue("inputs")
        args = [a.replace("{inputs}", str(inputs)) for a in args]
    out = tmp_path / "out"
    if name != "sweep":  # an earlier run's folder, which must stay as it was
        with atomic_output_dir(out, command=args[0]) as tmp:
            (tmp / "earlier.txt").write_text("an earlier run")
    before = _tree(out) if out.exists() else {}
    rc, latency, err = _stop_once_busy(name, args, out, sig, tmp_path)
    print(f"\n{name}: {sig} -> exit {rc} after {latency:.2f} s")
    assert rc == (130 if sig == "SIGINT" else 143), (name, rc, err[-800:])
    lines = err.strip().splitlines()
    assert "Traceback" not in err and len(lines) == 1, err[-800:]
    assert ("interrupted" if sig == "SIGINT" else "terminated") in lines[0]
    assert latency < LATENCY_S, (name, latency)
    leftovers = [p.name for p in tmp_path.iterdir() if ".partial-" in p.name or
                 p.name.endswith(".lock")]
    assert not leftovers, leftovers
    if name == "sweep":  # the finished points are kept, the folder is a sweep's
        assert "results.jsonl" in lines[0]
        assert json.loads((out / ".render_inspect.json").read_text())
    else:
        assert _tree(out) == before
    if name == "fit":  # the evaluations made are kept (and said where), nothing else
        cache = tmp_path / "out.cache"
        assert f"evaluations made are kept in {cache}" in lines[0], lines[0]
        kept = [p.name for p in cache.iterdir()]
        assert kept and all(k.endswith(".npz") for k in kept), kept
        assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "out.cache"]


#: a stop while Mitsuba / Dr.Jit are imported: the signal is sent from an audit hook at the
#: k-th module import after ``import mitsuba`` began, so that its handler runs inside that
#: import (without the deferral, k = 7 ... 10 failed to import drjit.llvm and k = 25 ... 35
#: aborted the process with SIGABRT from inside Mitsuba's C++ module set-up)
_STOP_IN_IMPORT = """
import os, signal, sys
from render_inspect import cli
from render_inspect.core import cancel
from render_inspect.core.cancel import Terminated
k = int(sys.argv[1])
def handler(signum, frame):  # the command line's handler; one stop is enough here
    if cancel.requested() is None:
        cli._on_terminate(signum, frame)
signal.signal(signal.SIGTERM, handler)
n = [0]
def hook(event, args):
    if event == "import" and n[0] >= 0:
        if n[0] == 0 and not str(args[0]).startswith(("mitsuba", "drjit")):
            return
        n[0] += 1
        if n[0] == k:
            n[0] = -1
            print("signal during the import of", args[0], flush=True)
            os.kill(os.getpid(), signal.SIGTERM)
sys.addaudithook(hook)
from render_inspect.render import import_mitsuba
try:
    import_mitsuba()
except Terminated:
    print("stopped after the import", flush=True)
    sys.exit(143)
print("no signal was sent: Mitsuba imports", n, "modules")
sys.exit(3)
"""


@pytest.mark.parametrize("k", [7, 10, 25, 30, 35])
@pytest.mark.slow
def test_a_stop_while_mitsuba_is_imported_waits_for_the_import(k):
    """SIGTERM arriving while Mitsuba and Dr.Jit are imported (their C++ module set-up
    builds Python objects, which cannot unwind an exception raised by the handler) is
    raised right after the import: a clean stop, never an abort."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", _STOP_IN_IMPORT, str(k)], capture_output=True,
                       text=True, env=env, timeout=120)
    assert "signal during the import of" in r.stdout, (r.returncode, r.stdout, r.stderr[-800:])
    assert r.returncode == 143 and "stopped after the import" in r.stdout, \
        (r.returncode, r.stdout, r.stderr[-800:])


#: a stop while llvmlite holds its lock on the LLVM library, taken for every call into it
#: (numba loading a kernel from its cache): the signal is sent from a callback that
#: llvmlite runs once it holds the lock, as numba's own callbacks run there; afterwards
#: another thread calls into LLVM, as a row thread loading its kernel does
_STOP_IN_LLVM_LOCK = """
import os, signal, sys, threading
import llvmlite.binding as llvm
from llvmlite.binding import ffi
import numba  # (its callbacks on the lock, as in a run)
from render_inspect.cli import _main
from render_inspect.core import cancel
from render_inspect.core.cancel import Terminated

signal.signal(signal.SIGTERM, _main._on_terminate)
sent = []
def taken():
    if not sent:
        sent.append(1)
        os.kill(os.getpid(), signal.SIGTERM)
ffi.register_lock_callback(taken, lambda: None)
try:
    llvm.get_process_triple()
    cancel.check()
except Terminated:
    print("stopped", flush=True)
other = threading.Thread(target=llvm.get_process_triple, daemon=True)
other.start()
other.join(20)
print("the lock is held" if other.is_alive() else "the lock is free", flush=True)
"""


@pytest.mark.slow
def test_a_stop_while_llvm_is_locked_leaves_the_lock_free():
    """SIGTERM arriving while llvmlite takes its lock (numba's callbacks run there) is
    raised at the next check, not inside the lock's steps: raised there it left the lock
    held for ever, and the next thread that called into LLVM (a row thread loading its
    kernel) waited for ever, and the stopped program with it."""
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    r = subprocess.run([sys.executable, "-c", _STOP_IN_LLVM_LOCK], capture_output=True,
                       text=True, env=env, timeout=120)
    assert r.returncode == 0 and r.stdout.split("\n")[:2] == ["stopped", "the lock is free"], \
        (r.returncode, r.stdout, r.stderr[-800:])
