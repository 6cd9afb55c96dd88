"""The writing of a simulation's outputs moves its progress by the files written: one
step, advanced once per file (from the main thread and the figures' thread), never back,
reaching its total exactly when the last file is written."""

from __future__ import annotations

import threading

import pytest

from render_inspect.core import cancel
from render_inspect.core.progress import set_reporter


class Recorder:
    def __init__(self):
        self.calls = []
        self.lock = threading.Lock()

    def start(self, description, total, timed=False):
        with self.lock:
            self.calls.append(("start", description, total, timed))
            return description

    def advance(self, handle, amount):
        with self.lock:
            self.calls.append(("advance", handle, amount))

    def progress(self, handle, completed):
        with self.lock:
            self.calls.append(("progress", handle, completed))

    def update(self, handle, description):
        with self.lock:
            self.calls.append(("update", handle, description))

    def finish(self, handle):
        with self.lock:
            self.calls.append(("finish", handle))


@pytest.mark.slow
def test_writing_moves_by_files_in_order(tmp_path):
    from render_inspect.pipeline import simulate, write_simulation
    from render_inspect.scene import load_scene

    scene = load_scene("sts_fig16_overcut", ["simulation.region=[1.0, 1.0, 1.06, 1.06]",
                                             "simulation.pixel=0.002"])
    sim = simulate(scene)
    rec = Recorder()
    cancel.clear()
    set_reporter(rec)
    try:
        write_simulation(sim, tmp_path)
    finally:
        set_reporter(None)
    starts = [c for c in rec.calls if c[0] == "start"]
    assert len(starts) == 1, starts
    _, name, total, timed = starts[0]
    assert not timed and "files)" in name
    files = sorted(p.name for p in tmp_path.iterdir())
    assert f"({len(files)} files)" in name, (name, files)
    mine = [c for c in rec.calls if c[1] == name]
    assert mine[0][0] == "start" and mine[-1] == ("finish", name)
    steps = [c[2] for c in mine if c[0] == "advance"]
    assert not [c for c in mine if c[0] == "progress"]  # measured, never estimated
    assert all(a > 0 for a in steps)
    done = 0.0
    for a in steps:  # monotonic, never past the total before the end
        done += a
        assert done <= total
    assert done == pytest.approx(total) and len(steps) == total == len(files) + 1  # (+ overview)


def test_each_render_view_is_a_step_moved_by_its_passes(tmp_path, monkeypatch):
    # the renderer itself is replaced by one that reports its passes as the Mitsuba
    # adapter does (core.progress.report between passes): each view's own step moves
    # forward by them while the render step advances once per view
    from render_inspect.core.progress import report
    from render_inspect.pipeline import _render
    from render_inspect.scene import load_scene

    def fake_views(scene, hm, cfg, *, seed, surface, views):
        for k in range(4):
            report(k, 4)
        return {views[0]: (None, {})}

    class Views:
        big = False

        def diffuse(self, cfg, view):
            return None, cfg

    monkeypatch.setattr(_render, "variant_info", lambda: {"mitsuba_variant": "x",
                                                          "mitsuba_version": "0"})
    monkeypatch.setattr(_render, "render_diffuse_views", fake_views)
    monkeypatch.setattr(_render, "write_diffuse_outputs", lambda *a, **k: {})
    scene = load_scene("sts_fig16_overcut", [])
    rec = Recorder()
    cancel.clear()
    set_reporter(rec)
    try:
        _render._render_views(scene, tmp_path, Views(), surface="machined", kind="diffuse",
                              timing={})
    finally:
        set_reporter(None)
    names = [c[1] for c in rec.calls if c[0] == "start"]
    assert names == ["render", "diffuse macro view: render passes",
                     "diffuse micro view: render passes"], names
    for view in ("macro", "micro"):
        name = f"diffuse {view} view: render passes"
        mine = [c for c in rec.calls if c[1] == name]
        moved = [c[2] for c in mine if c[0] == "advance"]
        assert moved == pytest.approx([0.25, 0.25, 0.25]), mine  # passes 1-3 done, in order
        assert mine[-1] == ("finish", name)
    outer = [c[2] for c in rec.calls if c[0] == "advance" and c[1] == "render"]
    assert outer == [1, 1]
