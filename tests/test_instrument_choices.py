"""Where a user names an instrument, the names come from the instrument registry: ``render
--kind`` takes a newly registered instrument (and refuses it before it is registered), and
``fit`` images through the registered instrument that records interferometer frames,
under that instrument's own scene section (the sweep file's ``[run] render``:
tests/test_sweep_render_kinds.py); the objective presets that ``characterise``, ``fit`` and
``render.interferometer.objective`` take come from the objective registry."""

from __future__ import annotations

import pytest

from render_inspect.cli import build_parser
from render_inspect.core.section import Section
from render_inspect.instruments import _registry as instruments_registry
from render_inspect.instruments import height_instrument, register_instrument
from render_inspect.pipeline._fit_model import ForwardModel


class _ProbeConfig(Section):
    tip_radius: float = 0.01


def _render_args(kind):
    return build_parser().parse_args(["render", "sts_sinusoidal_grid", "--out", "x", "--kind", kind])


def test_render_kind_takes_a_newly_registered_instrument(monkeypatch, capsys):
    with pytest.raises(SystemExit) as err:
        _render_args("probe")
    assert err.value.code == 2
    assert "invalid choice: 'probe'" in capsys.readouterr().err
    monkeypatch.setitem(instruments_registry._INSTRUMENTS, "probe", None)  # undone after
    register_instrument("probe", _ProbeConfig, render=lambda *a, **k: None,
                        write=lambda *a, **k: ({}, {}))
    assert _render_args("probe").kind == "probe"
    assert _render_args("interferometer").kind == "interferometer"


def test_render_kind_forgets_an_unregistered_instrument():
    """The registry is as it was after the test above (its entry removed again)."""
    assert "probe" not in instruments_registry.instrument_types()
    with pytest.raises(SystemExit):
        _render_args("probe")


def _model():
    base = {"simulation": {"region": [0, 0, 1, 1], "pixel": 0.01}}
    return ForwardModel(base, None, [0.0, 0.0, 0.1, 0.1], 0.002, {"objective": "20x", "noise": True}, 3)


def test_fit_evaluations_use_the_registered_frames_instrument(monkeypatch):
    from render_inspect.instruments import InterferometerConfig, render_interferogram

    # the shipped frames instrument is the interference microscope: fit's evaluations run
    # the very function and settings class they named before the registry answered
    assert height_instrument().render is render_interferogram
    assert height_instrument().config is InterferometerConfig
    assert _model().task({})["scene"]["render"] == {"interferometer": {"objective": "20x",
                                                                       "noise": False}}
    # another instrument recording interferometer frames takes the interferometer's place
    entries = dict(instruments_registry._INSTRUMENTS)
    frames = height_instrument()
    monkeypatch.setattr(instruments_registry, "_INSTRUMENTS",
                        {k: v for k, v in entries.items() if k != frames.name})
    register_instrument("probe", frames.config, render=frames.render, write=frames.write,
                        field=frames.field, memory=frames.memory, frames=True)
    assert height_instrument().name == "probe"
    task = _model().task({})
    assert task["scene"]["render"] == {"probe": {"objective": "20x", "noise": False}}
    drawn = _model().draw({}, 1)
    assert drawn["scene"]["render"] == {"probe": {"objective": "20x", "noise": True}}


# ------------------------------------------------------------------ objectives
def _characterise_args(name):
    return build_parser().parse_args(["characterise", "--objective", name, "--out", "x"])


def test_a_registered_objective_is_a_choice_of_the_scene_and_the_command_line(monkeypatch, capsys):
    """A 40x preset (NA 0.6, 0.45 mm field on 1024 pixels) registered here: characterise
    and fit take it on the command line (and refused it before), the scene takes it, and
    the interferometer images with its numbers; the registry is restored afterwards."""
    from render_inspect.instruments import (OBJECTIVES, Objective, objective, objective_names,
                                            register_objective)
    from render_inspect.instruments import _objectives
    from render_inspect.scene import instrument_config

    with pytest.raises(SystemExit) as err:
        _characterise_args("40x")
    assert err.value.code == 2 and "invalid choice: '40x'" in capsys.readouterr().err
    monkeypatch.setitem(_objectives._OBJECTIVES._entries, "40x", None)  # undone after
    o = register_objective(Objective("40x", magnification=40.0, numerical_aperture=0.6,
                                     pixel=0.45 / 1024, field_of_view=0.45, design="mirau"))
    assert OBJECTIVES["40x"] is o  # the read-only view follows the registry
    assert objective_names() == ["2.5x", "5x", "10x", "20x", "40x", "50x", "100x"]
    assert _characterise_args("40x").objective == "40x"
    fit = build_parser().parse_args(["fit", "m.exr", "--scene", "s", "--free", "tool.nose_radius",
                                     "--out", "x", "--objective", "40x"])
    assert fit.objective == "40x"
    cfg = instrument_config("40x")
    assert cfg.objective == "40x"
    assert objective("40x", numerical_aperture=0.5).numerical_aperture == 0.5
    # the preset's NA bounds the condenser's, as the built-in presets' do
    with pytest.raises(Exception, match="illumination_na"):
        instrument_config("40x", overrides=["illumination_na=0.65"])


def test_an_objective_preset_is_checked_when_registered():
    from render_inspect.errors import InputError
    from render_inspect.instruments import OBJECTIVES, Objective, register_objective

    with pytest.raises(InputError, match="numerical_aperture"):
        register_objective(Objective("bad", 10.0, 1.2, 0.001, 1.0))
    with pytest.raises(InputError, match="design"):
        register_objective(Objective("bad", 10.0, 0.3, 0.001, 1.0, design="fizeau"))
    with pytest.raises(InputError, match="must be an Objective"):
        register_objective({"name": "bad"})
    assert "bad" not in OBJECTIVES and "40x" not in OBJECTIVES  # (the test above undone)
