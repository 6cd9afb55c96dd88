"""docs/contributing.md's examples are tests: the package is copied, each example is
written into it as the one new file the page says, exactly as printed there, and the
commands the page names run on it in a fresh interpreter (a new design type, a new
process kind through ``simulate``, ``toolpath`` and ``compare``, a new instrument through
``render --kind``, a new objective preset through the scene and ``--objective``, a new
program format through ``toolpath --format``, a new reader of
measured files through ``analyze``, a new figure kind through ``draw_figure``)."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
PKG = REPO / "render_inspect"
DOC = REPO / "docs" / "contributing.md"

#: a small saddle, cut by STS on the ideal machine
SADDLE_SCENE = """
name = "saddle"
[design]
type = "saddle"
radius = 200.0
[process]
kind = "sts"
workpiece_radius = 0.5
spindle_rpm = 50
feed_mm_per_min = 1
points_per_rev = 360
[simulation]
region = [0.1, 0.1, 0.14, 0.14]
pixel = 0.002
"""

#: constant-surface-speed turning of a sinusoidal grid on a lathe with servo dynamics,
#: with small renders for compare
CSS_SCENE = """
name = "css"
[design]
type = "sinusoidal_grid"
amplitude_x = 0.001
amplitude_y = 0.001
wavelength_x = 0.5
wavelength_y = 0.5
[tool]
nose_radius = 0.5
[process]
kind = "css"
cutting_speed_mm_s = 5.0
spindle_rpm = 3000
feed_mm_per_min = 60
workpiece_radius = 0.5
points_per_rev = 360
[simulation]
region = [0.1, -0.05, 0.2, 0.05]
pixel = 0.002
[machine]
preset = "sts_lathe"
[render.interferometer]
pixel = 0.004
[render.diffuse]
resolution = 32
spp = 2
"""


#: the least a process kind is: a schema class and the three required hooks (no
#: compensation, no feed, no traits): simulate must run it
BARE_PROCESS = '''
from typing import Literal

import numpy as np

from ..core.section import Section
from ..core.toolpath import LinearProgram
from ..core.units import NM_TO_MM
from ..machining import design_grid
from ._contract import Cut, Plan, Process
from ._registry import register_process


class BareConfig(Section):
    kind: Literal["bare"]


class Bare(Process):
    config = BareConfig

    def plan(self, cfg, surface, *, region=None):
        x = np.array([0.0, 1.0])
        return Plan(LinearProgram(x, 0 * x, 0 * x, x, np.zeros(2, dtype=np.int64)))

    def cut(self, cfg, surface, plan):
        design = design_grid(surface, cfg.simulation.region, cfg.simulation.pixel)
        return Cut(design + NM_TO_MM, design)

    def estimate_memory(self, cfg, plan=None):
        return 0


register_process(Bare())
'''


def examples() -> dict[str, str]:
    """Relative path -> code of every "Create `render_inspect/...py`:" example."""
    text = DOC.read_text()
    found = re.findall(r"Create\s+`(render_inspect/[\w/]+\.py)`:\n```python\n(.*?)```", text,
                       re.S)
    return dict(found)


@pytest.fixture(scope="module")
def package(tmp_path_factory) -> Path:
    """A copy of the package with every example of the page added as its own file.  Its
    ``__pycache__`` folders come along with the sources' times (``copy2``): numba's cache of
    the package's own kernels, and Python's, hold for the copy as for the checkout, so the
    commands compile only what the examples add."""
    root = tmp_path_factory.mktemp("contributing")
    shutil.copytree(PKG, root / "render_inspect", copy_function=shutil.copy2)
    for rel, code in {**examples(), "render_inspect/processes/_bare.py": BARE_PROCESS}.items():
        target = root / rel
        assert not target.exists(), f"{rel}: the example must be a new file"
        target.write_text(code)
    return root


def _run(package: Path, *args, cwd: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(package)
    return subprocess.run([sys.executable, "-m", "render_inspect.cli", *args, "-q"],
                          capture_output=True, text=True, cwd=cwd, env=env)


def test_the_page_has_the_seven_examples():
    assert sorted(examples()) == ["render_inspect/design/_saddle.py",
                                  "render_inspect/instruments/_objective_40x.py",
                                  "render_inspect/instruments/_stylus.py",
                                  "render_inspect/io/_asc.py",
                                  "render_inspect/io/_xyz.py",
                                  "render_inspect/processes/_css.py",
                                  "render_inspect/report/_histogram.py"]


@pytest.mark.slow
def test_a_new_design_type_is_one_file(package, tmp_path):
    (tmp_path / "s.toml").write_text(SADDLE_SCENE)
    r = _run(package, "simulate", str(tmp_path / "s.toml"), "--out", str(tmp_path / "o"),
             cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["scene_name"] == "saddle" and m["residual"]["Sq_nm"] > 0


@pytest.mark.slow
def test_a_process_needs_only_its_three_hooks(package, tmp_path):
    """No compensation key, no feed, no traits: the chain asks nothing else of it."""
    scene = SADDLE_SCENE.replace('kind = "sts"', 'kind = "bare"').replace(
        "workpiece_radius = 0.5\nspindle_rpm = 50\nfeed_mm_per_min = 1\npoints_per_rev = 360\n", "")
    (tmp_path / "b.toml").write_text(scene)
    r = _run(package, "simulate", str(tmp_path / "b.toml"), "--out", str(tmp_path / "o"),
             cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["process"] == "bare" and m["compensation"] == "none"
    assert m["residual"]["mean_nm"] == pytest.approx(1.0) and m["toolpath"]["points"] == 2
    assert not (tmp_path / "o" / "toolpath.npz").exists()


@pytest.mark.mitsuba
@pytest.mark.slow
def test_a_new_process_kind_is_one_file(package, tmp_path):
    """The constant-surface-speed process: simulate, toolpath and compare end to end."""
    scene = tmp_path / "css.toml"
    scene.write_text(CSS_SCENE)
    r = _run(package, "simulate", str(scene), "--out", str(tmp_path / "sim"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "sim" / "metrics.json").read_text())
    assert m["process"] == "css" and m["compensation"] == "z" and m["residual"]["Sq_nm"] > 0
    assert m["machine"]["preset"] == "sts_lathe" and m["following_error"]["x_max_nm"] > 0
    # the program keeps the cutting speed: rho * dtheta / dt = 5 mm/s where the cap allows
    r = _run(package, "toolpath", str(scene), "--out", str(tmp_path / "tp"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    tp = np.load(tmp_path / "tp" / "toolpath.npz")
    speed = tp["rho"][1:] * np.diff(tp["theta"]) / np.diff(tp["t"])
    assert np.allclose(speed[tp["rho"][1:] > 0.05], 5.0, rtol=0.02)
    facts = json.loads((tmp_path / "tp" / "toolpath.json").read_text())
    assert facts["toolpath"]["cut_time_s"] == pytest.approx(tp["t"][-1] - tp["t"][0])
    r = _run(package, "compare", str(scene), "--out", str(tmp_path / "cmp"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    c = json.loads((tmp_path / "cmp" / "metrics.json").read_text())
    assert [v["name"] for v in c["variants"]] == ["speed_as_set", "speed_halved"]
    assert c["pair"]["key"] == "process.cutting_speed_mm_s"
    assert c["speed_as_set"]["process"] == "css" and (tmp_path / "cmp" / "report.html").is_file()


@pytest.mark.mitsuba
def test_a_new_instrument_is_one_file(package, tmp_path):
    (tmp_path / "s.toml").write_text(SADDLE_SCENE + "[render.stylus]\ntip_radius = 0.01\n")
    r = _run(package, "render", str(tmp_path / "s.toml"), "--kind", "stylus",
             "--out", str(tmp_path / "o"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    res = json.loads((tmp_path / "o" / "render_metrics.json").read_text())["render"]
    assert res["stylus"]["tip_radius_mm"] == 0.01 and res["stylus"]["points"] == 21
    rows = np.loadtxt(tmp_path / "o" / "stylus_profile.csv", delimiter=",", skiprows=1)
    # the tip rides on the surface: never below it
    assert np.all(rows[:, 2] >= rows[:, 1] - 1e-12)
    # and the command line lists it among the kinds
    r = _run(package, "render", str(tmp_path / "s.toml"), "--kind", "nope", "--out",
             str(tmp_path / "x"), cwd=tmp_path)
    assert r.returncode == 2 and "'stylus'" in r.stderr


@pytest.mark.slow
def test_a_new_file_format_is_one_file(package, tmp_path):
    (tmp_path / "s.toml").write_text(SADDLE_SCENE)
    for fmt in ("xyz", "npz"):
        r = _run(package, "toolpath", str(tmp_path / "s.toml"), "--format", fmt,
                 "--out", str(tmp_path / fmt), cwd=tmp_path)
        assert r.returncode == 0, r.stderr
    xyz = np.loadtxt(tmp_path / "xyz" / "toolpath.xyz")
    npz = np.load(tmp_path / "npz" / "toolpath.npz")
    assert np.allclose(xyz, np.column_stack([npz["x"], npz["y"], npz["z"]]), atol=1e-9)


_DRAW_HISTOGRAM = """
import sys
from pathlib import Path

import numpy as np

from render_inspect.report import draw_figure, figure_kinds

values = np.random.default_rng(0).normal(0.0, 1.0, 1000)
out = draw_figure({"kind": "histogram", "values": values, "label": "height, nm"},
                  Path(sys.argv[1]))
print(",".join(figure_kinds()), out.stat().st_size)
"""


@pytest.mark.slow
def test_a_new_figure_kind_is_one_file(package, tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(package)
    env.setdefault("MPLBACKEND", "Agg")
    r = subprocess.run([sys.executable, "-c", _DRAW_HISTOGRAM, str(tmp_path / "h.png")],
                       capture_output=True, text=True, cwd=tmp_path, env=env)
    assert r.returncode == 0, r.stderr
    kinds, size = r.stdout.split()
    assert "histogram" in kinds.split(",") and "map" in kinds.split(",") and int(size) > 1000
    assert (tmp_path / "h.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_a_new_measured_file_reader_is_one_file(package, tmp_path):
    """A known map (a plane tilted 2 um over the field plus a 50 nm sine, in um, one
    point not measured) written in the example's format and analysed: the heights come back
    in mm, the pixel and the invalid point as written."""
    x = np.arange(40) * 0.5e-3                                   # mm, pixel 0.5 um
    z_um = 2.0 * x[None, :] / x[-1] + 0.05 * np.sin(2 * np.pi * x[None, :] / 5e-3) \
        + 0.0 * x[:, None]
    z_um[3, 7] = np.nan
    lines = ["pixel_um 0.5"] + [" ".join(f"{v:.9f}" for v in row) for row in z_um]
    (tmp_path / "map.asc").write_text("\n".join(lines) + "\n")
    r = _run(package, "analyze", str(tmp_path / "map.asc"), "--out", str(tmp_path / "o"),
             "--form", "plane", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    m = json.loads((tmp_path / "o" / "metrics.json").read_text())
    assert m["input"]["path"].endswith("map.asc")
    assert m["input"]["n_invalid"] == 1 and np.allclose(m["pixel_mm"], 0.5e-3), m["pixel_mm"]
    # the plane is removed: what is left is the sine, Sq = 50 nm / sqrt(2) to within what
    # the plane fit takes of four periods
    assert abs(m["areal"]["Sq_nm"] - 50 / np.sqrt(2)) < 3, m["areal"]["Sq_nm"]
    # a file the reader refuses: one line naming the file and what it expected (a grid of
    # four columns: two or three would be a profile, which the profile reader takes)
    (tmp_path / "bad.asc").write_text("step 1\n1 2 3 4\n5 6 7 8\n")
    r = _run(package, "analyze", str(tmp_path / "bad.asc"), "--out", str(tmp_path / "b"),
             cwd=tmp_path)
    assert r.returncode == 1 and "pixel_um" in r.stderr and len(r.stderr.splitlines()) == 1


_NEW_INSTRUMENT_JOINS = """
from render_inspect.pipeline import render_kinds
from render_inspect.pipeline._render import _instruments

print(",".join(render_kinds()), ",".join(_instruments("all")))
"""


@pytest.mark.slow
def test_a_new_instrument_joins_every_render_run(package, tmp_path):
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(package)
    r = subprocess.run([sys.executable, "-c", _NEW_INSTRUMENT_JOINS], capture_output=True,
                       text=True, cwd=tmp_path, env=env)
    assert r.returncode == 0, r.stderr
    kinds, joined = (part.split(",") for part in r.stdout.split())
    assert "stylus" in kinds and {"stylus", "interferometer"} <= set(joined)


_NEW_OBJECTIVE = """
import json

import numpy as np

from render_inspect.instruments import interferometer_geometry, microscope_from_config, objective_names
from render_inspect.machining import HeightMap
from render_inspect.scene import scene_from_dict

scene = scene_from_dict({"design": {"type": "plane"},
                         "render": {"interferometer": {"objective": "40x", "noise": False}}})
cfg = scene.render.interferometer
z = np.zeros((1001, 1001))
geo = interferometer_geometry(HeightMap(z, z.copy(), 0.001, (0.0, 0.0)), cfg)
print(json.dumps({"names": objective_names(), "pixel": geo["pixel"], "nx": geo["nx"],
                  "ny": geo["ny"], "na": geo["numerical_aperture"],
                  "slope_limit": microscope_from_config(cfg).objective.slope_limit}))
"""


@pytest.mark.slow
def test_a_new_objective_is_one_file(package, tmp_path):
    """The 40x preset of the page: a scene takes it, and imaging a 1 mm map with it gives
    its 0.45 mm field of 1024 pixels of 0.45 mm / 1024 at NA 0.6 (slope limit asin 0.6);
    the command line lists it among --objective's choices and takes it."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["PYTHONPATH"] = str(package)
    r = subprocess.run([sys.executable, "-c", _NEW_OBJECTIVE], capture_output=True, text=True,
                       cwd=tmp_path, env=env)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)
    assert got["names"] == ["2.5x", "5x", "10x", "20x", "40x", "50x", "100x"]
    assert got["pixel"] == pytest.approx(0.45 / 1024) and got["nx"] == got["ny"] == 1024
    assert got["na"] == 0.6 and got["slope_limit"] == pytest.approx(np.arcsin(0.6))
    r = _run(package, "characterise", "--objective", "nope", "--out", str(tmp_path / "c"),
             cwd=tmp_path)
    assert r.returncode == 2 and "'40x'" in r.stderr and "--objective" in r.stderr
    # fit takes 40x: what it refuses next is the missing measured file
    r = _run(package, "fit", str(tmp_path / "nope.exr"), "--scene", "sts_sinusoidal_grid",
             "--free", "tool.nose_radius", "--objective", "40x", "--out", str(tmp_path / "f"),
             cwd=tmp_path)
    assert r.returncode == 1 and "nope.exr" in r.stderr and "invalid choice" not in r.stderr
