"""Where a user names an instrument, the names come from the instrument registry: ``render
--kind`` takes a newly registered instrument (and refuses it before it is registered), and
``fit`` images through the registered instrument that records interferometer frames,
under that instrument's own scene section (the sweep file's ``[run] render``:
tests/test_sweep_render_kinds.py)."""

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
