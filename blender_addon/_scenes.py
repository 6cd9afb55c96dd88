"""The scene file the add-on works on: the scenes shipped with render_inspect (the
``preset`` choices), the file in use, and its main numbers read into ``params``.

Kept apart from the property definitions (:mod:`.properties`) so that the property
callbacks (:mod:`._callbacks`) reach :func:`load_params` without importing the module that
imports them.
"""

import tomllib
from pathlib import Path

import bpy

from . import _lib

#: Sections of a scene file whose numbers the panel lists.
PARAM_SECTIONS = ("design", "tool", "process", "simulation")

# Blender keeps only pointers to enum item strings: the tuples live here.
_PRESET_ITEMS: list[tuple[str, str, str]] = []
_PRESET_PATHS: dict[str, str] = {}


def scenes_folder() -> Path | None:
    """The folder of the scenes shipped with render_inspect (package data of the copy in
    the extension or of an installed render_inspect; ``scenes/`` beside the package in a
    source checkout), found without importing render_inspect."""
    pkg = _lib.folder()
    if pkg is None:
        return None
    for folder in (pkg / "scenes", pkg / "data" / "scenes", pkg.parent / "scenes"):
        if any(folder.glob("*.toml")):
            return folder
    return None


def scan_presets() -> list[tuple[str, str, str]]:
    """(identifier, label, description) of every shipped scene, sorted by name."""
    _PRESET_ITEMS.clear()
    _PRESET_PATHS.clear()
    folder = scenes_folder()
    for path in sorted(folder.glob("*.toml")) if folder else ():
        try:
            data = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, tomllib.TOMLDecodeError):
            continue
        name = path.stem
        desc = str(data.get("description", ""))[:200]
        _PRESET_ITEMS.append((name, name, desc))
        _PRESET_PATHS[name] = str(path)
    if not _PRESET_ITEMS:
        _PRESET_ITEMS.append(("NONE", "No shipped scenes", "render_inspect's scenes were not found"))
    return _PRESET_ITEMS


#: The preset chosen when nothing else is.
DEFAULT_PRESET = "sts_sinusoidal_grid"


def preset_path(name: str) -> str | None:
    return _PRESET_PATHS.get(name)


def scene_file(settings) -> str:
    """The scene file in use: ``scene_path`` when set, else the preset's file."""
    if settings.scene_path.strip():
        return bpy.path.abspath(settings.scene_path.strip())
    return preset_path(settings.preset) or ""


def load_params(settings) -> None:
    """Fill ``settings.params`` with the numbers of the scene file in use (empty when it
    cannot be read: Simulate then reports why)."""
    path = scene_file(settings)
    settings.params.clear()
    settings.params_source = path
    settings.design_type = ""
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    settings.design_type = str(data.get("design", {}).get("type", ""))
    settings.scene_name = str(data.get("name", Path(path).stem))
    for section in PARAM_SECTIONS:
        table = data.get(section, {})
        if not isinstance(table, dict):
            continue
        for key, value in table.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                continue
            item = settings.params.add()
            item.key = f"{section}.{key}"
            item.section = section
            item.is_int = isinstance(value, int)
            item.original = float(value)
            item.value = float(value)
