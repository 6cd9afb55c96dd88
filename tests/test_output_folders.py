"""Output folders: checked before any work, locked, swapped in whole, never merged with
a user's files, left as they were after an error, an interruption or a kill."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from render_inspect import cli
from render_inspect.errors import InputError
from render_inspect.io import MARKER, atomic_output_dir, check_output_path, read_marker
from render_inspect.pipeline import run_simulate
from render_inspect.io._outdir_names import scene_files
from render_inspect.scene import find_scene, load_scene

SMALL = ["simulation.region=[-0.05,-0.05,0.05,0.05]", "simulation.pixel=0.005",
         "process.workpiece_radius=0.6"]
#: a run of a few seconds (for the signal and lock tests)
SLOW = ["simulation.region=[-1,-1,1,1]", "simulation.pixel=0.0008", "process.workpiece_radius=1.6"]


def _tree(folder: Path) -> dict:
    """Relative path -> sha256 of every file below ``folder``."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _leftovers(parent: Path) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if ".partial-" in p.name
                  or ".backup-" in p.name or p.name.endswith(".lock"))


def _main(capsys, *argv):
    """Run the command line in this process; the log handler it installs writes to this
    test's captured stderr and is removed afterwards."""
    cli.log.handlers.clear()
    try:
        rc = cli.main([str(a) for a in argv])
    finally:
        cli.log.handlers.clear()
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return rc, err


# ------------------------------------------------------------------ the folder itself
def test_a_new_folder_gets_the_files_and_the_marker(tmp_path):
    out = tmp_path / "a" / "b"
    with atomic_output_dir(out, command="simulate") as tmp:
        (tmp / "x.txt").write_text("1")
        (tmp / "sub").mkdir()
        (tmp / "sub" / "y.txt").write_text("2")
    assert sorted(os.listdir(out)) == [MARKER, "sub", "x.txt"]
    m = read_marker(out)
    assert m["files"] == {"sub/y.txt": "simulate", "x.txt": "simulate"}
    assert _leftovers(out.parent) == []


def test_rerun_replaces_the_whole_folder_and_drops_old_files(tmp_path):
    out = tmp_path / "o"
    with atomic_output_dir(out, command="toolpath") as tmp:
        (tmp / "toolpath.csv").write_text("old")
        (tmp / "report.html").write_text("old")
    with atomic_output_dir(out, command="toolpath") as tmp:
        (tmp / "toolpath.nc").write_text("new")
    assert sorted(os.listdir(out)) == [MARKER, "toolpath.nc"]
    assert _leftovers(tmp_path) == []


def test_a_folder_render_inspect_did_not_write_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "metrics.json").write_text('{"mine": 1}')
    with pytest.raises(InputError, match=r"--out .* not written by render-inspect.*--overwrite"):
        with atomic_output_dir(out, command="simulate"):
            raise AssertionError("the block must not run")
    assert (out / "metrics.json").read_text() == '{"mine": 1}'
    with atomic_output_dir(out, command="simulate", overwrite=True) as tmp:
        (tmp / "metrics.json").write_text("{}")
    assert (out / "metrics.json").read_text() == "{}"
    assert read_marker(out) is not None


def test_files_added_to_an_output_folder_are_not_deleted_silently(tmp_path):
    out = tmp_path / "o"
    with atomic_output_dir(out, command="simulate") as tmp:
        (tmp / "heightmap.exr").write_text("x")
    (out / "notes.txt").write_text("my notes")
    with pytest.raises(InputError, match=r"notes\.txt"):
        with atomic_output_dir(out, command="simulate"):
            pass
    assert (out / "notes.txt").read_text() == "my notes"


def test_render_merges_into_a_simulate_folder_of_the_same_part_only(tmp_path):
    scene = load_scene("sts_sinusoidal_grid", SMALL)
    other = scene.with_overrides(["process.spindle_rpm=60"])
    out = tmp_path / "o"
    with atomic_output_dir(out, command="simulate", scene=scene) as tmp:
        (tmp / "heightmap.exr").write_text("sim")
    with atomic_output_dir(out, command="render", merge=True, scene=scene) as tmp:
        (tmp / "interferogram.exr").write_text("r1")
    assert sorted(os.listdir(out)) == [MARKER, "heightmap.exr", "interferogram.exr"]
    # a second render replaces the first render's images, keeps simulate's files
    with atomic_output_dir(out, command="render", merge=True, scene=scene) as tmp:
        (tmp / "diffuse_macro.png").write_text("r2")
    assert sorted(os.listdir(out)) == [MARKER, "diffuse_macro.png", "heightmap.exr"]
    assert read_marker(out)["files"] == {"diffuse_macro.png": "render", "heightmap.exr": "simulate"}
    # a render settings change is the same part; a process change is not
    with atomic_output_dir(out, command="render", merge=True,
                           scene=scene.with_overrides(["render.diffuse.spp=4"])):
        pass
    with pytest.raises(InputError, match="different part"):
        with atomic_output_dir(out, command="render", merge=True, scene=other):
            pass
    with atomic_output_dir(out, command="render", merge=True, scene=other, overwrite=True) as tmp:
        (tmp / "x.png").write_text("")
    assert sorted(os.listdir(out)) == [MARKER, "x.png"]


@pytest.mark.parametrize("exc", [RuntimeError("boom"), KeyboardInterrupt()])
def test_an_error_or_interruption_leaves_the_folder_as_it_was(tmp_path, exc):
    out = tmp_path / "o"
    with atomic_output_dir(out, command="simulate") as tmp:
        (tmp / "metrics.json").write_text("old")
    before = _tree(out)
    with pytest.raises(type(exc)):
        with atomic_output_dir(out, command="simulate") as tmp:
            (tmp / "metrics.json").write_text("new")
            raise exc
    assert _tree(out) == before
    assert _leftovers(tmp_path) == []
    # a new folder that failed is not created at all, nor its parents
    with pytest.raises(type(exc)):
        with atomic_output_dir(tmp_path / "p" / "q" / "r", command="simulate"):
            raise exc
    assert not (tmp_path / "p").exists()


def test_a_second_run_into_the_same_folder_fails_at_once(tmp_path):
    out = tmp_path / "o"
    inside = threading.Event()
    release = threading.Event()

    def first():
        with atomic_output_dir(out, command="simulate") as tmp:
            (tmp / "a").write_text("1")
            inside.set()
            release.wait(30)

    t = threading.Thread(target=first)
    t.start()
    try:
        assert inside.wait(30)
        with pytest.raises(InputError, match=rf"being written by another render-inspect run "
                                             rf"\(process {os.getpid()}\)"):
            with atomic_output_dir(out, command="simulate"):
                pass
    finally:
        release.set()
        t.join()
    assert (out / "a").read_text() == "1"
    assert _leftovers(tmp_path) == []


def test_stale_temporary_folders_are_cleaned_and_a_lost_folder_restored(tmp_path):
    out = tmp_path / "o"
    with atomic_output_dir(out, command="simulate") as tmp:
        (tmp / "a").write_text("1")
    # what a killed run leaves: its temporary folder, and (killed during the swap) the
    # old folder renamed to a backup with nothing in its place
    (tmp_path / ".o.partial-999999-deadbeef").mkdir()
    (tmp_path / ".o.partial-999999-deadbeef" / "half.exr").write_text("half")
    os.rename(out, tmp_path / ".o.backup-999999-deadbeef")
    with atomic_output_dir(out, command="render", merge=True) as tmp:
        (tmp / "b").write_text("2")
    assert sorted(os.listdir(out)) == [MARKER, "a", "b"]
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("bad, why", [
    ("", "must name an output folder"),
    ("   ", "must name an output folder"),
    ("/dev/null", "not a folder"),
    ("/", "root folder"),
    ("/proc/render_inspect_test", "cannot write"),
    ("x" * 300, "too long"),
    ("a\x00b", "NUL"),
])
def test_bad_out_is_refused_before_any_work(tmp_path, monkeypatch, bad, why):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(InputError, match=why):
        check_output_path(bad)
    assert os.listdir(tmp_path) == []
    assert not any(n.startswith(".null") for n in os.listdir("/dev"))


def test_out_under_a_file_or_holding_the_current_folder_is_refused(tmp_path, monkeypatch):
    (tmp_path / "f").write_text("")
    with pytest.raises(InputError, match="lies under .* which is a file"):
        check_output_path(tmp_path / "f" / "sub")
    with pytest.raises(InputError, match="exists and is a file"):
        check_output_path(tmp_path / "f")
    (tmp_path / "d" / "e").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "d" / "e")
    for out in (".", "..", str(tmp_path / "d")):
        with pytest.raises(InputError, match="current folder"):
            check_output_path(out)
    long = tmp_path / ("n" * 240)
    with pytest.raises(InputError, match="too long"):
        check_output_path(long)


def test_read_only_file_system_is_refused(tmp_path):
    ro = Path("/sys/fs")
    if os.access(ro, os.W_OK):
        ro = Path("/proc/sys")
    with pytest.raises(InputError, match="--out"):
        with atomic_output_dir(ro / "render_inspect_out"):
            pass


# ------------------------------------------------------------------ the command line
def test_cli_refuses_bad_out_with_one_line_and_exit_1(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for bad in ["", "/dev/null", str(tmp_path / "f" / "x"), "/proc/x/y"]:
        (tmp_path / "f").write_text("")
        rc, err = _main(capsys, "simulate", "sts_sinusoidal_grid", "--out", bad)
        assert rc == 1 and "--out" in err and len(err.strip().splitlines()) == 1, err
    assert sorted(os.listdir(tmp_path)) == ["f"]


def test_cli_overwrite_and_refusal(tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / "metrics.json").write_text("mine")
    args = ["toolpath", "sts_sinusoidal_grid", "--out", out, *sum((["--set", s] for s in SMALL), [])]
    rc, err = _main(capsys, *args)
    assert rc == 1 and "--overwrite" in err and (out / "metrics.json").read_text() == "mine"
    rc, err = _main(capsys, *args, "--overwrite")
    assert rc == 0 and not (out / "metrics.json").exists() and (out / "toolpath.npz").exists()


@pytest.mark.slow
def test_outputs_are_byte_identical_between_runs(tmp_path):
    scene = load_scene("sts_sinusoidal_grid", SMALL)
    run_simulate(scene, tmp_path / "a")
    run_simulate(scene, tmp_path / "b")
    a, b = _tree(tmp_path / "a"), _tree(tmp_path / "b")
    assert MARKER in a and a.keys() == b.keys()
    assert {k: v for k, v in a.items() if k not in ("metrics.json", MARKER)} == \
        {k: v for k, v in b.items() if k not in ("metrics.json", MARKER)}
    # the marker differs only in the files' modification times it records
    ka, kb = (json.loads((tmp_path / d / MARKER).read_text()) for d in "ab")
    sizes = [{k: v[0] for k, v in m.pop("stat").items() if k != "metrics.json"} for m in (ka, kb)]
    assert sizes[0] == sizes[1] and "heightmap.exr" in sizes[0]
    assert ka == kb
    ma, mb = (json.loads((tmp_path / d / "metrics.json").read_text()) for d in "ab")
    ma.pop("timing_s"), mb.pop("timing_s")  # the seconds each step took
    assert ma == mb


def _cli_proc(*args):
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen([sys.executable, "-m", "render_inspect.cli", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)


def _wait_for(pred, timeout=60.0):
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout:
        if pred():
            return True
        time.sleep(0.05)
    return False


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143),
                                       (signal.SIGKILL, -9)])
@pytest.mark.parametrize("delay", [0.0, 1.5])
@pytest.mark.slow
def test_signals_leave_the_old_folder_and_no_partial(tmp_path, sig, code, delay):
    """An earlier run's folder survives a run interrupted at any point (the wait for the
    lock, planning, the numba kernels, writing): SIGINT and SIGTERM exit 130 / 143
    without a traceback and remove their temporary folder; after SIGKILL the next run
    removes it."""
    out = tmp_path / "o"
    run_simulate(load_scene("sts_sinusoidal_grid", SMALL), out)
    before = _tree(out)
    sets = sum((["--set", s] for s in SLOW + ["process.spindle_rpm=60"]), [])
    p = _cli_proc("simulate", "sts_sinusoidal_grid", "--out", out, *sets)
    assert _wait_for(lambda: any(".partial-" in n for n in os.listdir(tmp_path)))
    time.sleep(delay)
    p.send_signal(sig)
    _, err = p.communicate(timeout=120)
    if _tree(out) != before:
        # the signal came after the new folder was swapped in (a fast machine finishes
        # the run within the delay): then the new run is complete and the stop says so
        assert p.returncode in (0, code), err
        assert read_marker(out)["commands"]["simulate"] and (out / "heightmap.exr").exists()
        assert json.loads((out / "scene.json").read_text())["process"]["spindle_rpm"] == 60
        if p.returncode == code and sig != signal.SIGKILL:
            assert "written completely" in err or "run had finished" in err, err
        return
    assert p.returncode == code, err
    assert "Traceback" not in err and "SystemError" not in err
    assert _tree(out) == before
    if sig != signal.SIGKILL:
        assert _leftovers(tmp_path) == [], err
        assert "left as it was" in err
    else:  # the next run into the folder cleans up after the killed one
        run_simulate(load_scene("sts_sinusoidal_grid", SMALL), out)
        assert _leftovers(tmp_path) == []


@pytest.mark.slow
def test_a_concurrent_cli_run_fails_clearly(tmp_path, capsys):
    out = tmp_path / "o"
    sets = sum((["--set", s] for s in SLOW), [])
    p = _cli_proc("simulate", "sts_sinusoidal_grid", "--out", out, *sets)
    try:
        assert _wait_for(lambda: (tmp_path / ".o.lock").exists())
        rc, err = _main(capsys, "simulate", "sts_sinusoidal_grid", "--out", out,
                        *sum((["--set", s] for s in SMALL), []))
        assert rc == 1 and f"being written by another render-inspect run (process {p.pid})" in err
    finally:
        p.send_signal(signal.SIGTERM)
        p.communicate(timeout=120)


def test_interrupt_inside_a_compiled_kernel_is_an_interruption(capsys, monkeypatch, tmp_path):
    """Ctrl-C while numba runs surfaces as a SystemError whose context is the
    KeyboardInterrupt: the command line reports an interruption, exit 130."""
    from render_inspect import pipeline

    def kernel(*a, **k):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise SystemError("<numba function> returned a result with an exception set")

    monkeypatch.setattr(pipeline, "run_simulate", kernel)
    rc, err = _main(capsys, "simulate", "sts_sinusoidal_grid", "--out", tmp_path / "o")
    assert rc == 130 and "interrupted" in err and "SystemError" not in err


@pytest.mark.parametrize("signum, code, word", [(signal.SIGINT, 130, "interrupted"),
                                                (signal.SIGTERM, 143, "terminated")])
def test_an_error_native_code_makes_of_a_stop_is_the_stop(capsys, monkeypatch, tmp_path, signum,
                                                          code, word):
    """A signal's exception raised inside native code that calls back into Python can come
    out as that code's own error, the interruption dropped (matplotlib's C++ transforms:
    "Invalid affine transformation matrix"): once a stop was asked for, it is the stop."""
    from render_inspect import pipeline
    from render_inspect.core import cancel

    def drawing(*a, **k):
        cancel.request(signum)          # what the command line's handler records first
        raise ValueError("Invalid affine transformation matrix")

    monkeypatch.setattr(pipeline, "run_simulate", drawing)
    rc, err = _main(capsys, "simulate", "sts_sinusoidal_grid", "--out", tmp_path / "o")
    assert rc == code and word in err and "ValueError" not in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "o").exists()


def test_unexpected_errors_are_one_line_with_a_hint(capsys, monkeypatch, tmp_path):
    from render_inspect import pipeline

    def bug(*a, **k):
        return {}["missing"]

    monkeypatch.setattr(pipeline, "run_simulate", bug)
    rc, err = _main(capsys, "simulate", "sts_sinusoidal_grid", "--out", tmp_path / "o")
    assert rc == 1 and len(err.strip().splitlines()) == 1
    assert "internal error: KeyError" in err and "traceback" in err
    monkeypatch.setenv("RENDER_INSPECT_TRACEBACK", "1")
    cli.log.handlers.clear()
    rc = cli.main(["simulate", "sts_sinusoidal_grid", "--out", str(tmp_path / "o")])
    cli.log.handlers.clear()
    assert rc == 1 and "Traceback" in capsys.readouterr().err


@pytest.mark.slow
def test_marker_is_strict_json_and_lists_every_file(tmp_path):
    scene = load_scene("sts_sinusoidal_grid", SMALL)
    run_simulate(scene, tmp_path / "o")
    m = json.loads((tmp_path / "o" / MARKER).read_text())
    files = sorted(str(p.relative_to(tmp_path / "o")) for p in (tmp_path / "o").rglob("*")
                   if p.is_file() and p.name != MARKER)
    assert sorted(m["files"]) == files and set(m["files"].values()) == {"simulate"}
    assert m["written_by"] == "render_inspect" and len(m["commands"]["simulate"]["part_sha256"]) == 64


@pytest.mark.slow
def test_a_full_disk_while_writing_is_one_line_and_leaves_nothing(tmp_path):
    """The file-size limit makes every write beyond 64 kB fail inside the kernel (EFBIG,
    as a full disk gives ENOSPC): exit 1, one line naming --out, the old folder intact,
    no temporary folder left."""
    import resource

    out = tmp_path / "o"
    run_simulate(load_scene("sts_sinusoidal_grid", SMALL), out)
    before = _tree(out)

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (64 * 1024, 64 * 1024))

    sets = sum((["--set", s] for s in SMALL + ["process.spindle_rpm=60"]), [])
    r = subprocess.run([sys.executable, "-m", "render_inspect.cli", "simulate",
                        "sts_sinusoidal_grid", "--out", str(out), *sets],
                       capture_output=True, text=True, preexec_fn=limit, timeout=300)
    assert r.returncode == 1, r.stderr
    assert "Traceback" not in r.stderr and "Exception ignored" not in r.stderr
    errors = [line for line in r.stderr.splitlines() if "error" in line]
    assert len(errors) == 1 and "--out" in errors[0] and "nothing was written" in errors[0], r.stderr
    assert _tree(out) == before and _leftovers(tmp_path) == []


def test_no_space_left_is_reported_naming_out(tmp_path):
    import errno

    with pytest.raises(InputError, match=r"--out .*No space left on device while writing "
                                         r"heightmap.exr; nothing was written"):
        with atomic_output_dir(tmp_path / "o", command="simulate") as tmp:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp / "heightmap.exr"))
    assert os.listdir(tmp_path) == []


# ------------------------------------------------------------------ the other commands
@pytest.mark.slow
def test_every_command_that_writes_a_folder_refuses_a_users_folder(tmp_path, capsys):
    """analyze, measure, characterise, regress and sweep check --out before any work:
    a non-empty folder render_inspect did not write is refused and left as it was."""
    from render_inspect.io import write_x3p

    import numpy as np

    x3p = write_x3p(tmp_path / "m.x3p", np.zeros((8, 8)), pixel=0.001)
    runs = [["analyze", x3p], ["measure", tmp_path / "no_such_frames.exr"],
            ["characterise", "--objective", "20x", "--quick"],
            ["regress", "--only", "no_such_case"],
            ["sweep", "fig15_small"]]
    for argv in runs:
        out = tmp_path / f"mine_{argv[0]}"
        out.mkdir()
        (out / "notes.txt").write_text("my notes")
        rc, err = _main(capsys, *argv, "--out", out)
        assert rc == 1 and "--out" in err and "notes.txt" in err, (argv, err)
        assert sorted(os.listdir(out)) == ["notes.txt"], argv


def test_analyze_writes_a_marked_folder_and_replaces_it_whole(tmp_path, capsys):
    import numpy as np

    from render_inspect.io import write_x3p

    z = 1e-5 * np.random.default_rng(1).standard_normal((32, 32))
    x3p = write_x3p(tmp_path / "m.x3p", z, pixel=0.001)
    out = tmp_path / "a"
    assert _main(capsys, "analyze", x3p, "--out", out, "--x3p")[0] == 0
    assert read_marker(out)["files"]["height.x3p"] == "analyze"
    assert _main(capsys, "analyze", x3p, "--out", out)[0] == 0
    assert not (out / "height.x3p").exists()        # the earlier run's file is gone
    assert sorted(read_marker(out)["files"]) == ["height.png", "metrics.json"]


def test_a_sweep_folder_is_claimed_marked_and_resumable(tmp_path):
    from render_inspect.io import claim_output_dir

    out = tmp_path / "sweep"
    claim_output_dir(out, command="sweep")
    (out / "results.jsonl").write_text("")
    claim_output_dir(out, command="sweep")            # its own folder: resumed
    assert "sweep" in read_marker(out)["commands"]
    # another command may not replace the sweep's files
    with pytest.raises(InputError, match="did not write"):
        with atomic_output_dir(out, command="simulate"):
            pass
    # a sweep folder written before markers existed is recognised
    old = tmp_path / "old"
    old.mkdir()
    (old / "results.jsonl").write_text("")
    claim_output_dir(old, command="sweep", resumable=lambda p: (p / "results.jsonl").is_file())
    # a user's folder is refused; --overwrite writes beside the user's files
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("my notes")
    with pytest.raises(InputError, match="--overwrite"):
        claim_output_dir(mine, command="sweep")
    claim_output_dir(mine, command="sweep", overwrite=True)
    assert (mine / "notes.txt").read_text() == "my notes"
    # the sweep's folder is filled in place: it may hold the current folder
    claim_output_dir(tmp_path, command="sweep", overwrite=True)


def test_nested_outputs_and_stores_are_kept_as_units(tmp_path):
    """The add-on's layout: a root folder whose variant sub-folders are outputs of their
    own (renders are added to them) and a compare/ folder of another command; a Zarr
    store counts as one entry."""
    from render_inspect.io import write_marker

    root = tmp_path / "root"
    with atomic_output_dir(root, command="blender simulate", merge=True) as tmp:
        (tmp / "compensated").mkdir()
        (tmp / "compensated" / "heightmap.exr").write_text("c1")
        write_marker(tmp / "compensated", command="simulate")
        (tmp / "heightmap.zarr" / "machined" / "c").mkdir(parents=True)
        (tmp / "heightmap.zarr" / "machined" / "c" / "0").write_text("chunk")
    assert read_marker(root)["files"] == {"compensated/": "blender simulate",
                                          "heightmap.zarr/": "blender simulate"}
    # a render adds to the variant folder
    with atomic_output_dir(root / "compensated", command="render", merge=True) as tmp:
        (tmp / "cycles.png").write_text("png")
    assert sorted(os.listdir(root / "compensated")) == [MARKER, "cycles.png", "heightmap.exr"]
    # another command's output nested in the root is kept when the root is written again
    with atomic_output_dir(root / "compare", command="compare") as tmp:
        (tmp / "report.html").write_text("report")
    (root / ".compensated.lock").write_text("")       # a killed run's lock: not the user's
    with atomic_output_dir(root, command="blender simulate", merge=True) as tmp:
        (tmp / "compensated").mkdir()
        (tmp / "compensated" / "heightmap.exr").write_text("c2")
        write_marker(tmp / "compensated", command="simulate")
    assert (root / "compare" / "report.html").read_text() == "report"
    assert (root / "compensated" / "heightmap.exr").read_text() == "c2"
    assert not (root / "compensated" / "cycles.png").exists()
    assert not (root / "heightmap.zarr").exists()      # this command's own earlier output


# ------------------------------------------------------------------ hostile folders
def _write(out, name="a.txt", text="1", **kw):
    with atomic_output_dir(out, command="t", **kw) as tmp:
        (tmp / name).write_text(text)


def test_the_lock_file_is_never_written_through_a_link(tmp_path):
    """A planted ``.NAME.lock`` (a symbolic link, a hard link, a file with other content)
    is refused naming it; the file it points to is untouched."""
    victim = tmp_path / "victim.txt"
    victim.write_text("secret")
    lock = tmp_path / ".o.lock"
    for plant in (lambda: lock.symlink_to(victim), lambda: os.link(victim, lock),
                  lambda: lock.write_text("not a pid")):
        plant()
        with pytest.raises(InputError, match=r"--out .*\.o\.lock"):
            _write(tmp_path / "o")
        assert victim.read_text() == "secret" and not (tmp_path / "o").exists()
        lock.unlink()
    _write(tmp_path / "o")  # an ordinary run afterwards
    assert not lock.exists() and victim.read_text() == "secret"


def test_files_that_look_like_temporaries_are_the_users(tmp_path):
    """Only render_inspect's own temporaries, exactly named, are not counted: a user's
    ``.metrics.json.backup-1`` makes the folder refused, not deleted."""
    out = tmp_path / "o"
    _write(out)
    for name in (".metrics.json.backup-1", ".x.lock", ".a.txt.partial-1", ".a.tmp"):
        (out / name).write_text("mine")
        with pytest.raises(InputError, match=re.escape(name)):
            _write(out)
        assert (out / name).read_text() == "mine"
        (out / name).unlink()
    # what a killed run into a nested folder leaves is not the user's
    (out / ".sub.lock").write_text("123\n")
    (out / ".sub.partial-123-0123abcd").mkdir()
    (out / ".a.txt.abcd_123.tmp").write_text("half")
    _write(out, text="2")
    assert (out / "a.txt").read_text() == "2"


def test_a_users_file_in_a_nested_output_folder_is_not_deleted(tmp_path):
    out = tmp_path / "A"
    _write(out)
    _write(out / "sub", name="b.txt")
    _write(out, text="2")  # a nested output of render-inspect's own is fine
    _write(out / "sub", name="b.txt")
    (out / "sub" / "mine.txt").write_text("mine")
    with pytest.raises(InputError, match=r"sub/mine\.txt"):
        _write(out, text="3")
    assert (out / "sub" / "mine.txt").read_text() == "mine"


def test_a_refused_run_removes_no_sibling_folder(tmp_path):
    """Siblings named like a backup are removed only by a run that completes, and only
    when exactly so named."""
    out = tmp_path / "A"
    out.mkdir()
    (out / "user.txt").write_text("u")
    for name in (".A.backup-1", ".A.backup-123-0123abcd", ".A.partial-9-0123abcd"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "x").write_text("keep")
    with pytest.raises(InputError, match="not written by render-inspect"):
        _write(out)
    assert all((tmp_path / n / "x").exists() for n in (".A.backup-1", ".A.backup-123-0123abcd",
                                                       ".A.partial-9-0123abcd"))
    _write(tmp_path / "A2")
    _write(out, overwrite=True)
    assert (tmp_path / ".A.backup-1" / "x").exists()  # not one of render-inspect's names
    assert not (tmp_path / ".A.backup-123-0123abcd").exists()
    assert not (tmp_path / ".A.partial-9-0123abcd").exists()


def test_changed_files_and_forged_markers_are_not_trusted(tmp_path):
    """The marker vouches only for files unchanged since they were written (size and
    date), only when it belongs to this user and records them."""
    out = tmp_path / "o"
    _write(out)
    (out / "a.txt").write_text("edited by the user")
    with pytest.raises(InputError, match=r"changed since .*a\.txt"):
        _write(out)
    # a marker copied into (or written for) a folder of other files
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "a.txt").write_text("precious")
    shutil.copy(out / MARKER, mine / MARKER)
    with pytest.raises(InputError, match=r"a\.txt"):
        _write(mine)
    # a marker of an earlier layout (no sizes and dates) is not enough
    m = json.loads((mine / MARKER).read_text())
    m.pop("stat")
    m["marker_version"] = 1
    (mine / MARKER).write_text(json.dumps(m))
    with pytest.raises(InputError, match="earlier render-inspect version"):
        _write(mine)
    assert (mine / "a.txt").read_text() == "precious"


def test_overwrite_does_not_follow_a_link_and_inputs_are_kept(tmp_path):
    target = tmp_path / "precious"
    target.mkdir()
    (target / "data.txt").write_text("keep")
    link = tmp_path / "link"
    link.symlink_to(target)
    with pytest.raises(InputError, match="symbolic link.*--overwrite does not replace"):
        _write(link, overwrite=True)
    assert (target / "data.txt").read_text() == "keep"
    # an output folder that holds the command's input is refused, even with --overwrite
    out = tmp_path / "o"
    _write(out)
    with pytest.raises(InputError, match=r"holds the input .*a\.txt"):
        _write(out, overwrite=True, inputs=[out / "a.txt"])
    assert (out / "a.txt").read_text() == "1"


_SWAP_SIGNAL = """
import os, signal, sys
from render_inspect.io import _atomic
swap = _atomic._swap_in
def slow_swap(new, out, backup):
    os.kill(os.getpid(), getattr(signal, sys.argv[1]))  # arrives in the middle of the swap
    swap(new, out, backup)
_atomic._swap_in = slow_swap
from render_inspect import cli
sys.exit(cli.main(sys.argv[2:]))
"""


@pytest.mark.parametrize("sig, code", [("SIGINT", 130), ("SIGTERM", 143)])
@pytest.mark.slow
def test_a_signal_during_the_swap_is_held_and_reported_truthfully(tmp_path, sig, code):
    """The swap is completed, then the interruption is delivered: the exit code is 130 /
    143 and the message says the folder was written (it was), never "left as it was"."""
    out = tmp_path / "o"
    run_simulate(load_scene("sts_sinusoidal_grid", SMALL), out)
    old = read_marker(out)
    # the program kept small (120 points per revolution): the signal comes during the swap,
    # after the program is made, whatever its size
    r = subprocess.run([sys.executable, "-c", _SWAP_SIGNAL, sig, "toolpath", "sts_sinusoidal_grid",
                        "--set", "process.points_per_rev=120", "--out", str(out), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == code, r.stderr
    assert "Traceback" not in r.stderr and "left as it was" not in r.stderr
    assert f"the output folder {out} had been written completely" in r.stderr
    assert read_marker(out) != old and (out / "toolpath.npz").exists()
    assert _leftovers(tmp_path) == []


# ------------------------------------------------------------------ inputs in the folder
def test_the_scene_and_the_files_it_reads_are_never_deleted_with_the_folder(tmp_path, capsys,
                                                                            monkeypatch):
    """The scene file, a program given with --program, a height map design and a measured
    tool edge inside --out: refused in one line (exit 1), even with --overwrite, the file
    kept; the same from the Python API."""
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "o"
    rc, err = _main(capsys, "toolpath", "sts_sinusoidal_grid", "--out", out, "--format", "nc",
                    *(a for s in SMALL for a in ("--set", s)))
    assert rc == 0 and (out / "toolpath.nc").is_file()
    program = (out / "toolpath.nc").read_bytes()
    scene_text = find_scene("sts_sinusoidal_grid").read_text()
    (out / "my.toml").write_text(scene_text)
    sets = [a for s in SMALL for a in ("--set", s)]
    for argv in (["simulate", out / "my.toml", "--out", out, "--overwrite", *sets],
                 ["toolpath", out / "my.toml", "--out", out, "--overwrite", *sets],
                 ["fit", tmp_path / "m.csv", "--scene", out / "my.toml", "--free", "tool.nose_radius",
                  "--out", out, "--overwrite"],
                 # (no --overwrite needed to lose it: the folder is render_inspect's own)
                 ["simulate", "sts_sinusoidal_grid", "--program", out / "toolpath.nc", "--out", out,
                  *sets]):
        rc, err = _main(capsys, *argv)
        assert rc == 1 and "holds the input" in err and len(err.strip().splitlines()) == 1, err
    assert (out / "toolpath.nc").read_bytes() == program and (out / "my.toml").read_text() == scene_text
    # the files a scene reads, through the API: a height map design, a measured edge
    for key, value in (("design", {"type": "heightmap", "path": str(out / "toolpath.nc")}),
                       ("tool.edge_profile", str(out / "toolpath.nc"))):
        scene = load_scene("sts_sinusoidal_grid", SMALL)
        d = scene.to_dict()
        if key == "design":
            d["design"] = value
        else:
            d["tool"]["edge_profile"] = value
        assert str(out / "toolpath.nc") in scene_files(d)
        # (keys that only share a name, such as rcse.path = "rcse", are not files)
        assert scene_files(load_scene("rcse_circular_array")) == []
        with pytest.raises(InputError, match="holds the input"):
            with atomic_output_dir(out, overwrite=True, scene=d):
                pass
    assert (out / "toolpath.nc").read_bytes() == program


def test_a_file_given_with_vary_is_an_input_too(tmp_path, monkeypatch):
    """compare --vary process.program=A,B with A inside --out: refused, A kept."""
    from render_inspect.io import write_nc
    from render_inspect.pipeline import plan_program, run_compare

    monkeypatch.chdir(tmp_path)
    scene = load_scene("sts_sinusoidal_grid", SMALL)
    out = tmp_path / "o"
    out.mkdir()
    prog = write_nc(out / "p.nc", plan_program(scene).program)
    other = write_nc(tmp_path / "q.nc", plan_program(scene).program)
    kept = prog.read_bytes()
    with pytest.raises(InputError, match=r"holds the input .*p\.nc"):
        run_compare(scene, out, overwrite=True,
                    vary=f"process.program={json.dumps(str(prog))},{json.dumps(str(other))}")
    assert prog.read_bytes() == kept


def test_a_folder_named_after_a_shipped_scene_does_not_hide_it(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "sts_sinusoidal_grid").mkdir()
    rc, err = _main(capsys, "toolpath", "sts_sinusoidal_grid", "--out", tmp_path / "t",
                    *(a for s in SMALL for a in ("--set", s)))
    assert rc == 0, err
