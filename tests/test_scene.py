"""Scene files: validation names the key, the allowed range and the value."""

from pathlib import Path

import pytest

from render_inspect.errors import SceneError
from render_inspect.scene import load_scene, scene_from_dict

REPO = Path(__file__).resolve().parents[1]
GRID = REPO / "scenes" / "sts_sinusoidal_grid.toml"


def test_shipped_scenes_load():
    for p in sorted((REPO / "scenes").glob("*.toml")):
        scene = load_scene(p)
        assert scene.name


def test_unknown_key_is_named(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(GRID.read_text().replace("[tool]", "[tool]\nnose_radiuss = 1.0"))
    with pytest.raises(SceneError, match=r"tool\.nose_radiuss: unknown key"):
        load_scene(p)


@pytest.mark.parametrize("override, hint", [
    ("simulation.pixl=0.001", "did you mean 'pixel'?"),
    ("simulaton=0.001", "did you mean 'simulation'?"),
    ("design.amplitud_x=0.001", "did you mean 'amplitude_x' or 'amplitude_y'?"),
    ("machine.x.bandwith_hz=3", "did you mean 'bandwidth_hz'?"),
    ("tool.zzz=1", "keys here: clearance_angle_deg, contact_duty_cycle, edge_profile, "
                   "edge_scale, included_angle_deg, nose_radius, rake_angle_deg, waviness, wear, "
                   "wear_scale"),
])
def test_unknown_key_gets_the_key_meant(override, hint):
    with pytest.raises(SceneError) as e:
        load_scene(GRID, [override])
    assert f"{override.split('=')[0]}: unknown key" in str(e.value)
    assert str(e.value).endswith(hint)


def test_negative_radius_names_key_range_and_value():
    with pytest.raises(SceneError) as e:
        load_scene(GRID, ["tool.nose_radius=-0.5"])
    msg = str(e.value)
    assert "tool.nose_radius" in msg and "in (0, 50]" in msg and "-0.5" in msg


def test_feed_per_rev_larger_than_nose_radius():
    with pytest.raises(SceneError, match="feed per revolution.*tool.nose_radius"):
        load_scene(GRID, ["process.feed_mm_per_min=50"])  # 1 mm/rev > 0.514 mm


def test_empty_region():
    with pytest.raises(SceneError, match="simulation.region"):
        load_scene(GRID, ["simulation.region=[0.5, 0.0, 0.5, 1.0]"])


def test_wrong_type():
    with pytest.raises(SceneError, match="process.spindle_rpm"):
        load_scene(GRID, ["process.spindle_rpm='fast'"])


def test_set_overrides_any_key_with_toml_values():
    s = load_scene(GRID, ["process.spindle_rpm=100", "process.compensation='none'",
                          "simulation.region=[0, 0, 0.1, 0.1]"])
    assert s.process.spindle_rpm == 100
    assert s.process.compensation == "none"
    assert s.simulation.region == (0, 0, 0.1, 0.1)
    s2 = s.with_overrides(["tool.nose_radius=0.25"])
    assert s2.tool.nose_radius == 0.25 and s.tool.nose_radius == 0.514


def test_bad_override_syntax():
    with pytest.raises(SceneError, match="section.key=value"):
        load_scene(GRID, ["process.spindle_rpm"])


def test_unknown_design_type():
    with pytest.raises(SceneError, match="design"):
        scene_from_dict({"design": {"type": "banana"}})


def test_missing_file():
    with pytest.raises(SceneError, match="not found"):
        load_scene("/nonexistent/scene.toml")


@pytest.mark.parametrize("override, words", [
    # an end that :g would round is shown with every digit (6.28319 would call 6.283186
    # out of a range that seems to hold it)
    ("render.interferometer.step_rad=6.283186", "in (0, 6.283185307179586); received 6.283186"),
    # the cap on a number without a stated end keeps the end the key does state
    ("process.inner_radius=2e9", "process.inner_radius: must be within [0, 1e+09], received"),
    ("process.inner_radius=-1", "process.inner_radius: must be a finite number in [0, 1e+09]"),
    # the items of an array are checked when the scene is read, each named
    ("machine.errors.radial_sync=[[0, 5.0, 0.0]]", "machine.errors.radial_sync.0.0: must be an integer in [1, 100000]"),
    ("machine.errors.axial_sync=[[2, 2e6, 0.0]]", "machine.errors.axial_sync.0.1: must be a finite number in [0, 1e+06]"),
    ("machine.errors.vibration=[[0.0, 1.0, 'x', 0.0]]", "machine.errors.vibration.0.0: must be a finite number in (0, 1e+07]"),
    ("render.interferometer.spectrum=[[550, -1]]", "render.interferometer.spectrum.0.1: must be a finite number in [0, 1e+09]"),
    ("render.interferometer.spectrum=[[550, 1], [540, 1]]", "render.interferometer.spectrum: must have strictly increasing wavelengths, received [550.0, 540.0]"),
    ("render.interferometer.spectrum=[[550, 0], [560, 0]]", "render.interferometer.spectrum: must have weights >= 0, not all zero"),
    ("render.interferometer.field_of_view=[0.04, 0.04, -0.04, -0.04]",
     "render.interferometer.field_of_view: must be [x0, y0, x1, y1] with x1 > x0 and y1 > y0"),
    # a check of the section itself names its key once
    ("render.interferometer.illumination_na=0.95", "render.interferometer.illumination_na: must be <= the objective's NA"),
    ("design={type='lenslet_rings', ring_radii=[-1.0, 0.5], counts=[1, 4], element_radius=0.1, depth=0.01}",
     "design.ring_radii.0: must be a finite number in [0, 10000]; received -1.0"),
    ("design={type='lenslet_rings', ring_radii=[0.0, 0.5], counts=[1, 0], element_radius=0.1, depth=0.01}",
     "design.counts.1: must be an integer in [1, inf); received 0"),
])
def test_a_value_out_of_range_is_refused_when_the_scene_is_read(override, words):
    with pytest.raises(SceneError) as e:
        load_scene(GRID, [override])
    msg = str(e.value)
    assert words in msg, msg
    assert "render.interferometer.render.interferometer" not in msg


def test_scene_key_reference_is_current():
    """docs/scene_keys.md is generated from the schema; regenerate it with
    ``python -m render_inspect.scene.reference > docs/scene_keys.md``."""
    from render_inspect.scene._reference import scene_reference_markdown

    doc = (Path(__file__).resolve().parents[1] / "docs" / "scene_keys.md").read_text()
    assert doc == scene_reference_markdown()
    for key in ("spindle_rpm", "nose_radius", "wavelength_nm", "amplitude_x", "region"):
        assert f"`{key}`" in doc
    # the allowed column gives the loader's limits: the cap on an open end, the items' own
    # range, every digit of an end that :g would round
    assert "| `inner_radius` | number | 0.0 | >= 0, <= 1e+09 |" in doc
    assert "| [number, number, number, number] | [-1.0, -1.0, 1.0, 1.0] | each >= -10000, <= 10000 |" in doc
    assert "> 0, < 6.283185307179586 | PSI phase step" in doc
    assert "at least 1 item, at most 10000 items, each >= 0, <= 10000 | mm, ring radii" in doc


def test_shipped_scenes_are_found_by_name():
    from render_inspect.scene import find_scene, shipped_scenes

    names = set(shipped_scenes())
    assert {"sts_sinusoidal_grid", "hts_toric_msa", "sculpt_quad_mla", "rcse_circular_array"} <= names
    assert find_scene("sts_sinusoidal_grid").name == "sts_sinusoidal_grid.toml"
    assert load_scene("sts_fig16_overcut.toml").name == "sts_fig16_overcut"
    with pytest.raises(SceneError, match="shipped scene"):
        find_scene("no_such_scene")


def test_a_table_given_with_set_changes_its_keys_and_keeps_the_others():
    s = load_scene(GRID, ["tool.nose_radius=0.3", "tool={included_angle_deg=60}"])
    assert (s.tool.nose_radius, s.tool.included_angle_deg) == (0.3, 60.0)
    base = load_scene(GRID)
    s = load_scene(GRID, ["machine={x={bandwidth_hz=40.0}}"])
    assert s.machine.x.bandwidth_hz == 40.0 and s.machine.preset == base.machine.preset
    # another type or kind: the section is replaced (the old type's keys do not apply)
    s = load_scene(GRID, ["design={type='sphere', radius=20.0}"])
    assert s.design.type == "sphere" and s.design.radius == 20.0
    # another preset too: the scene's 1.3 ms FTS delay belongs to its own machine
    hts = load_scene("hts_toric_msa")
    assert hts.machine.fts_sync_delay_s
    assert load_scene("hts_toric_msa", ["machine={preset='ideal'}"]).machine.fts_sync_delay_s is None
    # an empty table clears the section
    assert load_scene("hts_toric_msa", ["machine={}"]).machine.fts_sync_delay_s is None
