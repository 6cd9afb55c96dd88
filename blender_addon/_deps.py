"""Which bundled Python modules this Blender can import, found without importing them.

The extension ships its dependencies as wheels for each platform; when one has no wheel for
a platform (Mitsuba has none for Intel macOS) the add-on still enables, the panel names what
is missing, and the operations that need it are greyed out.
"""

import importlib.util

#: What each operation needs: (import name, distribution, what it is used for).
CORE = (
    ("render_inspect", "render_inspect", "the simulation"),
    ("numpy", "numpy", "arrays"),
    ("scipy", "scipy", "filters and fits"),
    ("pydantic", "pydantic", "scene validation"),
    ("numba", "numba", "the cutting kernels"),
    ("OpenEXR", "OpenEXR", "EXR files"),
    ("PIL", "pillow", "PNG files"),
    ("matplotlib", "matplotlib", "figures"),
)
MITSUBA = (("mitsuba", "mitsuba", "the interferometer"), ("drjit", "drjit", "the interferometer"))
MESH = (("trimesh", "trimesh", "PLY/GLB export"),)
X3P = (("x3pio", "x3pio", "X3P export"),)
#: Everything the add-on imports: the extension bundles these distributions (and what they
#: require), at the versions of the project's lock (tools/build_blender_extension.py).
ALL = CORE + MITSUBA + MESH + X3P

NEEDS = {
    "simulate": CORE,
    "render": CORE,  # the interferogram is added when Mitsuba is there
    "compare": CORE + MITSUBA,
    "export": CORE + MESH,
}

_found: dict[str, bool] = {}


def available(module: str) -> bool:
    """True when ``module`` can be imported here (checked once; nothing is imported)."""
    if module not in _found:
        if module == "render_inspect":  # the extension's own copy (blender_addon/_lib.py)
            from . import _lib

            _found[module] = _lib.name() is not None
            return _found[module]
        try:
            _found[module] = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):
            _found[module] = False
    return _found[module]


def missing(groups=None) -> list[tuple[str, str, str]]:
    """The (module, distribution, use) entries of ``groups`` (default: every one) that
    cannot be imported, without duplicates."""
    groups = groups if groups is not None else CORE + MITSUBA + MESH + X3P
    seen, out = set(), []
    for entry in groups:
        if entry[0] not in seen and not available(entry[0]):
            seen.add(entry[0])
            out.append(entry)
    return out


def missing_for(operation: str) -> list[tuple[str, str, str]]:
    return missing(NEEDS[operation])


def has_mitsuba() -> bool:
    return not missing(MITSUBA)


def has_x3p() -> bool:
    return not missing(X3P)


def forget() -> None:
    """Look again next time (after the user installed something)."""
    from . import _lib

    _found.clear()
    _lib.forget()
