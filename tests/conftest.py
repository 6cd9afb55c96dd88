"""Test configuration: engines write into HOME, so point HOME and the caches at a
temporary folder before anything imports bpy, mitsuba, drjit or matplotlib."""

from __future__ import annotations

import atexit
import multiprocessing.process
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

_HOME = Path(tempfile.mkdtemp(prefix="render_inspect_test_home_"))
# the user's own HOME, for caches that should outlive a test run (pip's wheel cache)
os.environ.setdefault("RENDER_INSPECT_REAL_HOME", os.environ.get("HOME", str(_HOME)))
for _var in ("HOME", "XDG_CACHE_HOME", "BLENDER_USER_RESOURCES", "MPLCONFIGDIR"):
    os.environ[_var] = str(_HOME / _var.lower())
    Path(os.environ[_var]).mkdir(parents=True, exist_ok=True)
os.environ.setdefault("MPLBACKEND", "Agg")
# Dr.Jit's compiled kernels: one folder for the whole run, shared by the workers of `-n N`
# (each inherits the first process's environment) and the commands the tests start, so a
# renderer's kernel is compiled once per run, not once per worker.  Dr.Jit writes a kernel
# to a file of its own and links it in under its hash, so processes can share the folder.
_DRJIT_CACHE = os.environ.get("RENDER_INSPECT_TEST_DRJIT_CACHE") or str(_HOME / "drjit")
os.environ["RENDER_INSPECT_TEST_DRJIT_CACHE"] = os.environ["DRJIT_CACHE_DIR"] = _DRJIT_CACHE
Path(_DRJIT_CACHE).mkdir(parents=True, exist_ok=True)
# the temporary HOME goes when the process that made it ends (the workers end first)
atexit.register(shutil.rmtree, _HOME, ignore_errors=True)
# numba's parallel kernels run on OpenMP threads, and GNU OpenMP's idle threads spin for a
# while after each parallel loop before they sleep.  Under `make test` two workers share the
# cores, so a spinning thread burns the CPU the other worker's test needs: here they sleep
# at once (set before numba loads OpenMP; it changes how threads wait, not what they compute).
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

import pytest  # noqa: E402

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "scenes"


@pytest.fixture
def scenes_dir() -> Path:
    return SCENES


#: a scene small enough for command-line tests (0.2 x 0.2 mm at 2 um, tiny renders)
TINY_SCENE = """
name = "{name}"
[design]
type = "sinusoidal_grid"
amplitude_x = 0.001
amplitude_y = 0.001
wavelength_x = 0.5
wavelength_y = 0.5
[tool]
nose_radius = 0.5
[process]
kind = "sts"
spindle_rpm = 50
feed_mm_per_min = 1
workpiece_radius = 0.5
points_per_rev = 360
[simulation]
region = [-0.1, -0.1, 0.1, 0.1]
pixel = 0.002
[render.interferometer]
pixel = 0.004
[render.diffuse]
resolution = 32
spp = 2
"""


@pytest.fixture
def tiny_scene(tmp_path) -> Path:
    """A tiny scene file (:data:`TINY_SCENE`) in the test's folder."""
    p = tmp_path / "tiny.toml"
    p.write_text(TINY_SCENE.format(name="tiny"))
    return p


@pytest.fixture(scope="session")
def chromium() -> str:
    """The headless Chromium the report checks open pages in (``make setup`` installs it)."""
    for exe in ("chromium", "chromium-browser", "google-chrome", "chrome"):
        path = shutil.which(exe)
        if path:
            return path
    pytest.fail("headless Chromium is needed for the report check: run `make setup` as root "
                "(apt-get install chromium)")


# ------------------------------------------------------------------------ real data
#: The real instrument files and turned parts the tests read (../shared/realdata beside
#: the repository, or where RENDER_INSPECT_REALDATA names; see its SOURCES.md).
REALDATA = Path(os.environ.get("RENDER_INSPECT_REALDATA", REPO.parent / "shared" / "realdata"))


def run_main(capsys, *argv) -> tuple[int, str]:
    """``render-inspect ARGV`` run in this process: (its exit code, what it wrote to stderr);
    the command's log handlers are cleared around it."""
    from render_inspect import cli

    cli.log.handlers.clear()
    try:
        rc = cli.main([str(a) for a in argv])
    finally:
        cli.log.handlers.clear()
    return rc, capsys.readouterr().err


def real_file(*parts: str) -> Path:
    """The path of a real file under ``../shared/realdata``: the test is skipped, with the
    reason, when the whole folder is absent (a checkout without it), and fails when the
    folder is there but the file is not (a file the tests expect went missing)."""
    if not REALDATA.is_dir():
        pytest.skip(f"the real instrument files are not beside this checkout ({REALDATA} "
                    "is absent)")
    p = REALDATA.joinpath(*parts)
    if not p.is_file():
        pytest.fail(f"real instrument file missing: {p} (the tests read ../shared/realdata)")
    return p


# ------------------------------------------------------------------------ worker groups
#: fixture scopes that outlive a test: a test module's fixture of these scopes is made once
#: per worker that runs a test of it
_SHARED_SCOPES = ("module", "package", "session")


def _group_by_shared_fixtures(items) -> None:
    """A test that uses a module fixture of its own file (a simulated scene, a measured
    truth, a build) and names no ``xdist_group`` joins the group of that fixture, so that
    ``--dist loadgroup`` runs all its users on one worker and the fixture is made once per
    run, not once per worker."""
    for item in items:
        info = getattr(item, "_fixtureinfo", None)
        if info is None or item.get_closest_marker("xdist_group"):
            continue
        module = item.nodeid.split("::")[0]
        shared = sorted(name for name in item.fixturenames
                        for fd in info.name2fixturedefs.get(name, ())[-1:]
                        if fd.scope in _SHARED_SCOPES and fd.baseid == module)
        if shared:
            item.add_marker(pytest.mark.xdist_group(f"{Path(module).stem}.{'+'.join(shared)}"))


def _write_groups_into_ids(config, items) -> None:
    """The scheduler of ``--dist loadgroup`` reads a test's group from its id,
    ``...::test[param]@group``, which pytest-xdist writes into ``item._nodeid``; pytest 9.2
    keeps the id in ``item._id`` and ignores ``_nodeid``, so every group was split across
    the workers.  Write the suffix where pytest-xdist could not."""
    if not getattr(config.option, "loadgroup", False):  # set on the workers of -n N
        return
    try:
        from _pytest.nodeid import NodeId
    except ImportError:  # pytest before 9.2: pytest-xdist's own suffix works
        return
    for item in items:
        groups = sorted({str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                         for m in item.iter_markers("xdist_group")})
        if not groups or item.nodeid.rfind("@") > item.nodeid.rfind("]"):
            continue
        old = item._id
        new = NodeId(path=old.path, names=old.names, params=old.params)
        object.__setattr__(new, "_str_cache", f"{item.nodeid}@{'_'.join(groups)}")
        item._id = new


def _heavy_work_first(config, items) -> None:
    """Under ``--dist loadgroup`` the scheduler hands out its work units (a group, or one
    test) by their number of tests, most first (so the groups, then the single tests in
    the order they are collected); a worker takes the next unit when it is nearly idle.
    A minutes-long single test collected late (the files run in alphabetical order) leaves
    the other worker idle at the end of the run, so the single tests that carry a heavy
    mark are collected first and the light ones fill the workers' last minutes.  The tests
    of a group keep their order (a module fixture's parameters stay together).  Only on
    the workers of ``-n N``: a run in one process keeps the order of the files."""
    if not getattr(config.option, "loadgroup", False):
        return

    def heavy_single(item) -> bool:
        return (item.get_closest_marker("xdist_group") is None
                and any(item.get_closest_marker(m) for m in HEAVY_MARKS))

    first = [i for i in items if heavy_single(i)]
    if first:
        items[:] = first + [i for i in items if not heavy_single(i)]


def pytest_configure(config):
    # pytest-xdist's mark, known also where pytest-xdist is not loaded (-p no:xdist)
    config.addinivalue_line("markers", "xdist_group(name): the tests of one group run on one "
                            "worker under --dist loadgroup")
    _write_the_package_bytecode()
    _import_libraries_that_start_processes()


def _write_the_package_bytecode() -> None:
    """Write the package's bytecode (``__pycache__``) before any test runs, in the first
    process of the run only: where PYTHONDONTWRITEBYTECODE is set (many CI images set it)
    no process writes it, and every command the tests start would compile the package's
    sources again (0.4-0.9 CPU-s a start; the suite starts hundreds).  Files whose
    bytecode is up to date are left alone."""
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    import compileall

    compileall.compile_dir(str(REPO / "render_inspect"), quiet=1)


def _import_libraries_that_start_processes() -> None:
    """Import, before any test, the measured-file library whose own import starts processes
    (its version from ``git describe``, ``platform``'s ``uname -p``): otherwise the process
    rule below would pin them on whichever test of a run first reads a measured file."""
    try:
        import SurfaceTopography.IO  # noqa: F401
    except ImportError:  # an environment without it: the readers' tests say so
        pass


@pytest.hookimpl(wrapper=True)
def pytest_collection_modifyitems(config, items):
    """The tests of one ``xdist_group`` run on one worker under ``--dist loadgroup`` (``make
    test``): the groups the files name, and one per module fixture (tests/test_workers.py
    checks both on a small suite)."""
    _group_by_shared_fixtures(items)
    result = yield
    _heavy_work_first(config, items)
    _write_groups_into_ids(config, items)
    return result


# ------------------------------------------------------------------------ test tiers
# ``make test-quick`` runs what carries none of HEAVY_MARKS; a test that does heavy work
# must carry one.  Heavy work, found as it happens (not by timing, which depends on the
# machine): starting a process (subprocess, fork, spawn: every CLI run in a subprocess,
# every Dask cluster), simulating more than SMALL_MAP samples, importing or running
# Mitsuba.
HEAVY_MARKS = ("slow", "mitsuba", "blender", "browser", "gpu")
SMALL_MAP = 200_000
_CURRENT = {"light": False, "nodeid": "", "violation": None}


def _heavy_work(what: str, *, stop: bool = False) -> None:
    """Record heavy work in a test without a heavy mark; the test fails when it ends.  A
    process start is only recorded (raising inside a process pool or a Dask cluster's
    start-up would leave it waiting for its worker); ``stop`` fails the test at once."""
    if _CURRENT["light"]:
        _CURRENT["light"] = False  # one report per test
        _CURRENT["violation"] = (f"{_CURRENT['nodeid']} {what}: mark it @pytest.mark.slow (or "
                                 f"another of {', '.join(HEAVY_MARKS)}) so that `make "
                                 "test-quick` leaves it out")
        if stop:
            pytest.fail(_CURRENT["violation"], pytrace=False)


#: processes libraries start once for themselves, whichever test comes first (matplotlib
#: lists the system's fonts when it builds its font cache; a store library asks lscpu for the
#: processor once)
_LIBRARY_PROBES = ("fc-list", "lscpu")


def _audit(event: str, args) -> None:
    if _CURRENT["light"] and event in ("subprocess.Popen", "os.fork", "os.forkpty",
                                       "os.posix_spawn", "os.spawn", "os.exec"):
        exe = str(args[0]) if event == "subprocess.Popen" and args else ""
        if os.path.basename(exe) in _LIBRARY_PROBES:
            return
        _heavy_work(f"starts a process ({event}: {str(args)[:120]})")


sys.addaudithook(_audit)


@pytest.fixture(autouse=True)
def _heavy_work_needs_a_mark(request, monkeypatch):
    light = not any(request.node.get_closest_marker(m) for m in HEAVY_MARKS)
    had_mitsuba = "mitsuba" in sys.modules
    if light:
        from render_inspect.pipeline import _simulate

        real = _simulate.process_of

        def process_of(scene):
            ny, nx = scene.simulation.shape
            if ny * nx > SMALL_MAP:
                _heavy_work(f"simulates {ny} x {nx} = {ny * nx:,} samples (more than "
                            f"{SMALL_MAP:,})", stop=True)
            return real(scene)

        monkeypatch.setattr(_simulate, "process_of", process_of)
        start = multiprocessing.process.BaseProcess.start

        def start_process(self):
            _heavy_work(f"starts a process ({type(self).__name__})")
            return start(self)

        monkeypatch.setattr(multiprocessing.process.BaseProcess, "start", start_process)
    _CURRENT.update(light=light, nodeid=request.node.nodeid, violation=None)
    try:
        yield
    finally:
        still_light, violation = _CURRENT["light"], _CURRENT["violation"]
        _CURRENT.update(light=False, nodeid="", violation=None)
    if violation:  # also when the code under test caught the first report
        pytest.fail(violation, pytrace=False)
    if still_light and not had_mitsuba and "mitsuba" in sys.modules:
        pytest.fail(f"{request.node.nodeid} imports Mitsuba (renders): mark it "
                    "@pytest.mark.mitsuba", pytrace=False)


# ------------------------------------------------------------------------ quick tier's CPU
# A test without a heavy mark must also be quick: more than QUICK_CPU_S seconds of CPU in
# its set-up or in its call fails it, with the mark to add.  CPU time of the whole process
# (all its threads), not wall time, so that a loaded machine does not fail a test; numba's
# compilations are left out (a fresh checkout compiles the kernels in whichever test needs
# them first), and so is a traced run (coverage, a debugger), which is slower by its nature.
# In a run that keeps the slow tests (`make test`, CI) the limit is FULL_RUN_FACTOR times
# larger: a slower machine must not fail the whole suite on a test near the limit, while a
# heavy unmarked test still fails there.
#: RENDER_INSPECT_QUICK_CPU_S sets the limit for every run; 0 turns the check off
QUICK_CPU_S = float(os.environ.get("RENDER_INSPECT_QUICK_CPU_S", "6"))
FULL_RUN_FACTOR = 1.0 if "RENDER_INSPECT_QUICK_CPU_S" in os.environ else 3.0
_COMPILED = {"cpu_s": 0.0}
_PHASE_CPU = pytest.StashKey[dict]()


def _count_numba_compilations() -> None:
    """Add the CPU time of numba's compilations (outermost ones) to ``_COMPILED``."""
    try:
        from numba.core import event
    except ImportError:
        return

    class Compilations(event.Listener):
        depth, start = 0, 0.0

        def on_start(self, ev):
            if self.depth == 0:
                self.start = time.process_time()
            self.depth += 1

        def on_end(self, ev):
            self.depth -= 1
            if self.depth == 0:
                _COMPILED["cpu_s"] += time.process_time() - self.start

    event.register("numba:compile", Compilations())


_count_numba_compilations()


def _cpu_of_phase(item, when):
    start, compiled = time.process_time(), _COMPILED["cpu_s"]
    try:
        return (yield)
    finally:
        item.stash.setdefault(_PHASE_CPU, {})[when] = (
            time.process_time() - start - (_COMPILED["cpu_s"] - compiled))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item):
    return (yield from _cpu_of_phase(item, "setup"))


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    return (yield from _cpu_of_phase(item, "call"))


def _cpu_limit(config) -> float:
    """QUICK_CPU_S in a run that leaves the slow tests out, FULL_RUN_FACTOR times it
    otherwise."""
    quick = "not slow" in " ".join((config.getoption("markexpr") or "").split())
    return QUICK_CPU_S if quick else QUICK_CPU_S * FULL_RUN_FACTOR


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item, call):
    report = yield
    if (call.when != "call" or not report.passed or QUICK_CPU_S <= 0
            or sys.gettrace() is not None
            or any(item.get_closest_marker(m) for m in HEAVY_MARKS)):
        return report
    limit = _cpu_limit(item.config)
    spent = item.stash.get(_PHASE_CPU, {})
    over = [f"{spent[w]:.1f} s of CPU in its {w}" for w in ("setup", "call")
            if spent.get(w, 0.0) > limit]
    if over:
        report.outcome = "failed"
        report.longrepr = (f"{item.nodeid} took {' and '.join(over)} (more than "
                           f"{limit:g} s): mark it @pytest.mark.slow (or another of "
                           f"{', '.join(HEAVY_MARKS)}) so that `make test-quick` leaves it "
                           "out, or make it cheaper")
    return report
