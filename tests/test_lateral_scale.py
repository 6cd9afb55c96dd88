"""A design's lateral scale (the length its shape changes over, around which a comparison
chooses its S/L filters) is a method of the design surface, not a guess from the scene's
field names: each design type says it, and designs without one say None."""

from __future__ import annotations

import pytest

from render_inspect.design import make_surface
from render_inspect.metrology import feature_size
from render_inspect.scene import load_scene


@pytest.mark.parametrize("scene, scale", [
    ("sts_sinusoidal_grid", 2.5),     # the longer wavelength
    ("sts_mla_2x2", 4.243),           # the larger pitch
    ("rcse_circular_array", 0.8),     # an element's diameter (2 x 0.4 mm)
    ("compound_sinusoid", 4.0),       # the feature's, not the base's
    ("sts_fig16_overcut", 0.5),
])
def test_each_shipped_design_says_its_lateral_scale(scene, scale):
    surface = make_surface(load_scene(scene).design)
    assert surface.lateral_scale() == scale
    assert feature_size(surface) == scale


def test_a_design_without_one_says_none():
    assert make_surface({"type": "plane", "slope_x": 0.1}).lateral_scale() is None
    grid = make_surface({"type": "sinusoidal_grid", "amplitude_x": 0.001, "amplitude_y": 0.001,
                         "wavelength_x": 0.3, "wavelength_y": 0.7})
    assert grid.lateral_scale() == 0.7
