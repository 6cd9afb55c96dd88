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


def test_scene_key_reference_is_current():
    """docs/scene_keys.md is generated from the schema; regenerate it with
    ``python -m render_inspect.scene.reference > docs/scene_keys.md``."""
    from render_inspect.scene._reference import scene_reference_markdown

    doc = (Path(__file__).resolve().parents[1] / "docs" / "scene_keys.md").read_text()
    assert doc == scene_reference_markdown()
    for key in ("spindle_rpm", "nose_radius", "wavelength_nm", "amplitude_x", "region"):
        assert f"`{key}`" in doc


def test_shipped_scenes_are_found_by_name():
    from render_inspect.scene import find_scene, shipped_scenes

    names = set(shipped_scenes())
    assert {"sts_sinusoidal_grid", "hts_toric_msa", "sculpt_quad_mla", "rcse_circular_array"} <= names
    assert find_scene("sts_sinusoidal_grid").name == "sts_sinusoidal_grid.toml"
    assert load_scene("sts_fig16_overcut.toml").name == "sts_fig16_overcut"
    with pytest.raises(SceneError, match="shipped scene"):
        find_scene("no_such_scene")
