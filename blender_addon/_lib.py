"""Where the add-on finds render_inspect, without importing it.

In the extension, render_inspect ships as source inside the add-on's own package
(``_bundled/render_inspect``, imported relatively, as Blender's extension rules ask: the
extension changes no ``sys.path``).  From a source checkout (the tests, development) the
installed ``render_inspect`` is used.  Every module of the add-on reaches render_inspect
through :func:`module`.
"""

import importlib
import importlib.util
from pathlib import Path

#: The bundled copy's import name when this file is part of the add-on package.
BUNDLED = f"{__package__}._bundled.render_inspect" if __package__ else None

_name: list = []


def name():
    """The import name of render_inspect here (the bundled copy first), or None."""
    if not _name:
        found = None
        for candidate in (BUNDLED, "render_inspect"):
            if not candidate:
                continue
            try:
                if importlib.util.find_spec(candidate) is not None:
                    found = candidate
                    break
            except (ImportError, ValueError):
                continue
        _name.append(found)
    return _name[0]


def module(sub: str = ""):
    """``render_inspect`` or its submodule ``sub`` (e.g. ``"pipeline"``), imported."""
    base = name()
    if base is None:
        raise ImportError("render_inspect is not installed in this extension")
    return importlib.import_module(f"{base}.{sub}" if sub else base)


def folder():
    """The folder of the render_inspect package, found without importing it (or None)."""
    base = name()
    if base is None:
        return None
    try:
        spec = importlib.util.find_spec(base)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0])


def forget() -> None:
    _name.clear()
