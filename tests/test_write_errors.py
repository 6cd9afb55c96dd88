"""Write errors (a full disk, a quota, an I/O error) give one line naming the file and the
cause, and a failed run leaves no empty or partial folder.

OpenEXR reports a failed write as a ``RuntimeError`` whose text ends in the C library's
(``Failed to write pixel data to image file "x.exr". No space left on device.``); the
faults below are that error, injected into the writer, and the kernel's own (the
file-size limit, EFBIG)."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
import types

import numpy as np
import pytest

from render_inspect.errors import InputError
from render_inspect.io import atomic_output_dir, discard_unused, write_exr
from render_inspect.io._write_errors import as_os_error

FAULTS = [errno.ENOSPC, errno.EDQUOT, errno.EIO]

#: a script that runs the command line with OpenEXR's writes failing with the errno argv[1]
_FAILING_EXR = """
import errno, os, sys, types
import OpenEXR as real
code = int(sys.argv[1])

class File:
    def __init__(self, *a, **k):
        self._f = real.File(*a, **k)
    def __enter__(self):
        return self
    def __exit__(self, *exc):
        return False
    def write(self, path):
        raise RuntimeError(f'Failed to write pixel data to image file "{path}". '
                           f'{os.strerror(code)}.')

fake = types.ModuleType("OpenEXR")
fake.__dict__.update({k: getattr(real, k) for k in dir(real) if not k.startswith("__")})
fake.File = File
sys.modules["OpenEXR"] = fake
from render_inspect import cli
sys.exit(cli.main(sys.argv[2:]))
"""


def _failing_openexr(monkeypatch, code):
    import OpenEXR as real

    class File:
        def __init__(self, *a, **k):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def write(self, path):
            with open(path, "wb") as fh:  # a part written, as a real failure leaves
                fh.write(b"v/1\x01" + bytes(100))
            raise RuntimeError(f'Failed to write pixel data to image file "{path}". '
                               f'{os.strerror(code)}.')

    fake = types.ModuleType("OpenEXR")
    fake.__dict__.update({k: getattr(real, k) for k in dir(real) if not k.startswith("__")})
    fake.File = File
    monkeypatch.setitem(sys.modules, "OpenEXR", fake)


@pytest.mark.parametrize("code", FAULTS)
def test_an_exr_write_error_is_the_os_error_it_stands_for(tmp_path, monkeypatch, code):
    _failing_openexr(monkeypatch, code)
    with pytest.raises(OSError) as info:
        write_exr(tmp_path / "diffuse.exr", {"R": np.zeros((4, 4))})
    assert info.value.errno == code and info.value.filename == str(tmp_path / "diffuse.exr")
    assert os.listdir(tmp_path) == []  # no temporary file left


@pytest.mark.parametrize("code", FAULTS)
def test_an_exr_write_error_in_an_output_folder_is_one_line_naming_the_file(tmp_path,
                                                                           monkeypatch, code):
    _failing_openexr(monkeypatch, code)
    with pytest.raises(InputError) as info:
        with atomic_output_dir(tmp_path / "o", command="render") as tmp:
            write_exr(tmp / "diffuse.exr", {"R": np.zeros((4, 4))})
    msg = str(info.value)
    assert "\n" not in msg and "diffuse.exr" in msg and os.strerror(code) in msg, msg
    assert "nothing was written" in msg
    assert os.listdir(tmp_path) == []  # no folder, no partial folder, no lock


def test_library_errors_without_a_system_cause_are_left_alone(tmp_path):
    assert as_os_error(RuntimeError("Cannot compress: bad channel"), tmp_path / "a.exr") is None
    e = as_os_error(OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)), tmp_path / "a.exr")
    assert e.filename == str(tmp_path / "a.exr") and e.errno == errno.ENOSPC


def test_an_unused_folder_is_discarded_a_used_one_kept(tmp_path):
    a = tmp_path / "a"
    a.mkdir()
    (a / ".render_inspect.json").write_text("{}")
    (a / "results.jsonl").write_text("")
    assert discard_unused(a, (".render_inspect.json",)) and not a.exists()
    b = tmp_path / "b"
    b.mkdir()
    (b / "results.jsonl").write_text('{"id": 1}\n')
    assert not discard_unused(b, (".render_inspect.json",)) and b.exists()


@pytest.mark.slow  # the sweep starts its Dask cluster before it claims the folder
@pytest.mark.parametrize("code", FAULTS)
def test_sweep_on_a_full_disk_leaves_no_folder(tmp_path, monkeypatch, capsys, code):
    """The sweep's folder is made and marked before any point runs: a write error there
    (its marker, its copy of the sweep file) is one line, and no empty folder is left."""
    from render_inspect import cli
    from render_inspect.io import _atomic_write
    from render_inspect.pipeline import _sweep

    sweep = tmp_path / "s.toml"
    sweep.write_text('name = "s"\nscene = "sts_sinusoidal_grid"\n[grid]\n'
                     '"tool.nose_radius" = [0.2, 0.5]\n')

    def full(path, *a, **k):
        raise OSError(code, os.strerror(code), str(path))

    for where, name in ((_atomic_write, "atomic_write_stream"), (_sweep, "atomic_write_bytes")):
        with monkeypatch.context() as m:
            m.setattr(where, name, full)
            out = tmp_path / f"out_{name}"
            rc = cli.main(["sweep", str(sweep), "--out", str(out), "-q"])
            err = capsys.readouterr().err.strip().splitlines()
        assert rc == 1 and len(err) == 1 and os.strerror(code) in err[0], err
        assert "Traceback" not in err[0]
        assert not out.exists(), (name, os.listdir(out))
    assert sorted(os.listdir(tmp_path)) == ["s.toml"]


@pytest.mark.slow
@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EIO])
def test_the_command_line_reports_an_exr_write_error_in_one_line(tmp_path, code):
    out = tmp_path / "o"
    sets = ["simulation.region=[-0.02,-0.02,0.02,0.02]", "simulation.pixel=0.002",
            "process.workpiece_radius=0.05", "machine.preset='ideal'", "material.preset='ideal'"]
    args = sum((["--set", s] for s in sets), [])
    r = subprocess.run([sys.executable, "-c", _FAILING_EXR, str(code), "simulate",
                        "sts_sinusoidal_grid", *args, "--out", str(out), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 1, r.stderr
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and "internal error" not in err[0], err
    assert ".exr" in err[0] and os.strerror(code) in err[0] and "--out" in err[0], err
    assert os.listdir(tmp_path) == []


@pytest.mark.slow
def test_a_real_write_error_in_the_exr_writer_is_one_line(tmp_path):
    """The kernel's file-size limit fails the EXR writer's own write (EFBIG)."""
    import resource
    import signal

    out = tmp_path / "o"
    sets = ["simulation.region=[-0.1,-0.1,0.1,0.1]", "simulation.pixel=0.001",
            "process.workpiece_radius=0.15", "machine.preset='ideal'", "material.preset='ideal'"]

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (96 * 1024, 96 * 1024))

    r = subprocess.run([sys.executable, "-m", "render_inspect.cli", "simulate",
                        "sts_sinusoidal_grid", *sum((["--set", s] for s in sets), []),
                        "--out", str(out), "-q"], capture_output=True, text=True,
                       preexec_fn=limit, timeout=300)
    assert r.returncode == 1, r.stderr
    err = r.stderr.strip().splitlines()
    assert len(err) == 1 and "File too large" in err[0] and "internal error" not in err[0], err
    assert os.listdir(tmp_path) == []
