"""Report helpers: numbers for people, area-averaged maps, annotated images."""

from __future__ import annotations

import numpy as np
import pytest

from render_inspect.report import annotate_rgb, block_mean, display_map, fmt_number, fmt_quantity


@pytest.mark.parametrize("v,kw,text", [
    (-0.0002728, {"resolution": 0.01}, "0"),
    (3e-14, {"resolution": 1e-4}, "0"),
    (7.2216, {}, "7.22"),
    (744.18, {}, "744"),
    (4999.4, {}, "4999"),
    (0.0125, {}, "0.0125"),
    (None, {}, "n/a"),
    (float("nan"), {}, "n/a"),
    (True, {}, "yes"),
    (42052, {}, "42,052"),
    (-78.63, {"resolution": 0.01}, "-78.6"),
    (0.031, {"resolution": 0.01}, "0.03"),
])
def test_fmt_number(v, kw, text):
    assert fmt_number(v, **kw) == text


def test_fmt_quantity_units_and_resolution():
    assert fmt_quantity(-0.0002728, "nm") == "0 nm"
    assert fmt_quantity(7.2216, "nm") == "7.22 nm"
    assert fmt_quantity(0.066, "um") == "0.0660 um"
    assert fmt_quantity(None, "nm") == "n/a"


def test_block_mean_is_an_area_average_that_ignores_nan():
    z = np.arange(36, dtype=float).reshape(6, 6)
    b = block_mean(z, 3)
    assert b.shape == (2, 2)
    assert b[0, 0] == pytest.approx(z[:3, :3].mean())
    z[0, 0] = np.nan
    assert block_mean(z, 3)[0, 0] == pytest.approx(np.nanmean(z[:3, :3]))
    # partial blocks at the end: what they hold
    assert block_mean(np.ones((7, 7)), 3).shape == (3, 3)


def test_display_map_averages_fine_marks_instead_of_aliasing():
    """Rings of 5 um period on a 1 mm, 1000 px map shown at 250 px (4 um each): decimating
    leaves them at full strength as a moire of false rings; the area average of 4 x 4
    blocks attenuates them (to about the sinc of the block, 0.24)."""
    n = 1000
    x = (np.arange(n) - n / 2) * 0.001
    X, Y = np.meshgrid(x, x)
    rings = np.cos(2 * np.pi * np.hypot(X, Y) / 0.00505)  # finer than 2 display pixels
    avg = display_map(rings, 250)
    dec = rings[::4, ::4]
    assert avg.shape == (250, 250)
    assert avg.std() < 0.5 * dec.std()


def test_annotate_rgb_writes_text_and_scale_bar():
    img = np.full((200, 300, 3), 40, dtype=np.uint8)
    out = annotate_rgb(img, lines=["heights x20 (vertical exaggeration)"], scale_mm=0.05,
                       scale_px=60)
    assert out.shape == img.shape
    assert (out[:20, :150] != 40).any()        # the caption
    assert (out[-20:, -80:] != 40).any()       # the scale bar
    assert (out[80:120, 100:200] == 40).all()  # the picture itself is untouched


def test_large_lengths_move_to_the_next_unit():
    assert fmt_quantity(12445.0, "nm") == "12.4 um"
    assert fmt_quantity(-2244.0, "nm") == "-2244 nm"
