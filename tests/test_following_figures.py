"""The following-error figures, drawn with Pillow: one panel per axis that moves, with its
statistics; a single tick's spike stays visible after the per-bin envelope; the map's
colours follow the sign of each error, grey where nothing was cut."""

import io

import numpy as np
import pytest
from PIL import Image

from render_inspect.report import _following as F


def _image(path):
    return np.asarray(Image.open(io.BytesIO(path.read_bytes())).convert("RGB")).astype(int)


def _series(n=400_000, axes=("x", "z", "fts", "c"), seed=0):
    t = np.linspace(0.0, 600.0, n)
    rng = np.random.default_rng(seed)
    return t, {k: rng.normal(scale=1e-5 if k == "c" else 3e-6, size=t.size) for k in axes}


@pytest.mark.parametrize("axes", [("x",), ("x", "z"), ("x", "z", "c"), ("x", "z", "fts", "c")])
def test_one_panel_per_axis_that_moves(tmp_path, axes):
    t, errors = _series(axes=("x", "z", "fts", "c"))
    height = {}
    for n, names in ((1, ("x",)), (2, ("x", "z"))):
        png = F.plot_following_error(t, {k: errors[k] for k in names}, tmp_path / f"{n}.png")
        height[n] = _image(png).shape[0]
    per_panel = height[2] - height[1]
    assert per_panel > 100
    given = {k: errors[k] for k in axes}
    given["fts"] = np.zeros_like(t)  # an axis that does not move is left out
    png = F.plot_following_error(t, given, tmp_path / "given.png")
    rows = len([k for k in axes if k != "fts"])
    assert _image(png).shape[0] == height[1] + (rows - 1) * per_panel


def test_the_statistics_are_written_and_a_single_tick_spike_is_drawn(tmp_path):
    t, errors = _series(axes=("x",))
    stats = {"x_rms_nm": 3.0, "x_max_nm": 12.0}
    quiet = F.plot_following_error(t, errors, tmp_path / "quiet.png", stats=stats)
    spiky = dict(errors)
    spiky["x"] = errors["x"].copy()
    spiky["x"][123_457] = 40 * np.max(np.abs(errors["x"]))  # one tick of 400,000
    spike = F.plot_following_error(t, spiky, tmp_path / "spike.png", stats=stats)
    other = F.plot_following_error(t, errors, tmp_path / "other.png",
                                   stats={"x_rms_nm": 3.5, "x_max_nm": 12.0})
    a, b, c = _image(quiet), _image(spike), _image(other)
    assert a.shape == b.shape == c.shape
    assert not np.array_equal(a, c)  # the statistics are in the figure
    # the spike, one tick of 400,000, is drawn (the envelope keeps it): a thin line, many
    # rows of the panel high, where the curve's colour is in a few columns only
    curve = (31, 90, 160)

    def thin_rows(img):
        per_row = np.all(img == curve, axis=2).sum(axis=1)
        return int(np.count_nonzero((per_row >= 1) & (per_row <= 4)))

    assert thin_rows(b) > 60 and thin_rows(b) > 4 * thin_rows(a)


def test_the_figures_sent_to_another_process_are_their_panels(tmp_path):
    # what the command's figure process receives: the panels drawn, not the series (the
    # same PNG bytes from a small fraction of the data)
    import pickle

    from render_inspect.core.toolpath import ToolPath
    from render_inspect.report import draw_figure, drawn_data

    t, errors = _series(axes=("x", "z"))
    theta = np.linspace(0.0, 400 * np.pi, 400_001)
    path = ToolPath(theta, 2.0 - 0.01 * theta / (2 * np.pi), 2e-3 * np.cos(3 * theta), theta / 5.0)
    specs = {"fe": {"kind": "following_error", "t": t, "errors": errors,
                    "stats": {"x_rms_nm": 3.0, "x_max_nm": 9.0}},
             "axes": {"kind": "axes", "columns": [("STS program", path, {})], "title": "axes"}}
    for name, spec in specs.items():
        small = drawn_data(spec)
        assert small["kind"] == "panels"
        assert len(pickle.dumps(small, protocol=5)) < len(pickle.dumps(spec, protocol=5)) / 20
        a = draw_figure(spec, tmp_path / f"{name}_spec.png").read_bytes()
        b = draw_figure(small, tmp_path / f"{name}_panels.png").read_bytes()
        assert a == b, name
    other = {"kind": "map", "data": np.zeros((3, 4))}
    assert drawn_data(other) is other
