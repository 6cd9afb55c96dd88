"""Test configuration: engines write into HOME, so point HOME and the caches at a
temporary folder before anything imports bpy, mitsuba, drjit or matplotlib."""

from __future__ import annotations

import os
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
