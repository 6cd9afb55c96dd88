"""Saving a figure with one draw and its ticks computed once per state
(:func:`render_inspect.report._savefig.figure_png`) writes the bytes a plain ``savefig``
writes with the same compression level (the image of savefig's default level): constrained
layout with colour bars, rows of shared axes, logarithmic axes, ``tight_layout``."""

from __future__ import annotations

import io

import numpy as np
import pytest

from render_inspect.report._savefig import PNG_COMPRESS_LEVEL, figure_png, quick_ticks


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _maps(plt):
    """Two maps with colour bars (one extended), a scale of a different size each, and a
    suptitle: the layout of the comparison's map figures."""
    fig, axes = plt.subplots(1, 2, figsize=(9.2, 3.9), dpi=100, layout="constrained")
    y, x = np.mgrid[0:120, 0:90]
    for k, ax in enumerate(axes):
        z = np.sin(x / 7.0 + k) * np.cos(y / 11.0) * 10.0 ** (3 * k)
        im = ax.imshow(z, origin="lower", extent=(0, 0.9 * (k + 1), 0, 1.2), cmap="RdBu_r",
                       vmin=-0.8 * 10.0 ** (3 * k), vmax=0.8 * 10.0 ** (3 * k))
        ax.set_title(f"panel {k}")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, extend="both").set_label("nm")
    fig.suptitle("two maps")
    return fig


def _shared_rows(plt):
    """Rows of axes sharing y (one ticker for a row), a logarithmic row, a twin axis and
    a legend placed where it fits best, laid out by ``tight_layout``."""
    fig, axes = plt.subplots(2, 2, figsize=(8.0, 5.0), dpi=90, sharey="row")
    s = np.linspace(0.01, 3.0, 400)
    for j in range(2):
        axes[0, j].plot(s, np.sin(s * (3 + j)) * 1e-4 + 12.5, label="a")
        axes[0, j].legend(loc="best")
        axes[1, j].loglog(s, 1e3 * s ** -(2 + j), label="b")
        axes[1, j].set_xlabel("k (1/mm)")
    axes[0, 1].twinx().plot(s, s * 1e5, color="C1")
    return fig


@pytest.mark.parametrize("make,tight", [(_maps, False), (_shared_rows, True)])
def test_the_bytes_are_those_of_a_plain_savefig(make, tight):
    plt = _plt()
    fig = make(plt)
    if tight:
        fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL})
    plt.close(fig)
    fig = make(plt)
    if tight:
        fig.tight_layout()
    default = io.BytesIO()
    fig.savefig(default, format="png")
    plt.close(fig)
    png = figure_png(make(plt), tight_layout=tight)
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    assert png == buf.getvalue()
    # savefig's own compression level gives other bytes but the same image
    from PIL import Image

    assert png != default.getvalue()
    ours, theirs = (np.asarray(Image.open(io.BytesIO(b))) for b in (png, default.getvalue()))
    assert ours.shape == theirs.shape and np.array_equal(ours, theirs)


def test_the_axes_are_left_as_they_were():
    plt = _plt()
    fig = _maps(plt)
    axes = [a for ax in fig.axes for a in ax._axis_map.values()]
    with quick_ticks(fig):
        assert all("_update_ticks" in a.__dict__ for a in axes)
        fig.canvas.draw()
    assert not any("_update_ticks" in a.__dict__ or "_get_ticklabel_bboxes" in a.__dict__
                   for a in axes)
    plt.close(fig)


def test_remembered_ticks_follow_a_change_of_view():
    """Ticks asked again after the view limits changed are those of the new view."""
    plt = _plt()
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    with quick_ticks(fig):
        fig.canvas.draw()
        first = [t.get_loc() for t in ax.xaxis._update_ticks()]
        ax.set_xlim(0, 50)
        second = [t.get_loc() for t in ax.xaxis._update_ticks()]
    plt.close(fig)
    assert max(first) < 2 and max(second) > 10
