"""simulate_scene: one entry point for every process kind."""

from __future__ import annotations

import time

from ._result import SimulationResult


def simulate_scene(scene) -> SimulationResult:
    """Simulate the machined surface of ``scene`` (dispatch on ``scene.process.kind``).

    sts -> turning with a slow tool servo (this package); hts / fts -> hybrid slow + fast
    tool servo with servo dynamics; sculpt -> vibration-assisted sculpturing; rcse ->
    turning along a rotary-coordinate shuttling-element path."""
    t0 = time.perf_counter()
    kind = scene.process.kind
    if kind == "sts":
        from ._sts import simulate_sts

        res = simulate_sts(scene)
    elif kind in ("hts", "fts"):
        from ._servo import simulate_hts

        res = simulate_hts(scene)
    elif kind == "sculpt":
        from ._sculpt import simulate_sculpt

        res = simulate_sculpt(scene)
    elif kind == "rcse":
        from ._rcse import simulate_rcse

        res = simulate_rcse(scene)
    else:  # pragma: no cover - the scene schema rejects other kinds
        raise ValueError(f"process.kind {kind!r} is unsupported")
    res.timing_s.setdefault("total", time.perf_counter() - t0)
    return res
