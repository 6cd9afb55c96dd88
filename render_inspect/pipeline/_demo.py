"""``demo``: the sinusoidal grid of Li et al. 2018, compensated and uncompensated, through the
whole chain into a report."""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path

from ..scene import find_scene, load_scene, shipped_scenes
from ._compare import run_compare

__all__ = ["run_demo", "DEMO_SCENE"]

log = logging.getLogger("render_inspect")

#: the shipped scene the demo runs
DEMO_SCENE = "sts_sinusoidal_grid"


def run_demo(out: str | Path, *, quick: bool = False, overwrite: bool = False,
             overrides: Sequence[str] = ()) -> dict:
    """``render-inspect demo``: :func:`~render_inspect.pipeline.run_compare` on the
    shipped grid of Li et al. 2018 (``quick``: a 0.5 mm window at 2 um, for tests;
    ``overrides``: ``KEY=VALUE`` strings as ``--set`` takes them, applied after ``quick``'s)."""
    out = Path(out)
    window = ["simulation.region=[-0.25,-0.25,0.25,0.25]", "simulation.pixel=0.002"] if quick else []
    scene = load_scene(DEMO_SCENE, [*window, *overrides])
    log.info("demo: scene %s -> %s", shipped_scenes()[DEMO_SCENE].name, out)
    return run_compare(scene, out, overwrite=overwrite, scene_file=find_scene(DEMO_SCENE))
