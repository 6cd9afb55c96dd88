"""``render-inspect render``'s entry point, and seed 000's Fig. 16 case rendered."""

from __future__ import annotations

import json

import numpy as np
import pytest

from render_inspect.errors import InputError
from render_inspect.instruments import render_interferogram
from render_inspect.io import read_exr
from render_inspect.pipeline import render_heightmap, run_render
from render_inspect.scene import InterferometerConfig, load_scene

pytestmark = pytest.mark.mitsuba

SMALL = ["simulation.region=[-0.05, -0.05, 0.05, 0.05]", "simulation.pixel=0.001",
         "render.interferometer.pixel=0.002", "render.interferometer.subsamples=2",
         "render.diffuse.resolution=24", "render.diffuse.spp=4", "simulation.seed=11"]


def test_run_render_design_writes_all_outputs(scenes_dir, tmp_path):
    scene = load_scene(scenes_dir / "sts_sinusoidal_grid.toml", SMALL)
    out = tmp_path / "run"
    res = run_render(scene, out, surface="design", kind="all")
    r = res["render"]
    for name in ("interferogram.exr", "interferogram_fringes.png", "interferogram_height.png",
                 "diffuse_macro.exr", "diffuse_macro.png", "diffuse_micro.exr", "diffuse_micro.png",
                 "render_metrics.json"):
        assert (out / name).is_file(), name
    assert not list(tmp_path.glob(".run.partial-*"))
    ch, attrs = read_exr(out / "interferogram.exr")
    assert attrs["mitsuba_variant"] == r["mitsuba_variant"] and attrs["seed"] == 11
    assert ch["intensity"].shape == (50, 50)
    # the design surface: the ray-traced height is the design height at the pixel centres
    from render_inspect.design import make_surface

    x = attrs["origin_mm"][0] + attrs["pixel_size_mm"] * np.arange(50)
    y = attrs["origin_mm"][1] + attrs["pixel_size_mm"] * np.arange(50)
    expect = make_surface(scene.design).height(x[None, :], y[:, None])
    np.testing.assert_allclose(ch["height_true"], expect, atol=2e-8)
    from PIL import Image

    # no exaggeration in the scene: the automatic one is chosen and stated on the images
    assert scene.render.diffuse.exaggeration is None
    png = Image.open(out / "diffuse_macro.png")
    assert float(png.text["vertical_exaggeration"]) == r["diffuse_macro"]["vertical_exaggeration"] > 1
    _, dattrs = read_exr(out / "diffuse_micro.exr")
    assert dattrs["vertical_exaggeration"] == r["diffuse_micro"]["vertical_exaggeration"]
    saved = json.loads((out / "render_metrics.json").read_text())
    assert saved["render"]["interferometer"]["valid_fraction"] == r["interferometer"]["valid_fraction"]
    # seconds per instrument (by its name) and per diffuse view
    assert set(r["timing_s"]) >= {"interferometer", "diffuse_macro", "diffuse_micro"}


def test_run_render_is_bitwise_repeatable(scenes_dir, tmp_path):
    scene = load_scene(scenes_dir / "sts_sinusoidal_grid.toml",
                       SMALL + ["render.interferometer.noise=true"])
    run_render(scene, tmp_path / "a", surface="design", kind="interferometer")
    run_render(scene, tmp_path / "b", surface="design", kind="interferometer")
    a, _ = read_exr(tmp_path / "a" / "interferogram.exr")
    b, _ = read_exr(tmp_path / "b" / "interferogram.exr")
    for name in a:
        np.testing.assert_array_equal(a[name], b[name])


def test_bad_kind_and_surface(scenes_dir, tmp_path):
    scene = load_scene(scenes_dir / "sts_sinusoidal_grid.toml", SMALL)
    with pytest.raises(InputError, match="--kind"):
        run_render(scene, tmp_path / "x", kind="cycles")
    with pytest.raises(InputError, match="--surface"):
        run_render(scene, tmp_path / "x", surface="ideal")
    assert not (tmp_path / "x").exists()


def test_fig16_compensated_and_uncompensated_renders_differ_where_the_overcut_is(scenes_dir):
    # seed 000, Fig. 16: Ax = Ay = 1 um, l = 0.5 mm, f = 5 mm/min, S = 50 rpm, Rc = 0.5 mm
    base = load_scene(scenes_dir / "sts_sinusoidal_grid.toml", [
        "design.amplitude_x=0.001", "design.amplitude_y=0.001", "design.wavelength_x=0.5",
        "design.wavelength_y=0.5", "process.feed_mm_per_min=5.0", "process.spindle_rpm=50",
        "tool.nose_radius=0.5", "process.workpiece_radius=0.5",
        "simulation.region=[0.1, 0.1, 0.3, 0.3]", "simulation.pixel=0.002"])
    hz = render_heightmap(base.with_overrides(["process.compensation='z'"]))
    hn = render_heightmap(base.with_overrides(["process.compensation='none'"]))
    cfg = InterferometerConfig(pixel=0.002, field_of_view=(0.101, 0.101, 0.299, 0.299),
                               noise=False, subsamples=1, reference_height=0.0)
    iz = render_interferogram(hz, cfg)
    inn = render_interferogram(hn, cfg)
    sl = (slice(1, 100), slice(1, 100))  # camera pixels sit on height-map pixels 1..99
    overcut = (hn.machined - hz.machined)[sl] * 1e6  # nm, < 0 where the uncompensated path cuts deeper
    # the renders see the machined surfaces: the height difference is the overcut
    np.testing.assert_allclose((inn.height_true - iz.height_true) * 1e6, overcut, atol=0.05)
    d_i = np.abs(iz.frames - inn.frames).mean(axis=0)
    deep = overcut < -20.0
    same = np.abs(overcut) < 0.5
    assert deep.mean() > 0.3 and same.sum() > 20
    assert d_i[deep].mean() > 0.1
    assert d_i[same].mean() < 0.01
