"""The two scenes ``compare`` puts side by side: the pair the scene's process defines (its
``variants`` hook) or two values of one key (``--vary key=a,b``), and the scene with a
variant's keys set."""

from __future__ import annotations

import json
import re
from pathlib import Path
import tomllib
from typing import TYPE_CHECKING, Any, Iterable

from ..core.errors import InputError
from ..processes import Variant, VariantPair, process_of
from ._schema import apply_overrides, scene_from_dict

if TYPE_CHECKING:
    from ._schema import Scene

__all__ = ["parse_vary", "compare_pair", "variant_scene", "compare_variants"]


def parse_vary(text: str) -> tuple[str, tuple]:
    """``"key=a,b"`` -> ``(key, (a, b))`` with TOML values (``process.compensation=z,none``,
    ``tool.nose_radius=0.5,0.25``, ``simulation.region=[0,0,1,1],[0,0,2,2]``).

    Raises
    ------
    InputError
        Not of the form key=a,b with exactly two values.
    """
    if "=" not in text:
        raise InputError(f"--vary expects section.key=a,b (two values), received {text!r}")
    key, rest = text.split("=", 1)
    key = key.strip()
    if not key or not all(key.split(".")):
        raise InputError(f"--vary key must be a dotted path like process.compensation, received {key!r}")
    parts, depth, cur, quote = [], 0, "", None
    for ch in rest:
        if quote:
            cur += ch
            if ch == quote:
                quote = None
            continue
        if ch in "'\"":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    parts.append(cur)
    parts = [p.strip() for p in parts]
    if len(parts) != 2 or not all(parts):
        raise InputError(f"--vary {key} needs exactly two values separated by a comma, "
                         f"received {rest!r}")
    values = []
    for p in parts:
        try:
            values.append(tomllib.loads(f"v = {p}")["v"])
        except tomllib.TOMLDecodeError:
            values.append(p)  # a bare word is a string, as with --set
    return key, tuple(values)


def _slug(text: str) -> str:
    s = re.sub(r"[^A-Za-z0-9_.-]+", "_", str(text)).strip("_")
    return s[:60] or "value"


def compare_pair(scene: Scene, vary: str | None = None) -> VariantPair:
    """The pair ``compare`` shows: the process kind's own (its ``variants`` hook), or the
    two values of one key (``vary = "key=a,b"``)."""
    if vary is None:
        process = process_of(scene)
        pair = process.variants(process.inputs_of(scene))
        if pair is None:
            raise InputError(f"process.kind = {scene.process.kind!r} defines no comparison; "
                             f"use --vary key=a,b")
        return pair
    key, (va, vb) = parse_vary(vary)
    leaf = key.split(".")[-1]
    if leaf == "program":  # program files: named by their file names
        na, nb = (_slug(f"program_{Path(str(v)).stem}") for v in (va, vb))
    else:
        na, nb = _slug(f"{leaf}_{va}"), _slug(f"{leaf}_{vb}")
    if na == nb:
        na, nb = na + "_a", nb + "_b"
    return VariantPair(Variant(na, f"{key} = {va}", {key: va}),
                       Variant(nb, f"{key} = {vb}", {key: vb}), key=key,
                       about=f"The scene with {key} = {va} against {key} = {vb}.")


def variant_scene(scene: Scene, variant: Variant) -> Scene:
    """``scene`` with the variant's values set (dotted keys; ``None`` clears a key)."""
    if not variant.values:
        return scene
    data = scene.to_dict()
    plain = []
    for key, value in variant.values.items():
        if value is None:
            node = data
            parts = key.split(".")
            for p in parts[:-1]:
                node = node.setdefault(p, {})
            node[parts[-1]] = None
        else:
            plain.append((key, value))
    data = _set_values(data, plain)
    return scene_from_dict(data, source=f"(variant {variant.name})")


def _set_values(data: dict, pairs: Iterable[tuple[str, Any]]) -> dict:
    overrides = []
    for key, value in pairs:
        if isinstance(value, str):
            overrides.append(f"{key}={_toml_str(value)}")
        elif isinstance(value, bool):
            overrides.append(f"{key}={'true' if value else 'false'}")
        elif isinstance(value, (int, float)):
            overrides.append(f"{key}={value!r}")
        else:
            overrides.append(f"{key}={json.dumps(value)}")
    return apply_overrides(data, overrides)


def _toml_str(s: str) -> str:
    return "'" + s.replace("'", "") + "'"


def compare_variants(scene: Scene, vary: str | None = None) -> tuple:
    """The two scenes ``compare`` puts side by side (:func:`compare_pair`); everything
    but the varied keys (camera, seed, region) is the same."""
    pair = compare_pair(scene, vary)
    return tuple(variant_scene(scene, v) for v in pair.variants)
