"""Benchmark: evaluating design surfaces (height, gradient, Hessian) on a 1000 x 1000 grid.

Every tool path and every simulated height map starts with these calls, so their cost is
the floor of the pipeline.  Reports million points per second for each design type.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _surfaces(tmp: Path):
    from render_inspect.design import (
        Compound,
        ExpressionSurface,
        HeightMapSurface,
        LensletArray,
        LensletRings,
        SinusoidalGrid,
        Sphere,
        Toric,
    )

    grid = SinusoidalGrid(0.002, 0.002, 2.5, 2.5)
    x = -1.0 + 0.01 * np.arange(201)
    np.save(tmp / "map.npy", Sphere(20.0).height(x[None, :], x[:, None]))
    return {
        "sinusoidal_grid": grid,
        "sphere": Sphere(20.0),
        "toric": Toric(500.0, 250.0),
        "lenslet_array_round": LensletArray(rows=2, cols=2, pitch_x=4.243, pitch_y=4.243,
                                            lens_radius=250.004, aperture_radius=2.0),
        "lenslet_array_quad": LensletArray(rows=10, cols=10, pitch_x=0.19975, pitch_y=0.19975,
                                           lens_radius=1.0, cells="quad"),
        "lenslet_rings_61": LensletRings([0.0, 0.9, 1.8, 2.7, 3.6], [1, 6, 12, 18, 24], 0.4,
                                           0.002),
        "expression": ExpressionSurface("2e-3*cos(2*pi*x/2.5) + 2e-3*cos(2*pi*y/2.5)"),
        "compound_seed001": Compound(
            ExpressionSurface("-(x**2/(r + sqrt(r**2 - x**2)) + y**2/(r + sqrt(r**2 - y**2)))",
                              {"r": 1000.0}),
            SinusoidalGrid(0.03, 0.03, 4.0, 4.0, -np.pi / 2, -np.pi / 2)),
        "heightmap_cubic": HeightMapSurface(tmp / "map.npy", pixel=0.01, origin=(-1.0, -1.0)),
        "heightmap_linear": HeightMapSurface(tmp / "map.npy", pixel=0.01, origin=(-1.0, -1.0),
                                             interpolation="linear"),
    }


def main(n: int = 1000, repeats: int = 2) -> dict:
    """Time height / gradient / hessian of each design type on an ``n`` x ``n`` grid
    over [-1, 1]^2 mm; return {type: {call: Mpoints_per_s}}."""
    xs = np.linspace(-1.0, 1.0, n)
    X, Y = np.meshgrid(xs, xs)
    out = {"points": n * n}
    with tempfile.TemporaryDirectory() as tmp:
        for name, s in _surfaces(Path(tmp)).items():
            row = {}
            for call in ("height", "gradient", "hessian"):
                fn = getattr(s, call)
                best = min(_timed(fn, X, Y) for _ in range(repeats))
                row[call] = round(n * n / best / 1e6, 2)
            out[name] = row
    print(json.dumps(out, indent=2))
    return out


def _timed(fn, X, Y) -> float:
    t0 = time.perf_counter()
    fn(X, Y)
    return time.perf_counter() - t0


if __name__ == "__main__":
    main(**({"n": int(sys.argv[1])} if len(sys.argv) > 1 else {}))
