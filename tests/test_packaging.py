"""The package as a user gets it: a wheel built from this checkout, installed with pip
into a fresh virtual environment outside the checkout, runs the demo (on a small window) and finds
the shipped scenes by name.  And the environment as `make setup` makes it: exactly the lock
(requirements.lock), whose versions satisfy the ranges of pyproject.toml."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tools"))
import lock  # noqa: E402  (tools/lock.py)


@pytest.mark.slow
def test_the_lock_holds_every_distribution_of_the_environment_and_nothing_else():
    """pip list of this environment (make setup's .venv) against the lock: the same
    distributions at the same versions; render_inspect itself is installed from the
    checkout, not locked."""
    res = subprocess.run([sys.executable, "-m", "pip", "list", "--format=json"],
                         capture_output=True, text=True, check=True)
    installed = {canonicalize_name(d["name"]): d["version"] for d in json.loads(res.stdout)}
    assert installed.pop("render-inspect", None), "render_inspect is not installed here"
    locked = {e["name"]: e["version"] for e in lock.read_lock() if lock.applies(e, "linux-x64")}
    assert {n: v for n, v in installed.items() if locked.get(n) != v} == {}, \
        "installed but not at a locked version: run make setup (or make lock after a change)"
    assert sorted(set(locked) - set(installed)) == []
    for name in ("pip", "setuptools", "uv", "numpy", "bpy", "mitsuba", "pytest"):
        assert name in locked, name


def test_the_lock_has_hashes_and_satisfies_the_ranges_of_pyproject():
    import tomllib

    entries = lock.read_lock()
    assert entries and all(e["hashes"] for e in entries), \
        [e["name"] for e in entries if not e["hashes"]]
    names = [e["name"] for e in entries]
    assert len(names) == len(set(names))  # one version each
    versions = {e["name"]: e["version"] for e in entries}
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    reqs = [Requirement(r) for r in project["dependencies"]]
    reqs += [Requirement(r) for extra in project["optional-dependencies"].values() for r in extra]
    for req in reqs:
        name = canonicalize_name(req.name)
        if name == "render-inspect":
            continue
        assert name in versions, f"{req} is not locked"
        assert req.specifier.contains(versions[name], prereleases=True), (req, versions[name])
    # the package itself allows NumPy 2 (library users resolve their own); the lock holds
    # NumPy 1.x because bpy 5.0 needs it
    numpy = next(r for r in project["dependencies"] if r.startswith("numpy"))
    assert Requirement(numpy).specifier.contains("2.3.0")


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
    # built with the lock's setuptools, as `make setup` installs the checkout (no isolated
    # build environment fetched and installed first)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
                    "-w", str(dist), str(REPO)], check=True, env=env, cwd=tmp_path,
                   capture_output=True)
    wheel = next(dist.glob("render_inspect-*.whl"))
    venv = tmp_path / "venv"
    # a bare environment: the lock's pip installs into it from outside (--python), rather
    # than a copy of the pip bundled with Python installed into it first
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True, env=env)
    py = venv / "bin" / "python"
    # the tested versions (the lock, without its hashes) as constraints: pip's cache serves them.
    # --no-compile: Python compiles what the commands import when they import it (pip would
    # compile every module of every distribution first, a third of the install's time)
    (tmp_path / "constraints.txt").write_text(lock.constraints())
    subprocess.run([sys.executable, "-m", "pip", "--python", str(py), "install", "-q", "--no-compile",
                    "--constraint", str(tmp_path / "constraints.txt"), f"{wheel}[render]"],
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

    # the demo itself (run_compare on its scene: both variants, the interferometer, the
    # diffuse views, the overcut budget, the report) on a smaller window and small images
    # than --quick's: the same code and kernels at a fifth of the CPU time
    demo = subprocess.run([str(exe), "demo", "--quick", "--out", "demo",
                           "--set", "simulation.region=[-0.1,-0.1,0.1,0.1]",
                           "--set", "simulation.pixel=0.004",
                           "--set", "render.interferometer.field_of_view=[-0.05,-0.05,0.05,0.05]",
                           "--set", "render.diffuse.resolution=32", "--set", "render.diffuse.spp=4"],
                          env=env, cwd=tmp_path, capture_output=True, text=True)
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
