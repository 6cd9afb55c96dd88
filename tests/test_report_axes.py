"""What the report's maps say on their axes: the compare report's locator (Figure 1's left
panel, and the figure shown alone when the variants are identical) carries a colour bar
of the design's height with its unit and x, y in mm; characterise's ``flat_noise.png`` is
drawn in mm on the part, spanning the camera's field.  The figures are read back from
matplotlib (the figure each function draws, before it becomes a PNG)."""

from __future__ import annotations

# imported at collection, not inside a test: its first import starts a process (fc-list)
import matplotlib.pyplot  # noqa: F401
import numpy as np
import pytest

import render_inspect.report._figures as figures_module
import render_inspect.report._locator as locator_module
from render_inspect.report import characterise_figures, difference_figure, locator_figure
from render_inspect.report._locator import height_background


@pytest.fixture
def drawn(monkeypatch):
    """The matplotlib figures drawn (each kept open, and its PNG made as before)."""
    figs = []

    def keep(fig, **kw):
        figs.append(fig)
        return keep_png(fig, **kw)

    keep_png = figures_module._to_png
    monkeypatch.setattr(figures_module, "_to_png", keep)
    monkeypatch.setattr(locator_module, "_to_png", keep)
    return figs


def _colour_bars(fig) -> list:
    return [ax for ax in fig.axes if getattr(ax, "_colorbar", None) is not None]


def _sphere(r_mm: float, extent, n: int = 60) -> np.ndarray:
    x = np.linspace(extent[0], extent[1], n)
    y = np.linspace(extent[2], extent[3], n)
    xx, yy = np.meshgrid(x, y)
    return r_mm - np.sqrt(r_mm ** 2 - xx ** 2 - yy ** 2)     # sag, mm


def _locator(z_mm, extent) -> dict:
    return {"part": {}, "windows": [("region", (extent[0], extent[2], extent[1], extent[3]),
                                     "C3", "-")],
            "limits": extent, **height_background(z_mm, extent)}


def test_the_locator_has_a_colour_bar_of_the_design_height_in_um(drawn):
    ext = (-1.0, 1.0, -1.0, 1.0)
    z = _sphere(20.0, ext)                                   # 50 um sag at the corners
    locator_figure(_locator(z, ext))
    (fig,) = drawn
    (bar,) = _colour_bars(fig)
    assert bar.get_ylabel() == "design height (um)"
    lo, hi = bar._colorbar.mappable.get_clim()
    # the drawn map is the design in um (area-averaged for display: within a block's range)
    assert lo == pytest.approx(np.min(z) * 1e3, abs=1.0) and hi == pytest.approx(np.max(z) * 1e3,
                                                                                   rel=0.05)
    (panel,) = [ax for ax in fig.axes if ax not in _colour_bars(fig)]
    assert panel.get_xlabel() == "x (mm)" and panel.get_ylabel() == "y (mm)"


def test_a_design_flatter_than_a_micrometre_is_shown_in_nm(drawn):
    ext = (0.0, 0.2, 0.0, 0.2)
    x = np.linspace(0, 0.2, 40)
    z = np.tile(2e-4 * np.sin(2 * np.pi * x / 0.05), (40, 1))   # +-200 nm ripple
    bg = height_background(z, ext)
    assert bg["background_label"] == "design height (nm)"
    assert np.ptp(bg["background"][0]) == pytest.approx(np.ptp(z) * 1e6, rel=1e-12)
    locator_figure(_locator(z, ext))
    assert _colour_bars(drawn[0])[0].get_ylabel() == "design height (nm)"


def test_figure_one_locator_panel_has_its_colour_bar(drawn):
    ext = (-1.0, 1.0, -1.0, 1.0)
    z = _sphere(20.0, ext)
    d = np.random.default_rng(3).normal(size=(30, 30))
    s = np.linspace(-0.1, 0.1, 30)
    difference_figure(names=("a", "b"), locator=_locator(z, ext), true_diff=d,
                      true_extent=(-0.1, 0.1, -0.1, 0.1), measured_diff=d,
                      measured_extent=(-0.1, 0.1, -0.1, 0.1),
                      profile={"s": s, "true": d[15], "line": ((-0.1, 0.0), (0.1, 0.0))})
    (fig,) = drawn
    labels = sorted(ax.get_ylabel() for ax in _colour_bars(fig))
    assert labels == ["design height (um)", "height difference (nm)", "height difference (nm)"]


@pytest.mark.parametrize("pixel_mm, shape", [(0.002, (40, 50)), (0.00345, (64, 64))])
def test_flat_noise_axes_span_the_field_in_mm(drawn, pixel_mm, shape):
    """``flat_noise.png``: x and y in mm on the part, from 0 to the field (pixels x the
    camera pixel), not the pixel indices."""
    ny, nx = shape
    table = [{"frequency_per_mm": f, "itf_textbook": 1.0, "itf_model": 1.0, "itf_optics": 1.0,
              "itf_instrument": 1.0} for f in (10.0, 100.0)]
    m = {"itf": {"table": table, "cutoff_per_mm": 500.0, "camera_nyquist_per_mm": 250.0},
         "objective": {"name": "20x", "numerical_aperture": 0.4},
         "step": {"psi_profile": {"x_um": [0, 1], "height_nm": [0, 20]}},
         "slope": {}, "pixel_mm": pixel_mm}
    curves = {"step_profiles": {"100 nm": ([0, 1], [0, 1])},
              "flat_difference": np.random.default_rng(1).normal(size=shape)}
    figs = characterise_figures(m, curves)
    assert figs["flat_noise.png"][:4] == b"\x89PNG"
    fig = drawn[-1]                                          # flat_noise.png, drawn last
    (ax,) = [a for a in fig.axes if a.images]
    assert ax.get_xlabel() == "x (mm)" and ax.get_ylabel() == "y (mm)"
    assert ax.images[0].get_extent() == pytest.approx([0.0, nx * pixel_mm, 0.0, ny * pixel_mm])
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    assert (x0, x1, y0, y1) == pytest.approx((0.0, nx * pixel_mm, 0.0, ny * pixel_mm))
