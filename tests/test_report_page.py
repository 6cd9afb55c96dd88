"""The report's choices on known inputs: the common window lands on a design's features,
panels of the same window carry the same scale bar, the first figure's low-pass removes
marks the map cannot hold, every parameter has a unit or a reason, and the deepest cut is
explained from the budget the pipeline computes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from render_inspect.metrology import common_window
from render_inspect.metrology._profiles import design_features
from render_inspect.report import lowpass_map, scale_bar_length
from render_inspect.report._page import _overcut_sentences
from render_inspect.report._params import key_unit, section_rows, settings_rows, value_text


def _lenslets_on_a_base(n=241, pixel=0.0125):
    """Four concave caps (r 0.4 mm, sag from R 10 mm) on a toric base, 3 x 3 mm."""
    x = (np.arange(n) - n // 2) * pixel
    X, Y = np.meshgrid(x, x)
    z = (X ** 2 / 1000 + Y ** 2 / 500)
    for cx, cy in ((-0.75, -0.75), (0.75, -0.75), (-0.75, 0.75), (0.75, 0.75)):
        r2 = (X - cx) ** 2 + (Y - cy) ** 2
        cap = np.where(r2 < 0.16, 10 - np.sqrt(np.maximum(100 - r2, 0)) - (10 - math.sqrt(100 - 0.16)), 0)
        z -= cap
    return x, X, Y, z


def test_common_window_lands_on_the_features_of_a_design():
    x, X, Y, z = _lenslets_on_a_base()
    pixel = x[1] - x[0]
    feats = design_features(z, pixel)
    assert feats is not None and 0.1 < feats.mean() < 0.5
    # the largest difference is on the bare base in a corner; a smaller one on the lenses
    diff = 30.0 * np.exp(-((X - 1.4) ** 2 + (Y - 1.4) ** 2) / 0.02) + 5.0 * (feats > 0)
    plain = common_window(diff, pixel=pixel, origin=(x[0], x[0]), size_mm=0.3)
    on = common_window(diff, pixel=pixel, origin=(x[0], x[0]), size_mm=0.3, design=z)
    cx, cy = (plain["window"][0] + plain["window"][2]) / 2, (plain["window"][1] + plain["window"][3]) / 2
    assert math.hypot(cx - 1.4, cy - 1.4) < 0.2            # without the design: the corner
    cx, cy = (on["window"][0] + on["window"][2]) / 2, (on["window"][1] + on["window"][3]) / 2
    assert min(math.hypot(cx - a, cy - b) for a in (-0.75, 0.75) for b in (-0.75, 0.75)) < 0.3
    # a design alike everywhere (a sinusoid) keeps the plain rule
    s = 2e-3 * np.cos(2 * np.pi * X / 2.5) + 2e-3 * np.cos(2 * np.pi * Y / 2.5)
    assert design_features(s, pixel) is None
    same = common_window(diff, pixel=pixel, origin=(x[0], x[0]), size_mm=0.3, design=s)
    assert same == plain


def test_panels_of_nearly_the_same_width_carry_the_same_scale_bar():
    # a 20x window (256 camera pixels) and its pixel-edge extent on a 2.5 um grid
    assert scale_bar_length(0.225) == scale_bar_length(0.2275) == pytest.approx(0.05)
    assert scale_bar_length(0.09) == scale_bar_length(0.0912) == pytest.approx(0.02)
    for w in (0.045, 0.45, 0.9, 1.8, 3.0):
        bar = scale_bar_length(w)
        assert 0.09 * w < bar <= 0.26 * w
        assert round(bar / 10 ** math.floor(math.log10(bar)), 6) in (1, 2, 5)


def test_lowpass_removes_marks_the_map_cannot_hold():
    pixel = 0.002
    x = np.arange(200) * pixel
    X, Y = np.meshgrid(x, x)
    slow = 10.0 * np.sin(2 * np.pi * X / 0.2)          # 200 um: kept
    marks = 8.0 * np.sin(2 * np.pi * (X + 0.3 * Y) / 0.005)  # 5 um at 2 um pixels: aliases
    out = lowpass_map(slow + marks, pixel, 0.0108)
    inner = (slice(30, -30), slice(30, -30))
    assert np.std((out - slow)[inner]) < 0.6            # the marks' false stripes averaged out
    assert np.corrcoef(out[inner].ravel(), slow[inner].ravel())[0, 1] > 0.99
    z = slow.copy()
    z[50:60, 50:60] = np.nan
    assert np.isnan(lowpass_map(z, pixel, 0.0108)[55, 55])


def test_every_parameter_has_a_unit_or_a_reason():
    from render_inspect.scene import load_scene

    sc = load_scene("hts_toric_msa")
    d = sc.to_dict()
    cells = []
    for sec in ("design", "tool", "process", "machine", "material", "simulation", "metrology"):
        for title, rows in section_rows(sec, getattr(sc, sec), d[sec]):
            for key, value, meaning in rows:
                cells.append((title, key, value, meaning))
                assert value and meaning, (title, key)
                assert value.lower() not in ("none", "n/a", "nan", "-"), (title, key, value)
    by = {(t, k): v for t, k, v, _ in cells}
    assert by[("[simulation]", "pixel")] == "2.5 um"
    assert by[("[tool]", "nose_radius")] == "25 um"
    assert by[("[process]", "spindle_rpm")] == "100 rpm"
    assert by[("[machine.z]", "bandwidth_hz")].startswith("not set: the preset 'fts'")
    assert by[("[material]", "edge_radius_nm")] == "50 nm"
    assert key_unit("noise_urad") == "urad" and key_unit("acceleration_limit_mm_s2") == "mm/s^2"
    assert value_text("spectrum", None) == "not set (not used)"
    rows = dict(settings_rows({"z": {"noise_rms": 3e-6, "bandwidth_hz": 100.0,
                                     "velocity_limit": None},
                               "c": {"noise_rms": 1e-6},
                               "errors": {"axial_sync": [[2, 3e-6, 0.5]]}}))
    assert rows["z.noise_rms"] == "3.00 nm" and rows["c.noise_rms"] == "1.00 urad"
    assert rows["z.velocity_limit"] == "no limit" and rows["z.bandwidth_hz"] == "100.0 Hz"
    assert rows["errors.axial_sync"].startswith("harmonic 2: 3.00 nm at 28.6 deg")


def test_the_deepest_cut_is_explained_by_its_budget():
    metrics = {"variants": [{"name": "compensated", "label": "Z compensation"},
                            {"name": "uncompensated", "label": "none"}],
               "compensated": {
                   "overcut": {"at_mm": [0.1, -0.2], "window_mm": [0, 0, 0.1, 0.1],
                               "min_nm": -19.0, "geometry_nm": 0.0,
                               "alone_nm": {"lathe": -15.0, "material": -1.3},
                               "labels": {"lathe": "the lathe (sts_lathe)",
                                          "material": "the material (al6082)"}},
                   "following_error": {"z_max_nm": 14.2, "z_rms_nm": 3.0},
                   "machine": {"settings": {"errors": {"axial_sync": [[2, 3e-6, 0.7],
                                                                      [3, 2e-6, 2.0]],
                                                       "axial_async_rms": 2e-6}}},
                   "material": {"grooves_rms_nm": 0.99}},
               "uncompensated": {"overcut": None}}
    (text,) = _overcut_sentences(metrics)
    for part in ("19.0 nm below the design", "commanded geometry alone", "leaves 0 nm",
                 "the lathe (sts_lathe) alone -15.0 nm", "within 14.2 nm",
                 "by up to 5.00 nm once per turn", "the material (al6082) alone -1.30 nm",
                 "grooves along the cut (0.99 nm rms)", "all together -19.0 nm"):
        assert part in text, part


def test_the_page_names_every_mitsuba_variant_it_used():
    """The interferometer renders in an RGB variant, the turned aluminium's diffuse views in
    a spectral one: the page names both (it named the first alone)."""
    from render_inspect.report._page import _variants_text

    m = {"mitsuba_variant": "llvm_ad_rgb",
         "render_settings": {"diffuse": {"macro": {"mitsuba_variant": "llvm_ad_spectral"},
                                         "micro": {"mitsuba_variant": "llvm_ad_rgb"}}}}
    assert _variants_text(m) == "llvm_ad_rgb (interferometer), llvm_ad_spectral (diffuse views)"
    m["render_settings"]["diffuse"]["macro"]["mitsuba_variant"] = "llvm_ad_rgb"
    assert _variants_text(m) == "llvm_ad_rgb"
    assert _variants_text({"mitsuba_variant": "scalar_rgb"}) == "scalar_rgb"
