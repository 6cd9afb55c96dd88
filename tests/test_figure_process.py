"""The figures of ``simulate`` drawn by a forked child process: the same files, byte for
byte, as drawn in the process itself; a figure's error raised in the parent; a child that
ends early leaves its figures to the parent."""

import os
import signal
import sys

import numpy as np
import pytest

from render_inspect.pipeline._figure_process import FigureProcess
from render_inspect.report import draw_figure, residual_png

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
    return {"following_error.png": fe, "map.png": mp}


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
    assert sorted(times) == sorted(seen) == ["following_error.png", "map.png", "residual.png"]
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
    assert sorted(times) == ["following_error.png", "map.png"]
    for name, spec in _specs().items():
        draw_figure(spec, tmp_path / f"ref_{name}")
        assert (tmp_path / name).read_bytes() == (tmp_path / f"ref_{name}").read_bytes()


#: in a fresh process (numba not yet imported, the kernels not yet made): a figure kind
#: that records what the child had loaded when its first job arrived
_PROBE = """
import json, sys
from pathlib import Path
from render_inspect.core.lazy import LazyDispatcher
from render_inspect.pipeline._figure_process import FigureProcess
from render_inspect.report import register_figure

@register_figure("probe_loaded")
def probe(spec, png):
    from render_inspect.toolpath import _kinematics
    Path(png).write_text(json.dumps({
        "matplotlib.pyplot": "matplotlib.pyplot" in sys.modules,
        "numba": "numba" in sys.modules,
        "kernels": [not isinstance(getattr(_kinematics, k), LazyDispatcher)
                    for k in ("_gradient", "_second")]}))
    return Path(png)

assert "numba" not in sys.modules and "matplotlib" not in sys.modules
drawer = FigureProcess.start()
try:
    drawer.draw("probe", {"kind": "probe_loaded"}, Path(sys.argv[1]))
    drawer.results()
finally:
    drawer.close()
from render_inspect.toolpath import _kinematics
print(json.dumps({"parent_kernels": [not isinstance(getattr(_kinematics, k), LazyDispatcher)
                                     for k in ("_gradient", "_second")]}))
"""


def test_the_child_loads_the_figures_library_and_kernels_before_its_first_figure(tmp_path):
    # (the axis-motion figure's derivatives are compiled kernels: loaded before the fork,
    # which the parent's planning needs too, not when that figure is drawn)
    import json
    import subprocess
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=str(repo) + os.pathsep + os.environ.get("PYTHONPATH", ""),
               MPLBACKEND="Agg")
    out = tmp_path / "probe.json"
    r = subprocess.run([sys.executable, "-c", _PROBE, str(out)], capture_output=True, text=True,
                       timeout=300, env=env, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout.strip().splitlines()[-1]) == {"parent_kernels": [True, True]}
    assert json.loads(out.read_text()) == {"matplotlib.pyplot": True, "numba": True,
                                           "kernels": [True, True]}
