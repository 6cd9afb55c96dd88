"""The scene-key reference (docs/scene_keys.md), generated from the schema itself so it
cannot drift from what the loader accepts:
``python -m render_inspect.scene.reference > docs/scene_keys.md``."""

from __future__ import annotations

import enum
import types
import typing

import annotated_types as at
from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from ..processes import retired_keys
from . import Scene

__all__ = ["scene_reference_markdown"]


def _type_name(ann: typing.Any) -> str:
    origin = typing.get_origin(ann)
    args = typing.get_args(ann)
    if origin is typing.Literal:
        return " \\| ".join(f'"{a}"' if isinstance(a, str) else repr(a) for a in args)
    if origin is typing.Union or origin is types.UnionType:
        names = [_type_name(a) for a in args if a is not type(None)]
        s = " or ".join(names)
        return s + (" or none" if type(None) in args else "")
    if origin in (list, tuple):
        if origin is tuple and args and args[-1] is not Ellipsis:
            return f"[{', '.join(_type_name(a) for a in args)}]"
        return f"list of {_type_name(args[0])}" if args else "list"
    if origin is dict:
        return f"table of {_type_name(args[1])}" if len(args) == 2 else "table"
    if origin is typing.Annotated:
        return _type_name(args[0])
    if isinstance(ann, type):
        if issubclass(ann, enum.Enum):
            return " \\| ".join(f'"{m.value}"' for m in ann)
        return {"float": "number", "int": "integer", "bool": "true/false", "str": "text"}.get(
            ann.__name__, ann.__name__)
    return str(ann).replace("typing.", "")


def _range(field: FieldInfo) -> str:
    lo = hi = ""
    for m in field.metadata:
        if isinstance(m, at.Gt):
            lo = f"> {m.gt:g}"
        elif isinstance(m, at.Ge):
            lo = f">= {m.ge:g}"
        elif isinstance(m, at.Lt):
            hi = f"< {m.lt:g}"
        elif isinstance(m, at.Le):
            hi = f"<= {m.le:g}"
        elif isinstance(m, at.MinLen):
            lo = f"at least {m.min_length} items" if lo == "" else lo
        elif isinstance(m, at.MaxLen):
            hi = f"at most {m.max_length}" if hi == "" else hi
    return ", ".join(x for x in (lo, hi) if x)


def _default(field: FieldInfo) -> str:
    if field.default is not PydanticUndefined:
        d = field.default
        if d is None:
            return "none"
        if isinstance(d, bool):
            return "true" if d else "false"
        if isinstance(d, str):
            return f'"{d}"'
        if isinstance(d, (list, tuple)):
            return "[" + ", ".join(repr(v) if not isinstance(v, str) else f'"{v}"' for v in d) + "]"
        return repr(d)
    if field.default_factory is not None:
        try:
            d = field.default_factory()  # type: ignore[call-arg]  # (a section's class: no arguments)
        except TypeError:
            return "(section)"
        if isinstance(d, BaseModel):
            return "(section)"
        return repr(d)
    return "**required**"


def _is_model(ann: typing.Any) -> bool:
    return isinstance(ann, type) and issubclass(ann, BaseModel)


def _union_members(ann: typing.Any) -> list:
    while typing.get_origin(ann) is typing.Annotated:
        ann = typing.get_args(ann)[0]
    out = []
    for a in typing.get_args(ann):
        while typing.get_origin(a) is typing.Annotated:
            a = typing.get_args(a)[0]
        if _is_model(a):
            out.append(a)
    return out


def _table(model: type[BaseModel], prefix: str, lines: list, sections: list) -> None:
    rows = []
    for name, field in model.model_fields.items():
        ann = field.annotation
        if _is_model(ann):
            sections.append((f"{prefix}.{name}" if prefix else name, ann, field))
            continue
        members = _union_members(ann)
        if members:
            sections.append((f"{prefix}.{name}" if prefix else name, members, field))
            continue
        desc = (field.description or "").replace("|", "\\|")
        rows.append(f"| `{name}` | {_type_name(ann)} | {_default(field)} | {_range(field)} | {desc} |")
    if rows:
        lines += ["| key | type | default | allowed | meaning |", "|---|---|---|---|---|", *rows, ""]


def _doc(model: type[BaseModel]) -> str:
    d = (model.__doc__ or "").strip()
    if not d or d.startswith("!!!") or "A base class for creating Pydantic models" in d:
        return ""
    return " ".join(d.split()) + "\n"


def _section(path: str, model: type[BaseModel], lines: list) -> None:
    sections: list = []
    lines.append(f"## `[{path}]`\n")
    doc = _doc(model)
    if doc:
        lines.append(doc)
    _table(model, path, lines, sections)
    for sub_path, sub, field in sections:
        if isinstance(sub, list):
            _union(sub_path, sub, lines)
        else:
            _section(sub_path, sub, lines)


def _union(path: str, members: list, lines: list) -> None:
    key = "type" if "type" in members[0].model_fields else "kind"
    lines.append(f"## `[{path}]`\n")
    names = []
    for m in members:
        names += list(typing.get_args(m.model_fields[key].annotation))
    lines.append(f"`{key}` chooses one of: " + ", ".join(f'`"{n}"`' for n in names) + ".\n")
    for m in members:
        kinds = " / ".join(f'"{n}"' for n in typing.get_args(m.model_fields[key].annotation))
        lines.append(f"### `{key} = {kinds}`\n")
        doc = _doc(m)
        if doc:
            lines.append(doc)
        sections: list = []
        _table(m, path, lines, sections)
        for sub_path, sub, field in sections:
            if isinstance(sub, list):
                lines.append(f"`{sub_path.split('.')[-1]}`: a nested `[{path}]` table of any "
                             f"type above.\n")
            else:
                _section(sub_path, sub, lines)


def scene_reference_markdown() -> str:
    """Markdown reference of every scene key: type, default, allowed range, meaning."""
    lines = ["# Scene keys", "",
             "Every key a scene file (TOML) may hold, generated from the schema the loader "
             "validates against (`python -m render_inspect.scene.reference`). Lengths are in "
             "mm; other units are in the key's name (`_deg`, `_nm`, `_hz`, `_s`). Any key can "
             "be overridden on the command line with `--set section.key=value` (TOML value "
             "syntax). Unknown keys are errors.", ""]
    sections: list = []
    top: list[str] = []
    _table(Scene, "", top, sections)
    lines += ["## Top level", ""] + top
    for path, sub, field in sections:
        if isinstance(sub, list):
            _union(path, sub, lines)
        else:
            _section(path, sub, lines)
    retired = retired_keys()
    if retired:
        lines += ["## Retired keys", "",
                  "Still accepted, with a warning naming the key to use instead; they will be "
                  "removed.", "", "| key | use instead | where it applied |", "|---|---|---|"]
        for old, (new, note) in retired.items():
            lines.append(f"| `{old}` | {f'`{new}`' if new else '(nothing: ignored)'} | {note} |")
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"
