"""Compile the numba kernels once per environment.

``make setup`` runs ``python -m render_inspect.pipeline._warmup``: every kernel is
called once with the argument types the commands use, and numba stores the machine code
in its cache (``cache=True``: the ``__pycache__`` folders beside the sources, or numba's
user cache folder where those are read-only).  Later processes, Dask workers included,
load the code instead of compiling it.

Besides the turning kernels, the NC program's compiled writer and reader (a small program
written and read back) and the tiled path, it cuts both variants of every shipped
scene in a window of 40 x 40 points (so the machine, servo, material and sculpturing
kernels those scenes use are compiled with the types the commands use) and runs the
comparison of the demo's scene on a small window (the interferometer's and the phase
retrieval's kernels).

Run as a program, the work is shared by two processes (this one and one it starts): one
compiles the shipped scenes' kernels, the other the demo's comparison and the kernels
called here directly, each from the other's cache where it is already there.  On two
cores this halves the wait (on one core it costs a little more than one process would).
"""

from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..batch import run_tiles
from ..core.toolpath import ToolPath
from ..io import (block_sums, create_heightmap_zarr, grid_attrs, heightmap_channels,
                  heightmap_overview, preview, read_nc, write_nc)
from ..machining import (edge_turns, load_cut_kernels, material_burr_block, prepare_envelope,
                         residual_metrics, simulate_turning, tile_abs_dev, tile_moments)


class _Flat:
    def height(self, x, y):
        return np.zeros(np.broadcast(x, y).shape)


def _spiral(uniform: bool) -> ToolPath:
    n_rev, per_rev = 12, 64
    u = np.linspace(0.0, 1.0, n_rev * per_rev + 1)
    theta = 2 * math.pi * n_rev * (u if uniform else u ** 1.1)
    rho = 0.12 - 0.01 * theta / (2 * math.pi)
    return ToolPath(theta, rho, np.zeros_like(theta), theta)


def warm_up() -> float:
    """Compile (or load) the turning kernels the commands run; return the seconds it took."""
    t0 = time.perf_counter()
    region = (-0.02, -0.02, 0.02, 0.02)
    # (the direct per-pixel kernel, simulate_turning(..., reference=True), checks the fast
    # one in the tests; no command runs it on a path that feeds towards the axis, so it is
    # compiled when first used rather than here: 10 CPU-s of the warm-up)
    for uniform in (True, False):
        m = simulate_turning(_spiral(uniform), nose_radius=0.1, half_width=0.05, region=region, pixel=0.002)
    # a grid of more than two blocks (101 x 101): the same kernel on threads (the 21 x 21
    # grids above run it on the calling thread, as small grids do)
    simulate_turning(_spiral(True), nose_radius=0.1, half_width=0.05, region=(-0.1, -0.1, 0.1, 0.1),
                     pixel=0.002)
    load_cut_kernels()
    d = np.zeros_like(m)
    residual_metrics(m, d)
    tile_moments(m, d)
    for arr in (m, m.astype(np.float32)):
        tile_abs_dev(arr, 0.0, -1.0, 1.0, 8)
        block_sums(arr, 2)
    preview(m, 4, minus=d)
    heightmap_channels(d, m)
    heightmap_overview(d, m, 4)
    # the burr model's edge tests (they run only where a map has candidate edges: a kink)
    y, x = np.mgrid[0:40, 0:40] * 0.002
    edge_turns(0.1 * np.abs(x - 0.04) + 0.1 * np.abs(y - 0.04), pixel=0.002, span=2)
    # and the proof of no edge on a tile's window, from the design on its block
    zb = 0.002 * (x ** 2 + y ** 2)
    material_burr_block(zb, pixel=0.002, chip_thickness=1e-3, coefficient=1.0, smoothing=0.002, width=0.003,
                        border=(False, False, False, False), inner=(18, 22, 18, 22), reference=zb)
    ep = prepare_envelope(_spiral(True), nose_radius=0.1, half_width=0.05)
    with tempfile.TemporaryDirectory() as tmp:
        # the NC program's compiled writer and reader (a program written and read back)
        write_nc(Path(tmp) / "p.nc", _spiral(True))
        read_nc(Path(tmp) / "p.nc")
        store = str(Path(tmp) / "w.zarr")
        shape = m.shape
        # (two levels: a tile's coarser levels are compiled loops too)
        create_heightmap_zarr(store, shape, chunk=64, attrs=grid_attrs(0.002, region[:2], None, None),
                              levels=2)
        run_tiles(ep, _Flat(), origin=region[:2], pixel=0.002, shape=shape, store=store, levels=2, tile=64,
                  workers=1)
    return time.perf_counter() - t0


#: the window of the shipped scenes' warm-up cut, in pixels of each scene
_WINDOW_PIXELS = 40
#: the demo's comparison made small: a 0.1 mm field, tiny diffuse renders
_SMALL_COMPARE = ("render.interferometer.field_of_view=[-0.05, -0.05, 0.05, 0.05]",
                  "render.diffuse.resolution=32", "render.diffuse.spp=4")


def warm_up_scenes(*, compare: bool = True) -> float:
    """Cut both variants of every shipped scene in a small window at the scene's own
    pixel (the kernels they use, with the types they use), and run the demo's
    comparison on a small window (unless ``compare`` is False: :func:`warm_up_compare`);
    return the seconds it took."""
    # the scenes and the public pipeline, imported when the warm-up runs (the package's
    # __init__ is complete by then; this module is not imported by it)
    from ..scene import load_scene, shipped_scenes
    # (see above)
    from . import compare_variants, simulate

    t0 = time.perf_counter()
    for path in shipped_scenes().values():
        scene = load_scene(path)
        x0, y0, x1, y1 = scene.simulation.region
        half = _WINDOW_PIXELS / 2 * scene.simulation.pixel
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        window = f"simulation.region=[{cx - half!r}, {cy - half!r}, {cx + half!r}, {cy + half!r}]"
        for variant in compare_variants(load_scene(path, [window])):
            simulate(variant)
    if compare:
        warm_up_compare()
    return time.perf_counter() - t0


def warm_up_compare() -> float:
    """Run the demo's comparison on a small window (the interferometer's and the phase
    retrieval's kernels); return the seconds it took."""
    # (imported when the warm-up runs, as in warm_up_scenes)
    from ..scene import load_scene
    # (see above)
    from . import DEMO_SCENE, run_compare

    t0 = time.perf_counter()
    scene = load_scene(DEMO_SCENE, ["simulation.region=[-0.05, -0.05, 0.05, 0.05]",
                                    *_SMALL_COMPARE])
    with tempfile.TemporaryDirectory() as tmp:
        run_compare(scene, Path(tmp) / "compare")
    return time.perf_counter() - t0


def _main(argv: list[str]) -> int:
    """The program: the shipped scenes in a second process, the comparison and the
    direct kernels in this one (``--part scenes`` is the second process)."""
    import logging

    # (the shipped scenes' notes on their own models, e.g. a steel's chemical wear of the
    # diamond, are for a user's run of the scene, not for the setup)
    logging.getLogger("render_inspect").setLevel(logging.ERROR)
    if argv == ["--part", "scenes"]:
        warm_up_scenes(compare=False)
        return 0
    t0 = time.perf_counter()
    other = subprocess.Popen([sys.executable, "-m", __spec__.name if __spec__ else __name__,
                              "--part", "scenes"])
    try:
        warm_up_compare()
        warm_up()
    finally:
        rc = other.wait()
    if rc != 0:
        print(f"the warm-up of the shipped scenes failed (exit code {rc})", file=sys.stderr)
        return 1
    print(f"numba kernels compiled or loaded from the cache in {time.perf_counter() - t0:.1f} s "
          f"(two processes)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(_main(sys.argv[1:]))
