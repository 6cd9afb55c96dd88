"""A sweep file's ``[run] render`` takes what ``render --kind`` takes, from the instrument
registry: a newly registered instrument included, an unknown name refused in one line that
lists the registered ones."""

from __future__ import annotations

import pytest

from render_inspect.batch import read_sweep
from render_inspect.core.errors import InputError
from render_inspect.core.section import Section
from render_inspect.instruments import _registry as instruments_registry
from render_inspect.instruments import height_instrument, register_instrument
from render_inspect.pipeline import render_kinds

SWEEP = """scene = "sts_sinusoidal_grid"
[grid]
"tool.nose_radius" = [0.5, 1.0]
[run]
render = "{render}"
measure = {measure}
"""


class _ProbeConfig(Section):
    tip_radius: float = 0.01


def _read(tmp_path, render, measure="false"):
    f = tmp_path / "s.toml"
    f.write_text(SWEEP.format(render=render, measure=measure))
    return read_sweep(f, render_kinds=render_kinds(), frames_kind=height_instrument().name)


def test_a_registered_instrument_is_a_sweep_render_choice(tmp_path, monkeypatch):
    with pytest.raises(InputError, match=r"run\.render: must be one of 'none', "
                                         r"'interferometer', 'diffuse' or 'all'; received 'probe'"):
        _read(tmp_path, "probe")
    monkeypatch.setitem(instruments_registry._INSTRUMENTS, "probe", None)  # undone after
    register_instrument("probe", _ProbeConfig, render=lambda *a, **k: None,
                        write=lambda *a, **k: ({}, {}))
    assert "probe" in render_kinds()
    assert _read(tmp_path, "probe").run.render == "probe"
    # measuring reads the frames instrument's interferogram: only it (or all) will do
    with pytest.raises(InputError, match=r"measure = true needs render = 'interferometer' or "
                                         r"'all', received render = 'probe'"):
        _read(tmp_path, "probe", measure="true")
    assert _read(tmp_path, "all", measure="true").run.measure
