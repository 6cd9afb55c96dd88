"""The package as a user gets it: a wheel built from this checkout, installed with pip
into a fresh virtual environment outside the checkout, runs the demo and finds the shipped
scenes by name."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _env() -> dict:
    env = dict(os.environ)
    real_home = env.get("RENDER_INSPECT_REAL_HOME", env.get("HOME", ""))
    env.setdefault("PIP_CACHE_DIR", str(Path(real_home) / ".cache" / "pip"))
    env.pop("PYTHONPATH", None)  # nothing from the checkout may leak in
    return env


@pytest.mark.slow
def test_wheel_installs_into_a_fresh_venv_and_runs_the_demo(tmp_path):
    env = _env()
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(dist),
                    str(REPO)], check=True, env=env, cwd=tmp_path, capture_output=True)
    wheel = next(dist.glob("render_inspect-*.whl"))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, env=env)
    py = venv / "bin" / "python"
    # the tested versions (requirements.txt) as constraints: pip's cache serves them
    subprocess.run([str(py), "-m", "pip", "install", "-q", "--constraint",
                    str(REPO / "requirements.txt"), f"{wheel}[render]"],
                   check=True, env=env, cwd=tmp_path, capture_output=True)
    exe = venv / "bin" / "render-inspect"
    where = subprocess.run([str(py), "-c", "import render_inspect; print(render_inspect.__file__)"],
                           check=True, env=env, cwd=tmp_path, capture_output=True, text=True)
    assert str(REPO) not in where.stdout and str(venv) in where.stdout

    sim = subprocess.run([str(exe), "simulate", "sts_sinusoidal_grid", "--out", "sim",
                          "--set", "simulation.region=[-0.1,-0.1,0.1,0.1]"],
                         env=env, cwd=tmp_path, capture_output=True, text=True)
    assert sim.returncode == 0, sim.stderr
    m = json.loads((tmp_path / "sim" / "metrics.json").read_text())
    assert m["scene_name"] == "sts_sinusoidal_grid" and m["samples"] == 201 * 201  # 1 um pixels

    demo = subprocess.run([str(exe), "demo", "--out", "demo", "--quick"], env=env, cwd=tmp_path,
                          capture_output=True, text=True)
    assert demo.returncode == 0, demo.stderr
    assert (tmp_path / "demo" / "report.html").stat().st_size > 10_000
    assert (tmp_path / "demo" / "compensated" / "heightmap.exr").is_file()

    # the regression cases, their references and the sweeps ship with the package
    reg = subprocess.run([str(exe), "regress", "--only", "sts_grid_normal,fig16_overcut_z",
                          "--out", "regress"], env=env, cwd=tmp_path, capture_output=True, text=True)
    assert reg.returncode == 0, reg.stderr
    assert json.loads((tmp_path / "regress" / "summary.json").read_text())["passed"] == 2
    sweeps = subprocess.run([str(py), "-c", "from render_inspect.pipeline import find_sweep; "
                             "print(find_sweep('fig15_small'), find_sweep('fig15'))"],
                            env=env, cwd=tmp_path, capture_output=True, text=True)
    assert sweeps.returncode == 0 and str(venv) in sweeps.stdout, sweeps.stderr
