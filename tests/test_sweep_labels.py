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
    ("machining.time_min", "machining time (min)"),
])

def test_sweep_axis_labels(key, label):
    assert _label(key) == label


def test_key_units_for_report_tables():
    from render_inspect.report._keys import key_unit

    assert [key_unit(k) for k in ("tool.nose_radius", "material.texture_nm",
                                  "machine.x.bandwidth_hz", "process.spindle_rpm",
                                  "toolpath.points")] == ["mm", "nm", "Hz", "rpm", ""]


def test_default_plot_titles_and_legends_use_words(monkeypatch):
    from render_inspect.report import _sweep_plots as sp

    texts = []

    real = sp._png

    def spy(fig, **kw):
        for ax in fig.axes:
            texts.append(ax.get_title()) if ax.get_title() else None
            leg = ax.get_legend()
            texts.extend(t.get_text() for t in (leg.get_texts() if leg else []))
        return real(fig, **kw)

    monkeypatch.setattr(sp, "_png", spy)
    sp.curves_png([(0.2, 50, 1.0), (0.6, 50, 2.0)], x="process.feed_mm_per_min",
                  series="process.spindle_rpm", y="residual.Sq_nm")
    sp.heatmap_png([(0.2, 50, 1.0)], x="process.feed_mm_per_min", y="process.spindle_rpm")
    assert texts == ["residual Sq vs process feed rate", "process spindle speed = 50 rpm",
                     "residual Sq over process feed rate and process spindle speed"]
