"""The registry helper every registry of named scene variants is built on (design types,
process kinds, objective presets)."""

from typing import Literal

import pytest
from pydantic import BaseModel

from render_inspect.core.plugins import Registry, literal_values
from render_inspect.design import design_types
from render_inspect.errors import SceneError
from render_inspect.processes import process_kinds


class _A(BaseModel):
    kind: Literal["a", "alpha"] = "a"


class _B(BaseModel):
    kind: Literal["b"] = "b"


class _Entry:
    def __init__(self, config):
        self.config = config


def test_entries_under_their_literal_names_and_a_clear_lookup_error():
    reg = Registry("thing.kind")
    a = reg.add(literal_values(_A, "kind"), _Entry(_A))
    b = reg.add(literal_values(_B, "kind"), _Entry(_B))
    assert reg.entries() == {"a": a, "alpha": a, "b": b}
    assert reg.lookup("alpha") is a and reg.get("zeta") is None and "b" in reg
    assert reg.configs() == [_A, _B]  # each schema class once, in registration order
    with pytest.raises(SceneError, match=r"^thing\.kind must be one of \['a', 'alpha', 'b'\], "
                                         r"received 'zeta'$"):
        reg.lookup("zeta")
    b2 = reg.add(["b"], _Entry(_B))  # a name registered again is replaced
    assert reg.lookup("b") is b2


def test_the_union_is_made_once_and_again_after_a_registration():
    reg = Registry("thing.kind")
    reg.add(["a"], _Entry(_A))
    made, after = [], []
    make = (lambda configs: made.append(tuple(configs)) or len(made))
    first = reg.union(make, lambda union, configs: after.append(union))
    assert reg.union(make) == first == 1 and made == [(_A,)] and after == [1]
    reg.add(["b"], _Entry(_B))
    assert reg.union(make) == 2 and made[-1] == (_A, _B)


def test_the_design_and_process_registries_use_it():
    assert {"sinusoidal_grid", "compound"} <= set(design_types())
    assert {"sts", "sculpt"} <= set(process_kinds())
    from render_inspect.design._registry import _DESIGNS
    from render_inspect.processes._registry import _PROCESSES

    assert isinstance(_DESIGNS, Registry) and isinstance(_PROCESSES, Registry)


def test_the_view_is_read_only_and_follows_registrations():
    reg = Registry("thing.kind")
    view = reg.view()
    assert dict(view) == {}
    a = reg.add(["a"], _Entry(_A))
    assert dict(view) == {"a": a} and view["a"] is a
    with pytest.raises(TypeError):
        view["b"] = a
