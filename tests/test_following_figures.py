"""The following-error figures are laid out with fixed margins (no tight_layout): every
label, tick label and title stays inside the figure and no axes overlaps another."""

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

from render_inspect.report import _following as F  # noqa: E402


def _boxes_after_save(monkeypatch, tmp_path, draw):
    import matplotlib.pyplot as plt

    kept = {}

    def save(fig, png_path):
        fig.canvas.draw()
        r = fig.canvas.get_renderer()
        kept["fig"] = fig.bbox
        kept["drawn"] = fig.get_tightbbox(r).transformed(fig.dpi_scale_trans)  # all that is drawn
        kept["axes"] = [ax.get_tightbbox(r) for ax in fig.axes]
        plt.close(fig)
        return png_path

    monkeypatch.setattr(F, "_save", save)
    draw(tmp_path / "f.png")
    return kept


def _inside(box, outer, tol=1.0):
    return (box.x0 >= outer.x0 - tol and box.y0 >= outer.y0 - tol and box.x1 <= outer.x1 + tol
            and box.y1 <= outer.y1 + tol)


@pytest.mark.parametrize("axes", [("x",), ("x", "z"), ("x", "z", "c"), ("x", "z", "fts", "c")])
def test_following_error_figure_fits(monkeypatch, tmp_path, axes):
    t = np.linspace(0.0, 600.0, 20001)
    rng = np.random.default_rng(0)
    errors = {k: rng.normal(scale=1e-5 if k == "c" else 3e-6, size=t.size) * 1e3 for k in axes}
    stats = {}
    for k in axes:
        unit = "urad" if k == "c" else "nm"
        stats[f"{k}_rms_{unit}"], stats[f"{k}_max_{unit}"] = -123.456, -12345.6
    kept = _boxes_after_save(monkeypatch, tmp_path, lambda p: F.plot_following_error(
        t, errors, p, title="a scene's long name: following error (command - followed)", stats=stats))
    assert _inside(kept["drawn"], kept["fig"])
    boxes = kept["axes"]
    assert len(boxes) == len(axes)
    for upper, lower in zip(boxes, boxes[1:]):      # rows top to bottom, no overlap
        assert lower.y1 <= upper.y0 + 1.0


@pytest.mark.parametrize("title", [None, "a scene: following error of the pass that cut each point"])
def test_following_error_map_fits(monkeypatch, tmp_path, title):
    rng = np.random.default_rng(1)
    x = -1500.0 * np.abs(rng.normal(size=(101, 151)))
    z = rng.normal(scale=8.0, size=(101, 151))
    kept = _boxes_after_save(monkeypatch, tmp_path, lambda p: F.plot_following_error_map(
        x, z, (-12.5, 12.5, -10.0, 10.0), p, title=title))
    assert _inside(kept["drawn"], kept["fig"])
    a, b, bar_a, bar_b = kept["axes"]                # the two maps, then their colorbars
    assert a.x1 <= bar_a.x0 + 1.0 and bar_a.x1 <= b.x0 + 1.0 and b.x1 <= bar_b.x0 + 1.0
