"""The static types of a scene (what mypy knows of ``Scene``, ``DesignConfig``,
``ProcessConfig``, ``RenderConfig``, ``ArtifactsConfig``) agree with the schema the
registries assemble at import, section for section and key for key: a section, key or
kind registered without its static type fails here, and so does a static type the schema
no longer has."""

from __future__ import annotations

import typing

from render_inspect.design import DesignSection, design_types
from render_inspect.instruments import instrument_types
from render_inspect.processes import ProcessSection, process_kinds, scene_sections
from render_inspect.scene import ArtifactsConfig, RenderConfig, Scene
from render_inspect.scene import _schema, _types


def _plain(annotation):
    """The classes of an annotation, without pydantic's Annotated tags and discriminators."""
    while typing.get_origin(annotation) is typing.Annotated:
        annotation = typing.get_args(annotation)[0]
    if typing.get_origin(annotation) is typing.Union:
        return frozenset(_plain(a) for a in typing.get_args(annotation))
    return annotation


def _fields(model) -> dict:
    return {name: _plain(f.annotation) for name, f in model.model_fields.items()}


def _static(cls) -> dict:
    """The annotations of a static declaration, resolved (the registered ``[artifacts]``
    table by the schema's class)."""
    hints = typing.get_type_hints(cls, localns={"ArtifactsConfig": ArtifactsConfig})
    return {name: _plain(t) for name, t in hints.items()}


def test_design_section_lists_every_design_type():
    assert _plain(DesignSection) == frozenset(e.config for e in design_types().values())
    assert _fields(Scene)["design"] == _plain(DesignSection)


def test_process_section_lists_every_process_kind():
    assert _plain(ProcessSection) == frozenset(e.config for e in process_kinds().values())
    assert _fields(Scene)["process"] == _plain(ProcessSection)


def test_render_sections_are_the_instruments_and_diffuse():
    static = _static(_types.RenderSections)
    assert static == _fields(RenderConfig)
    assert set(static) == set(instrument_types()) | {"diffuse"}
    assert all(static[n] is e.config for n, e in instrument_types().items())


def test_artifacts_sections_are_the_registered_ones():
    static = _static(_types.ArtifactsSections)
    assert static == _fields(ArtifactsConfig)
    registered = {p.split(".")[1]: c for p, c in scene_sections().items() if "." in p}
    assert static == registered


def test_scene_is_its_declared_sections_and_the_registered_ones():
    declared = _fields(_schema._SceneBase)
    registered = _static(_types.RegisteredSections)
    assert not set(declared) & set(registered)
    assert _fields(Scene) == {**declared, **registered}
    tops = {p.split(".")[0] for p in scene_sections()}
    assert set(registered) == tops


def test_the_comparison_sees_a_missing_key():
    """The comparison above can fail: a declaration without one of the schema's keys, or
    with a key the schema lacks, differs."""
    class Fewer:
        burrs: _types.BurrConfig

    class More(_types.ArtifactsSections):
        chatter: _types.BurrConfig

    assert _static(Fewer) != _fields(ArtifactsConfig)
    assert _static(More) != _fields(ArtifactsConfig)
