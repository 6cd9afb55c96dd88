"""Scene files: TOML, validated on load.

>>> scene = load_scene("scenes/sts_sinusoidal_grid.toml", overrides=["process.spindle_rpm=100"])

Unknown keys, wrong types and non-physical values raise :class:`SceneError` naming the
key (dotted path), what is allowed and the value received.
"""

from __future__ import annotations

import copy
import json
import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Iterable

from pydantic import Field, ValidationError, model_validator

from ..core.errors import SceneError
from ..core.section import Section
from ..design import DesignConfig, design_types
from ..instruments import InterferometerConfig
from ..processes import ProcessConfig, StsProcessConfig, process_kinds
from ..render import DiffuseConfig
from ._artifacts import ArtifactsConfig, BurrConfig, ServoConfig, VibrationConfig
from ._machine import MachineConfig, MaterialConfig
from ._metrology import MetrologyConfig
from ._rcse import RcseConfig
from ._render import render_config_class
from ._sections import SimulationConfig, ToolConfig

__all__ = ["Scene", "load_scene", "scene_from_dict", "apply_overrides", "SceneError",
           "shipped_scenes", "find_scene", "instrument_config", "scene_sections",
           "DesignConfig", "ToolConfig", "ProcessConfig", "SimulationConfig", "RenderConfig",
           "InterferometerConfig", "DiffuseConfig", "ArtifactsConfig", "ServoConfig",
           "VibrationConfig", "BurrConfig", "MetrologyConfig", "RcseConfig", "MachineConfig",
           "MaterialConfig"]

#: the ``[render]`` section: registered instruments + diffuse light
RenderConfig = render_config_class()


class Scene(Section):
    name: str = "scene"
    description: str = ""
    design: DesignConfig
    tool: ToolConfig = Field(default_factory=ToolConfig)
    process: ProcessConfig = Field(default_factory=StsProcessConfig)
    simulation: SimulationConfig = Field(default_factory=SimulationConfig)
    render: RenderConfig = Field(default_factory=RenderConfig)
    artifacts: ArtifactsConfig = Field(default_factory=ArtifactsConfig)
    metrology: MetrologyConfig = Field(default_factory=MetrologyConfig)
    rcse: RcseConfig = Field(default_factory=RcseConfig)
    machine: MachineConfig = Field(default_factory=MachineConfig)
    material: MaterialConfig = Field(default_factory=MaterialConfig)

    @model_validator(mode="after")
    def _cross_checks(self):
        check = getattr(self.process, "check_with", None)
        if check is not None:
            check(self)  # the process kind's checks against the design and the tool
        return self

    def to_dict(self) -> dict:
        return self.model_dump(mode="json")

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    def with_overrides(self, overrides: Iterable[str]) -> "Scene":
        return scene_from_dict(apply_overrides(self.to_dict(), overrides))


def _format_error(err: ValidationError, source: str) -> SceneError:
    tags = _union_tags()
    lines = []
    for e in err.errors():
        loc = ".".join(str(p) for p in e["loc"] if not (isinstance(p, str) and p in tags))
        msg = e["msg"]
        if e["type"] == "extra_forbidden":
            msg = "unknown key (not allowed here; check the spelling)"
        elif msg.startswith("Value error, "):
            msg = msg[len("Value error, "):]
            m = re.match(r"^([a-z_][a-z0-9_]*) (must|is|are) ", msg)
            if m:  # a model-level check about one of its keys: name the key in full
                loc = f"{loc}.{m.group(1)}" if loc else m.group(1)
                msg = msg[len(m.group(1)) + 1:]
        inp = e.get("input")
        got = "" if e["type"] in ("missing",) or isinstance(inp, dict) else f"; received {inp!r}"
        lines.append(f"  {loc or '(top level)'}: {msg}{got}")
    return SceneError(f"invalid scene {source}:\n" + "\n".join(lines))


def _union_tags() -> set:
    """Names pydantic puts into error locations for the members of a union."""
    tags = set(design_types())
    tags |= {entry.config.__name__ for entry in process_kinds().values()}
    return tags


def scene_from_dict(data: dict, source: str = "(dict)") -> Scene:
    try:
        return Scene.model_validate(data)
    except ValidationError as err:
        raise _format_error(err, source) from None


def _parse_value(text: str):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # a bare word is taken as a string


def apply_overrides(data: dict, overrides: Iterable[str] | None) -> dict:
    """Return a copy of ``data`` with ``section.key=value`` overrides (TOML values) applied."""
    data = copy.deepcopy(data)
    for item in overrides or ():
        if "=" not in item:
            raise SceneError(f"--set expects section.key=value, received {item!r}")
        key, text = item.split("=", 1)
        key = key.strip()
        parts = key.split(".")
        if not all(parts):
            raise SceneError(f"--set key must be a dotted path like process.spindle_rpm, received {key!r}")
        node = data
        for p in parts[:-1]:
            nxt = node.get(p)
            if nxt is None:
                nxt = node[p] = {}
            if not isinstance(nxt, dict):
                raise SceneError(f"--set {key}: {p!r} is a value, not a section")
            node = nxt
        node[parts[-1]] = _parse_value(text.strip())
    return data


def instrument_config(objective: str = "20x", mode: str = "psi",
                      overrides: Iterable[str] | None = None) -> InterferometerConfig:
    """``[render.interferometer]`` for ``objective`` and ``mode`` with ``KEY=VALUE``
    overrides (TOML values; the ``render.interferometer.`` prefix is optional), validated
    with the scene's messages (``render-inspect characterise --set``)."""
    items = []
    for item in overrides or ():
        key = item.split("=", 1)[0].strip()
        if "=" in item and not key.startswith("render.interferometer."):
            item = f"render.interferometer.{item.strip()}"
        items.append(item)
    data = {"design": {"type": "plane"},
            "render": {"interferometer": {"objective": objective, "mode": mode}}}
    return scene_from_dict(apply_overrides(data, items), "(characterise)").render.interferometer


def shipped_scenes() -> dict[str, Path]:
    """The scenes that ship with the package (the seed papers' cases): name -> path."""
    root = resources.files("render_inspect") / "scenes"
    return {p.name[:-5]: Path(str(p)) for p in sorted(root.iterdir(), key=lambda q: q.name)
            if p.name.endswith(".toml")}


def find_scene(name_or_path) -> Path:
    """A scene file: ``name_or_path`` itself when it is a file, else the shipped scene of
    that name (``sts_sinusoidal_grid`` or ``sts_sinusoidal_grid.toml``)."""
    path = Path(name_or_path)
    if path.is_file():
        return path
    shipped = shipped_scenes()
    key = path.name[:-5] if path.name.endswith(".toml") else path.name
    if path.parent == Path(".") and key in shipped:
        return shipped[key]
    if path.is_dir():
        raise SceneError(f"scene: {str(path)!r} is a folder; give a scene file (.toml) or the "
                         f"name of a shipped scene ({', '.join(shipped)})")
    raise SceneError(f"scene file not found: {str(path)!r}; give a path to a .toml file or the "
                     f"name of a shipped scene ({', '.join(shipped)})")


def scene_sections() -> tuple[str, ...]:
    """The scene's sections (``design``, ``tool``, ... ``material``): what a dotted scene
    key such as ``tool.nose_radius`` starts with."""
    return tuple(k for k in Scene.model_fields if k not in ("name", "description"))


def load_scene(path: str | Path, overrides: Iterable[str] | None = None) -> Scene:
    """Read a TOML scene file (or a shipped scene by name), apply ``--set`` overrides and
    validate."""
    path = find_scene(path)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"scene file {str(path)!r} is not valid TOML: {err}") from None
    data = apply_overrides(data, overrides)
    # relative heightmap paths are relative to the scene file
    _resolve_paths(data.get("design"), path.parent)
    return scene_from_dict(data, source=str(path))


def _resolve_paths(design, base: Path):
    if not isinstance(design, dict):
        return
    if design.get("type") == "heightmap" and isinstance(design.get("path"), str):
        p = Path(design["path"])
        if not p.is_absolute():
            design["path"] = str((base / p).resolve())
    for k in ("base", "feature"):
        _resolve_paths(design.get(k), base)
