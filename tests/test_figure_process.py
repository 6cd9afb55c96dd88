"""The figures of ``simulate`` drawn by a forked child process: the same files, byte for
byte, as drawn in the process itself; figures that arrive together drawn at once; a
figure's error raised in the parent; a child that ends early leaves its figures to the
parent, and one the parent ends leaves no figure being drawn."""

import os
import signal
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from render_inspect.core.limits import usable_cpus
from render_inspect.core.toolpath import ToolPath
from render_inspect.pipeline._figure_process import FigureProcess
from render_inspect.report import draw_figure, register_figure, residual_png

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not sys.platform.startswith("linux"), reason="fork: Linux only")]


def _specs():
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 60.0, 5001)
    fe = {"kind": "following_error", "t": t, "title": "following error",
          "errors": {"x": rng.normal(scale=3e-3, size=t.size), "z": rng.normal(scale=2e-3, size=t.size)},
          "stats": {"x_rms_nm": 3.0, "x_max_nm": 9.0, "z_rms_nm": 2.0, "z_max_nm": 7.0}}
    mp = {"kind": "map", "data": rng.normal(size=(40, 60)), "extent": (0.0, 0.6, 0.0, 0.4),
          "title": "a map", "label": "nm"}
    theta = np.linspace(0.0, 40 * np.pi, 20_001)
    path = ToolPath(theta, 0.5 - 0.01 * theta / (2 * np.pi), 2e-3 * np.cos(3 * theta), theta / 5.0)
    ax = {"kind": "axes", "columns": [("STS program", path, {})], "title": "the axes that move"}
    return {"following_error.png": fe, "map.png": mp, "kinematics.png": ax}


def _residual_args():
    img = np.random.default_rng(4).normal(scale=1e-6, size=(50, 50)).astype(np.float32)
    return img, 2, {"extent": [-0.5, 0.5, -0.5, 0.5], "mean_nm": 0.1, "title": "residual"}


def test_the_child_draws_the_same_files(tmp_path):
    here, there = tmp_path / "here", tmp_path / "there"
    here.mkdir()
    there.mkdir()
    img, factor, kw = _residual_args()
    for name, spec in _specs().items():
        draw_figure(spec, here / name)
    residual_png(here / "residual.png", img, factor, **kw)
    drawer = FigureProcess.start()
    assert drawer is not None
    try:
        for name, spec in _specs().items():
            drawer.draw(name, spec, there / name)
        drawer.residual("residual.png", there / "residual.png", img, factor, **kw)
        seen = []
        times = drawer.results(seen.append)
    finally:
        drawer.close()
    assert sorted(times) == sorted(seen) == ["following_error.png", "kinematics.png", "map.png", "residual.png"]
    for name in times:
        assert (here / name).read_bytes() == (there / name).read_bytes(), name


def test_a_figures_error_is_raised_in_the_parent(tmp_path):
    drawer = FigureProcess.start()
    assert drawer is not None
    try:
        drawer.draw("bad.png", {"kind": "no such kind"}, tmp_path / "bad.png")
        with pytest.raises(ValueError, match="unknown figure kind 'no such kind'"):
            drawer.results()
    finally:
        drawer.close()


@register_figure("slow_probe")
def _slow_probe(spec, png):
    # (a figure that takes a while: says it started, then, a second later, that it ended)
    Path(spec["started"]).write_text(str(os.getpid()))
    time.sleep(1.0)
    Path(png).write_text("drawn")
    return Path(png)


def _wait_for(path, seconds=60.0):
    t0 = time.monotonic()
    while not path.exists():
        assert time.monotonic() - t0 < seconds, f"{path} never appeared"
        time.sleep(0.02)


def test_figures_that_arrive_together_are_drawn_at_once(tmp_path):
    # (by two copies of the child: the second starts before the first has ended)
    if usable_cpus() < 2:
        pytest.skip("one usable core: the child draws one figure after the other")
    drawer = FigureProcess.start()
    assert drawer is not None
    try:
        for k in (1, 2):
            drawer.draw(f"f{k}.png", {"kind": "slow_probe", "started": str(tmp_path / f"s{k}")},
                        tmp_path / f"f{k}.png")
        _wait_for(tmp_path / "s2")
        assert not (tmp_path / "f1.png").exists()
        pids = {(tmp_path / f"s{k}").read_text() for k in (1, 2)}
        assert len(pids) == 2 and str(drawer.pid) not in pids
        assert sorted(drawer.results()) == ["f1.png", "f2.png"]
    finally:
        drawer.close()


def test_closing_the_child_ends_the_figures_it_is_drawing(tmp_path):
    # (a command that stops ends its figure process at once: no copy goes on to write
    # into the output folder)
    drawer = FigureProcess.start()
    assert drawer is not None
    try:
        drawer.draw("f.png", {"kind": "slow_probe", "started": str(tmp_path / "s")},
                    tmp_path / "f.png")
        _wait_for(tmp_path / "s")
    finally:
        drawer.close()
    time.sleep(2.0)
    assert not (tmp_path / "f.png").exists()


def test_a_child_that_ended_leaves_its_figures_to_the_parent(tmp_path):
    drawer = FigureProcess.start()
    assert drawer is not None
    try:
        os.kill(drawer.pid, signal.SIGKILL)
        for name, spec in _specs().items():
            drawer.draw(name, spec, tmp_path / name)
        times = drawer.results()
    finally:
        drawer.close()
    assert sorted(times) == ["following_error.png", "kinematics.png", "map.png"]
    for name, spec in _specs().items():
        draw_figure(spec, tmp_path / f"ref_{name}")
        assert (tmp_path / name).read_bytes() == (tmp_path / f"ref_{name}").read_bytes()


#: in a fresh process (numba not yet imported, the kernels not yet made): figure kinds
#: that record what the child had loaded when the job arrived, and after drawing the
#: axis-motion figure of a planned program (also drawn in this process)
_PROBE = """
import json, sys
from pathlib import Path
from render_inspect.core.lazy import LazyDispatcher
from render_inspect.design import make_surface
from render_inspect.pipeline._figure_process import FigureProcess
from render_inspect.processes import process_of
from render_inspect.report import draw_figure, register_figure
from render_inspect.scene import load_scene

def loaded():
    return {"matplotlib.pyplot": "matplotlib.pyplot" in sys.modules, "numba": "numba" in sys.modules}

@register_figure("probe_loaded")
def probe(spec, png):
    Path(png).write_text(json.dumps(loaded()))
    return Path(png)

@register_figure("probe_kinematics")
def probe_kinematics(spec, png):
    draw_figure(spec["figure"], Path(png).with_suffix(".png"))
    Path(png).write_text(json.dumps(loaded()))
    return Path(png)

out = Path(sys.argv[1])
assert "numba" not in sys.modules and "matplotlib" not in sys.modules
drawer = FigureProcess.start()
try:
    # a figure drawn with Pillow first: the child does not import matplotlib for it
    import numpy as np, time
    t = np.linspace(0.0, 1.0, 5000)
    drawer.draw("pillow", {"kind": "following_error", "t": t, "errors": {"x": np.sin(40 * t) * 1e-6}},
                out / "pillow.png")
    for _ in range(3000):
        if (out / "pillow.png").exists():
            break
        time.sleep(0.01)
    time.sleep(0.2)
    maps = Path(f"/proc/{drawer.pid}/maps").read_text()
    pillow_only = {"drawn": (out / "pillow.png").exists(), "matplotlib": "matplotlib" in maps}
    drawer.draw("first", {"kind": "probe_loaded"}, out / "first.json")
    from render_inspect.toolpath import _kinematics
    parent = [not isinstance(getattr(_kinematics, k), LazyDispatcher) for k in ("_gradient", "_second")]
    scene = load_scene("sts_sinusoidal_grid", ["simulation.region=[0.2, 0.2, 0.3, 0.3]"])
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    plan = process.plan_window(cfg, make_surface(scene.design), tuple(scene.simulation.region))
    spec = plan.plots["kinematics.png"]
    drawer.draw("kinematics", {"kind": "probe_kinematics", "figure": spec}, out / "child.json")
    drawer.results()
finally:
    drawer.close()
draw_figure(spec, out / "here.png")
print(json.dumps({"parent_kernels": parent, "pillow_only": pillow_only}))
"""


def test_the_child_draws_without_numba_and_the_parent_starts_it(tmp_path):
    # (the child imports matplotlib only for a figure that needs it, never numba; the
    # axis-motion figure is drawn from the derivatives the plan took, the same bytes as
    # drawn here)
    import json
    import subprocess

    repo = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=str(repo) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               MPLBACKEND="Agg")
    r = subprocess.run([sys.executable, "-c", _PROBE, str(tmp_path)], capture_output=True,
                       text=True, timeout=300, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1]) == {
        "parent_kernels": [True, True], "pillow_only": {"drawn": True, "matplotlib": False}}
    for probe in ("first", "child"):
        assert json.loads((tmp_path / f"{probe}.json").read_text()) == {
            "matplotlib.pyplot": True, "numba": False}, probe
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_the_following_error_figures_are_handed_over_before_the_cut_ends(monkeypatch):
    """The command's figure process is sent the following error against time once the
    machine has followed the program, and its map once the passes are known, each
    before the cut's end, and every figure exactly once."""
    from render_inspect.pipeline import simulate
    from render_inspect.processes import _mechanics
    from render_inspect.scene import load_scene

    scene = load_scene("sts_sinusoidal_grid", ["simulation.region=[0.2, 0.2, 0.3, 0.3]"])
    events: list = []
    turn = _mechanics.turn

    def traced_turn(*args, **kwargs):
        out = turn(*args, **kwargs)
        events.append("cut ends")
        return out

    monkeypatch.setattr("render_inspect.processes._turning.turn", traced_turn)
    sim = simulate(scene, figures=lambda plots: events.append(sorted(plots)))
    assert events.index(["following_error.png"]) < events.index(["following_error_map.png"]) \
        < events.index("cut ends"), events
    sent = [name for e in events if e != "cut ends" for name in e]
    assert sorted(sent) == sorted(sim.figures) and len(set(sent)) == len(sent), events
