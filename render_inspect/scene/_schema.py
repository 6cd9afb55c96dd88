"""The scene schema, assembled from the registries, and the loading of scene files
(the functions :mod:`render_inspect.scene` exports)."""

from __future__ import annotations

import copy
import json
import re
import tomllib
import typing
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable

from pydantic import BaseModel, Field, ValidationError, create_model, model_validator

from ..core.annotations import annotation_bounds, unwrap_annotation
from ..core.errors import SceneError
from ..core.messages import NUMERIC_ERRORS, bound_text, shown, validation_line
from ..core.units import MIB_TO_BYTES
from ..core.section import MAX_MAGNITUDE, Section
from ..design import DesignConfig, design_types
from ..instruments import InterferometerConfig, objective_names
from ..processes import (BurrConfig, MachineConfig, MaterialConfig, ProcessConfig, RcseConfig,
                         StsProcessConfig, VibrationConfig, migrate_scene, process_kinds)
from ..processes import scene_sections as registered_sections
from ..render import DiffuseConfig
from ._metrology import MetrologyConfig
from ._render import render_config_class
from ._sections import SimulationConfig, ToolConfig
from ._types import RegisteredSections
from ._units import unit_errors, unit_warnings

__all__ = ["Scene", "load_scene", "scene_from_dict", "apply_overrides", "SceneError",
           "shipped_scenes", "find_scene", "instrument_config", "scene_sections",
           "DesignConfig", "ToolConfig", "ProcessConfig", "SimulationConfig", "RenderConfig",
           "InterferometerConfig", "DiffuseConfig", "ArtifactsConfig", "VibrationConfig",
           "BurrConfig", "MetrologyConfig", "RcseConfig", "MachineConfig", "MaterialConfig",
           "unit_warnings", "objective_names", "MAX_SCENE_BYTES", "MAX_SCENE_DEPTH"]

if TYPE_CHECKING:
    # what a type checker sees of the sections assembled from the registries (_types.py)
    from ._types import ArtifactsConfig, RenderConfig
    from ..processes import ProcessScene
else:
    #: the ``[render]`` section: registered instruments + diffuse light
    RenderConfig = render_config_class()


def _registered() -> tuple[dict, dict]:
    """(top-level section -> class, table -> {section -> class}) of the registered
    sections (``"artifacts.burrs"`` goes into the ``artifacts`` table)."""
    top: dict[str, type] = {}
    tables: dict[str, dict[str, type]] = {}
    for path, cls in registered_sections().items():
        if "." in path:
            table, name = path.split(".")
            tables.setdefault(table, {})[name] = cls
        else:
            top[path] = cls
    return top, tables


_TOP, _TABLES = _registered()
#: tables of registered sections (``[artifacts]``: process errors added to the ideal cut)
_TABLE_CLASSES = {
    # (the schema is assembled from the registries at import: mypy cannot follow it)
    table: create_model(f"{table.capitalize()}Config", __base__=Section,  # type: ignore[call-overload]
                        __doc__=f"``[{table}]``: " + ", ".join(f"``[{table}.{n}]``" for n in members),
                        **{n: (c, Field(default_factory=c)) for n, c in members.items()})
    for table, members in _TABLES.items()}
if not TYPE_CHECKING:
    #: the ``[artifacts]`` table (burrs, vibration, ...)
    ArtifactsConfig = _TABLE_CLASSES.get("artifacts")


class _SceneBase(Section):
    """A scene: the design, the tool, the process and how to simulate, render and
    characterise the part."""

    name: str = Field("scene", max_length=200, description="shown in titles and program headers")
    description: str = Field("", max_length=10_000)
    design: DesignConfig
    tool: ToolConfig = Field(default_factory=ToolConfig)
    process: ProcessConfig = Field(default_factory=StsProcessConfig)
    simulation: SimulationConfig = Field(default_factory=SimulationConfig)
    render: RenderConfig = Field(default_factory=RenderConfig)
    metrology: MetrologyConfig = Field(default_factory=MetrologyConfig)

    @model_validator(mode="before")
    @classmethod
    def _retired_keys(cls, data: Any) -> Any:
        """Rewrite retired keys into their successors (the process modules' migrations)."""
        return migrate_scene(data) if isinstance(data, dict) else data

    @model_validator(mode="after")
    def _cross_checks(self) -> _SceneBase:
        check = getattr(self.process, "check_with", None)
        if check is not None:
            check(self)  # the process kind's checks against the design and the tool
        for mistake in unit_errors(self):  # a region typed in micrometres, ...
            raise ValueError(mistake)
        return self

    def to_dict(self) -> dict:
        return self.model_dump(mode="json")

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), sort_keys=True)

    def with_overrides(self, overrides: Iterable[str]) -> "Scene":
        return scene_from_dict(apply_overrides(self.to_dict(), overrides))


if TYPE_CHECKING:
    class Scene(_SceneBase, RegisteredSections):
        """A validated scene: the sections of the schema and the registered ones."""

    def _processes_read_a_scene(scene: Scene) -> ProcessScene:
        """(checked, never run) a scene is what the processes' checks, inputs and settings
        read (:class:`~render_inspect.processes.ProcessScene`)."""
        return scene
else:
    #: the scene schema: the sections above, the tables of registered sections and the
    #: registered top-level sections (``[rcse]``, ``[machine]``, ``[material]``, ...)
    Scene = create_model(
        "Scene", __base__=_SceneBase, __doc__=_SceneBase.__doc__,
        **{t: (c, Field(default_factory=c)) for t, c in _TABLE_CLASSES.items()},
        **{n: (c, Field(default_factory=c)) for n, c in _TOP.items()})


_shown = shown
_NUMERIC_ERRORS = NUMERIC_ERRORS | {"bool_type"}


def _union_classes() -> dict:
    out = {name: entry.config for name, entry in design_types().items()}
    out.update({entry.config.__name__: entry.config for entry in process_kinds().values()})
    return out


def _expected(loc: tuple[int | str, ...]) -> str | None:
    """What a scene key accepts, e.g. "a number in (0, 20000]", from the schema."""
    unions = _union_classes()
    model: type[BaseModel] | None
    meta: list[Any]
    model, ann, meta = Scene, None, []
    for part in loc:
        if isinstance(part, str) and part in unions and ann is not None:
            model, ann, meta = unions[part], None, []
            continue
        if isinstance(part, int):
            base, _ = unwrap_annotation(ann)
            args = typing.get_args(base)
            if not args:
                return None
            ann = args[min(part, len(args) - 1)] if typing.get_origin(base) is tuple else args[0]
            ann, meta = unwrap_annotation(ann)
            model = ann if isinstance(ann, type) and issubclass(ann, BaseModel) else None
            continue
        if model is None or part not in model.model_fields:
            return None
        field = model.model_fields[part]
        ann, meta = unwrap_annotation(field.annotation)
        meta = list(field.metadata) + meta
        model = ann if isinstance(ann, type) and issubclass(ann, BaseModel) else None
    if ann not in (int, float):
        return None
    lo, hi, lo_open, hi_open = annotation_bounds(meta)
    infinite = any(getattr(m, "allow_inf_nan", None) for m in meta)  # OrInfinity
    kind = "an integer" if ann is int else "a number" if infinite else "a finite number"
    if ann is float:
        # (the cap every number field has where its key states no end: core.section)
        if lo is None:
            lo, lo_open = -MAX_MAGNITUDE, False
        if hi is None and not infinite:
            hi, hi_open = MAX_MAGNITUDE, False
    if lo is None and hi is None:
        return kind
    lo_s = "-inf" if lo is None else bound_text(lo)
    hi_s = "inf" if hi is None else bound_text(hi)
    return (f"{kind} in {'(' if lo_open or lo is None else '['}{lo_s}, {hi_s}"
            f"{')' if hi_open or (hi is None and not infinite) else ']'}")


def _model_at(loc: tuple[int | str, ...]) -> type[BaseModel] | None:
    """The schema's section (a model class) at the location ``loc`` of a validation
    error, or None where there is none (an array, a plain value)."""
    unions = _union_classes()
    model: type[BaseModel] | None = Scene
    ann = None
    for part in loc:
        if isinstance(part, str) and part in unions and ann is not None:
            model, ann = unions[part], None
            continue
        if isinstance(part, int) or model is None or part not in model.model_fields:
            return None
        ann, _ = unwrap_annotation(model.model_fields[part].annotation)
        model = ann if isinstance(ann, type) and issubclass(ann, BaseModel) else None
    return model


def _did_you_mean(loc: tuple[int | str, ...]) -> str:
    """", did you mean 'pixel'?" for an unknown key whose section has a key spelled
    alike; else the section's keys when they are few; else nothing."""
    import difflib

    if not loc or not isinstance(loc[-1], str):
        return ""
    model = _model_at(loc[:-1])
    if model is None:
        return ""
    keys = sorted(model.model_fields)
    close = difflib.get_close_matches(loc[-1], keys, n=2, cutoff=0.6)
    if close:
        return "; did you mean " + " or ".join(repr(k) for k in close) + "?"
    if len(keys) <= 12:
        return "; keys here: " + ", ".join(keys)
    return ""


def _format_error(err: ValidationError, source: str) -> SceneError:
    """The errors of a validation as one line each in the scene's words
    (:func:`~render_inspect.core.messages.validation_line`): the dotted key, what it
    accepts, the value received.  The values missing from an array of fixed length are
    said once ("must hold 4 values")."""
    tags = _union_tags()
    lines: list[str] = []
    short: dict[str, tuple[int, Any]] = {}
    for e in err.errors():
        loc = tuple(p for p in e["loc"] if not (isinstance(p, str) and p in tags))
        if e["type"] == "missing" and loc and isinstance(loc[-1], int):
            parent = ".".join(str(p) for p in loc[:-1])
            short[parent] = (max(short.get(parent, (0,))[0], loc[-1] + 1), e.get("input"))
            continue
        expected = _expected(e["loc"]) if e["type"] in _NUMERIC_ERRORS else None
        key, text = validation_line(e, key=".".join(str(p) for p in loc), expected=expected,
                                    tags=sorted(design_types()))
        if e["type"] == "extra_forbidden":
            text += _did_you_mean(e["loc"])
        lines.append(f"{key or '(top level)'}: {text}")
    for parent, (n, inp) in short.items():
        inp = list(inp) if isinstance(inp, tuple) else inp
        lines.append(f"{parent}: must hold {n} values; received {_shown(inp)}")
    if len(lines) == 1:
        return SceneError(f"invalid scene {source}: {lines[0]}")
    return SceneError(f"invalid scene {source} ({len(lines)} errors):\n"
                      + "\n".join(f"  {line}" for line in lines))


def _union_tags() -> set:
    """Names pydantic puts into error locations for the members of a union."""
    tags = set(design_types())
    tags |= {entry.config.__name__ for entry in process_kinds().values()}
    return tags


def scene_from_dict(data: dict, source: str = "(dict)") -> Scene:
    """Validate a scene given as a dictionary (the tables of a scene file); ``source`` names
    it in the messages."""
    if not isinstance(data, dict):
        raise SceneError(f"invalid scene {source}: expected a table of sections, received "
                         f"{type(data).__name__}")
    _check_depth(data, f"scene {source}")
    try:
        return Scene.model_validate(data)
    except ValidationError as err:
        raise _format_error(err, source) from None


#: largest scene file read, bytes
MAX_SCENE_BYTES = 4 * MIB_TO_BYTES
#: deepest nesting of tables and arrays in a scene (the schema needs 5)
MAX_SCENE_DEPTH = 32


def _depth(data: object) -> int:
    """Nesting depth of dicts and lists in ``data`` (iterative: safe on any depth)."""
    deepest = 0
    stack = [(data, 1)]
    children: Iterable[Any]
    while stack:
        node, d = stack.pop()
        if isinstance(node, dict):
            children = node.values()
        elif isinstance(node, (list, tuple)):
            children = node
        else:
            continue
        deepest = max(deepest, d)
        if deepest > MAX_SCENE_DEPTH:
            return deepest
        stack.extend((c, d + 1) for c in children)
    return deepest


def _check_depth(data: object, what: str) -> None:
    if _depth(data) > MAX_SCENE_DEPTH:
        raise SceneError(f"{what} nests tables/arrays deeper than {MAX_SCENE_DEPTH} levels; "
                         f"a scene needs at most a few")


def _check_text(key: str, text: str) -> None:
    bad = next((c for c in text if (ord(c) < 32 and c != "\t") or 0x7f <= ord(c) < 0xa0
                or c in "\u2028\u2029"), None)
    if bad is not None:
        raise SceneError(f"--set {key}: the value must be one line of text without control "
                         f"characters (write a line break inside a TOML string as \\n), received "
                         f"{_shown(text)}")


def _parse_value(text: str, key: str = "value") -> Any:
    """A ``--set`` value: one TOML value (a bare word is taken as a string)."""
    _check_text(key, text)
    try:
        parsed = tomllib.loads(f"v = {text}")
    except tomllib.TOMLDecodeError:
        if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_.\-]*", text):
            return text  # a bare word is taken as a string
        raise SceneError(f"--set {key}: {_shown(text)} is not a TOML value (quote text: "
                         f"{key}='...'; numbers like 100 or 0.5; arrays like [0, 0, 1, 1])") from None
    except RecursionError:
        raise SceneError(f"--set {key}: the value nests arrays too deeply") from None
    if set(parsed) != {"v"}:
        raise SceneError(f"--set {key}: give one value, received {_shown(text)}")
    _check_depth(parsed, f"--set {key}")
    return parsed["v"]


def apply_overrides(data: dict, overrides: Iterable[str] | None) -> dict:
    """Return a copy of ``data`` with ``section.key=value`` overrides (TOML values) applied
    (a table merged into the table it names: :func:`_merged`)."""
    _check_depth(data, "the scene")
    data = copy.deepcopy(data)
    if isinstance(overrides, str):
        overrides = [overrides]
    for item in overrides or ():
        if not isinstance(item, str):
            raise SceneError(f"--set expects text section.key=value, received {_shown(item)}")
        if "=" not in item:
            raise SceneError(f"--set expects section.key=value, received {_shown(item)}")
        key, text = item.split("=", 1)
        key = key.strip()
        parts = key.split(".")
        if not all(re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", p) for p in parts) or len(parts) > 8:
            raise SceneError(f"--set key must be a dotted path like process.spindle_rpm, "
                             f"received {_shown(key)}")
        node = data
        for p in parts[:-1]:
            nxt = node.get(p)
            if nxt is None:
                nxt = node[p] = {}
            if not isinstance(nxt, dict):
                raise SceneError(f"--set {key}: {p!r} is a value, not a section")
            node = nxt
        node[parts[-1]] = _merged(node.get(parts[-1]), _parse_value(text.strip(), key))
    return data


#: the keys that choose what a table is (``design.type``, ``process.kind``, a machine's or
#: a material's ``preset``): a table naming another one replaces the old one
_CHOOSERS = ("type", "kind", "preset")


def _merged(old: Any, new: Any) -> Any:
    """The value a ``--set`` leaves: a table given for a table is merged into it, key by
    key (``--set 'tool={included_angle_deg=60}'`` changes that key and keeps the others,
    those set by earlier options too), unless it chooses another ``type``, ``kind`` or
    ``preset`` (the old table's keys belong to the old one) or is empty (``{}`` clears the
    table): then it replaces the table; any other value replaces the old one."""
    if not (isinstance(old, dict) and isinstance(new, dict)) or not new:
        return new
    if any(k in new and k in old and new[k] != old[k] for k in _CHOOSERS):
        return new
    out = dict(old)
    for k, v in new.items():
        out[k] = _merged(old.get(k), v)
    return out


def instrument_config(objective: str = "20x", mode: str = "psi",
                      overrides: Iterable[str] | None = None) -> InterferometerConfig:
    """``[render.interferometer]`` for ``objective`` and ``mode`` with ``KEY=VALUE``
    overrides (TOML values; the ``render.interferometer.`` prefix is optional), validated
    with the scene's messages (``render-inspect characterise --set``)."""
    items = []
    for item in overrides or ():
        key = item.split("=", 1)[0].strip()
        if "=" in item and not key.startswith("render.interferometer."):
            if key.split(".")[0] in scene_sections():
                raise SceneError(f"--set takes the instrument's keys here ([render.interferometer], "
                                 f"e.g. numerical_aperture=0.5), received {_shown(key)}")
            item = f"render.interferometer.{item.strip()}"
        items.append(item)
    data = {"design": {"type": "plane"},
            "render": {"interferometer": {"objective": objective, "mode": mode}}}
    scene = scene_from_dict(apply_overrides(data, items), "(characterise)")
    return scene.render.interferometer


def shipped_scenes() -> dict[str, Path]:
    """The scenes that ship with the package (the seed papers' cases): name -> path."""
    # the package by its own name (render_inspect, or the copy inside the Blender extension)
    root = resources.files(__package__.rpartition(".")[0]) / "scenes"
    return {p.name[:-5]: Path(str(p)) for p in sorted(root.iterdir(), key=lambda q: q.name)
            if p.name.endswith(".toml")}


def find_scene(name_or_path: str | Path) -> Path:
    """A scene file: ``name_or_path`` itself when it is a file, else the shipped scene of
    that name (``sts_sinusoidal_grid`` or ``sts_sinusoidal_grid.toml``; a folder of that
    name in the working folder does not hide it)."""
    text = str(name_or_path)
    if not text.strip():
        raise SceneError("scene: give a scene file (.toml) or the name of a shipped scene, "
                         "received an empty name")
    if "\x00" in text:
        raise SceneError(f"scene: the name contains a NUL character, received {_shown(text)}")
    path = Path(name_or_path)
    try:
        if path.is_file():
            return path
        shipped = shipped_scenes()
        key = path.name[:-5] if path.name.endswith(".toml") else path.name
        # (a folder of that name, an output folder named after the scene, is not a scene:
        # the bare name still means the shipped scene)
        if path.parent == Path(".") and key in shipped:
            return shipped[key]
        if path.is_dir():
            raise SceneError(f"scene: {text!r} is a folder; give a scene file (.toml) or the "
                             f"name of a shipped scene ({', '.join(shipped)})")
        if path.exists():
            raise SceneError(f"scene: {text!r} is not a regular file (a device, pipe or "
                             f"socket); give a scene file (.toml)")
    except OSError as err:  # a name too long, a path through a file, no permission
        raise SceneError(f"scene: cannot use {_shown(text)} ({err.strerror or err})") from None
    raise SceneError(f"scene file not found: {text!r}; give a path to a .toml file or the "
                     f"name of a shipped scene ({', '.join(shipped)})")


def read_scene_text(path: Path) -> str:
    """The text of a scene file: at most :data:`MAX_SCENE_BYTES`, UTF-8, no NUL bytes."""
    try:
        with open(path, "rb") as fh:
            raw = fh.read(MAX_SCENE_BYTES + 1)
    except OSError as err:
        raise SceneError(f"scene file {str(path)!r} cannot be read ({err.strerror or err})") from None
    if len(raw) > MAX_SCENE_BYTES:
        raise SceneError(f"scene file {str(path)!r} is larger than {MAX_SCENE_BYTES // MIB_TO_BYTES} MiB; "
                         f"a scene is a short TOML text")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        line = raw[:err.start].count(b"\n") + 1
        raise SceneError(f"scene file {str(path)!r} is not UTF-8 text (byte {err.start}, line "
                         f"{line}: {raw[err.start:err.start + 1]!r}); save it as UTF-8") from None
    if text.startswith("\ufeff"):  # a byte-order mark some editors write: not part of the text
        text = text[1:]
    if "\x00" in text:
        raise SceneError(f"scene file {str(path)!r} contains NUL bytes: it is a binary file, not "
                         f"a TOML scene")
    return text


def scene_sections() -> tuple[str, ...]:
    """The scene's sections (``design``, ``tool``, ... ``material``): what a dotted scene
    key such as ``tool.nose_radius`` starts with."""
    return tuple(k for k in Scene.model_fields if k not in ("name", "description"))


def load_scene(path: str | Path, overrides: Iterable[str] | None = None) -> Scene:
    """Read a TOML scene file (or a shipped scene by name), apply ``--set`` overrides and
    validate."""
    path = find_scene(path)
    text = read_scene_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SceneError(f"scene file {str(path)!r} is not valid TOML: {err}") from None
    except RecursionError:
        raise SceneError(f"scene file {str(path)!r} nests tables/arrays deeper than "
                         f"{MAX_SCENE_DEPTH} levels") from None
    data = apply_overrides(data, overrides)
    # relative heightmap paths are relative to the scene file
    _resolve_paths(data.get("design"), path.parent)
    _resolve_edge_path(data.get("tool"), path.parent)
    _resolve_program(data.get("process"), path.parent)
    return scene_from_dict(data, source=str(path))


def _resolve_edge_path(tool: object, base: Path) -> None:
    """``[tool] edge_profile`` relative to the scene file."""
    if isinstance(tool, dict) and isinstance(tool.get("edge_profile"), str) \
            and "\x00" not in tool["edge_profile"] and tool["edge_profile"].strip():
        p = Path(tool["edge_profile"])
        if not p.is_absolute():
            tool["edge_profile"] = str((base / p).resolve())


def _resolve_program(process: object, base: Path) -> None:
    """``process.program`` (a machine program file) relative to the scene file."""
    if isinstance(process, dict) and isinstance(process.get("program"), str) \
            and process["program"] and "\x00" not in process["program"]:
        p = Path(process["program"]).expanduser()
        if not p.is_absolute():
            process["program"] = str((base / p).resolve())


def _resolve_paths(design: object, base: Path) -> None:
    if not isinstance(design, dict):
        return
    if design.get("type") == "heightmap" and isinstance(design.get("path"), str) \
            and "\x00" not in design["path"]:
        p = Path(design["path"])
        if not p.is_absolute():
            design["path"] = str((base / p).resolve())
    for k in ("base", "feature"):
        _resolve_paths(design.get(k), base)

