"""Test configuration: engines write into HOME, so point HOME and the caches at a
temporary folder before anything imports bpy, mitsuba, drjit or matplotlib."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

_HOME = Path(tempfile.mkdtemp(prefix="render_inspect_test_home_"))
# the user's own HOME, for caches that should outlive a test run (pip's wheel cache)
os.environ.setdefault("RENDER_INSPECT_REAL_HOME", os.environ.get("HOME", str(_HOME)))
for _var in ("HOME", "XDG_CACHE_HOME", "BLENDER_USER_RESOURCES", "MPLCONFIGDIR"):
    os.environ[_var] = str(_HOME / _var.lower())
    Path(os.environ[_var]).mkdir(parents=True, exist_ok=True)
os.environ.setdefault("MPLBACKEND", "Agg")

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
