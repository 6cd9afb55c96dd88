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

from ..core.annotations import annotation_bounds, unwrap_annotation
from ..core.messages import bound_text
from ..core.section import MAX_MAGNITUDE
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


def _ends(ann: typing.Any, meta: list, capped: bool) -> str:
    """A number's allowed range in words (">= 0, <= 1"); ``capped``: a float's open side
    carries the schema's cap on numbers that state no range (+-MAX_MAGNITUDE)."""
    if ann not in (int, float):
        return ""
    lo, hi, lo_open, hi_open = annotation_bounds(meta)
    infinite = any(getattr(m, "allow_inf_nan", None) for m in meta)
    if capped and ann is float:
        if lo is None:
            lo, lo_open = -MAX_MAGNITUDE, False
        if hi is None:
            hi, hi_open = MAX_MAGNITUDE, False
    ends = []
    if lo is not None:
        ends.append(f"{'>' if lo_open else '>='} {bound_text(lo)}")
    if hi is not None:
        ends.append(f"{'<' if hi_open else '<='} {bound_text(hi)}")
    text = ", ".join(ends)
    return f"{text} (or inf)" if infinite and text else text


def _range(field: FieldInfo) -> str:
    """The allowed column: the number's range (with the cap the loader puts on an open
    side, :data:`~render_inspect.core.section.MAX_MAGNITUDE`), an array's length and its
    items' range."""
    ann, meta = unwrap_annotation(field.annotation)
    meta = list(field.metadata) + meta
    lo_set, hi_set = (any(getattr(m, a, None) is not None for m in field.metadata for a in pair)
                      for pair in (("gt", "ge"), ("lt", "le")))
    capped = not (lo_set and hi_set)
    parts = [_ends(ann, meta, capped)]
    what = ("character", "characters") if ann is str else ("item", "items")
    for m in meta:
        if isinstance(m, at.MinLen):
            parts.append(f"at least {m.min_length} {what[m.min_length != 1]}")
        elif isinstance(m, at.MaxLen):
            parts.append(f"at most {m.max_length} {what[m.max_length != 1]}")
    if typing.get_origin(ann) in (list, tuple):
        items = {_ends(*unwrap_annotation(a), capped) for a in typing.get_args(ann)
                 if a is not Ellipsis}
        if len(items) == 1 and (each := items.pop()):
            parts.append(f"each {each}")
    return ", ".join(p for p in parts if p)


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
             "syntax). Unknown keys are errors. The allowed column gives the loader's limits; a "
             "number whose key states no end of its own is held within +-1e9 all the same "
             "(shown), positions and heights within +-10000 mm. Some keys are also checked "
             "against each other (the table's meaning says which); the error names them.", ""]
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
