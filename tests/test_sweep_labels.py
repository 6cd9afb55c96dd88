"""Sweep plots label their axes with the keys' words and units, not raw key names."""

import pytest

from render_inspect.report._sweep_plots import _label


@pytest.mark.parametrize("key, label", [
    ("tool.nose_radius", "tool nose radius (mm)"),
    ("residual.Sq_nm", "residual Sq (nm)"),
    ("process.spindle_rpm", "process spindle speed (rpm)"),
    ("process.feed_mm_per_min", "process feed rate (mm/min)"),
    ("machine.x.bandwidth_hz", "machine x bandwidth (Hz)"),
    ("artifacts.servo.delay_s", "artifacts servo delay (s)"),
    ("tool.included_angle_deg", "tool included angle (deg)"),
    ("toolpath.points", "toolpath points"),
])
def test_sweep_axis_labels(key, label):
    assert _label(key) == label


def test_key_units_for_report_tables():
    from render_inspect.report._keys import key_unit

    assert [key_unit(k) for k in ("tool.nose_radius", "material.texture_nm",
                                  "machine.x.bandwidth_hz", "process.spindle_rpm",
                                  "toolpath.points")] == ["mm", "nm", "Hz", "rpm", ""]
