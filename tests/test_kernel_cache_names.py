"""numba's on-disk cache names a kernel after its Python function (module, qualified name,
first line) and keys the entries by the argument types only, not by the compile options.
Two kernels made from one function with different options (a parallel one for whole grids
and a serial, GIL-free one for tiles) would share one cache entry: whichever was compiled
first would be loaded for the other too.  Every cached kernel of the package therefore has a
cache name of its own."""

from __future__ import annotations

import importlib
import pkgutil
from collections import defaultdict

import render_inspect
from render_inspect.core.lazy import LazyDispatcher

#: modules that need a GPU or Blender to import
SKIP = ("render_inspect.blender_addon",)


def _options(kernel) -> dict | None:
    """The compile options of a cached kernel (a lazy one, or numba's dispatcher that it
    became once a kernel of its module ran: the module's names are then numba's own), None
    for anything else."""
    if isinstance(kernel, LazyDispatcher):
        return kernel._options if kernel._options.get("cache") else None
    if hasattr(kernel, "targetoptions") and hasattr(kernel, "py_func"):
        cached = type(getattr(kernel, "_cache", None)).__name__ != "NullCache"
        return dict(kernel.targetoptions, cache=True) if cached else None
    return None


def _kernels() -> list[tuple[str, object]]:
    found = []
    for info in pkgutil.walk_packages(render_inspect.__path__, "render_inspect."):
        if info.name.startswith(SKIP) or info.name.endswith("__main__"):
            continue
        try:
            mod = importlib.import_module(info.name)
        except ImportError:  # (an optional dependency: its kernels cannot be used either)
            continue
        for name, value in vars(mod).items():
            if _options(value) is not None:
                found.append((f"{info.name}.{name}", value))
    return found


def test_every_cached_kernel_has_a_cache_name_of_its_own():
    by_name: dict[tuple, dict[str, dict]] = defaultdict(dict)
    for where, k in _kernels():
        f = k.py_func
        key = (f.__module__, f.__qualname__, f.__code__.co_firstlineno)
        by_name[key][where] = {o: v for o, v in _options(k).items() if o in ("parallel", "nogil")}
    shared = {key: kernels for key, kernels in by_name.items()
              if len({repr(sorted((k, sorted(v) if isinstance(v, (set, frozenset)) else v)
                                for k, v in o.items())) for o in kernels.values()}) > 1}
    assert not shared, f"kernels with different options share a numba cache entry: {shared}"
    assert len(by_name) > 20  # (the package's kernels were found)


def test_the_cut_and_envelope_kernels_are_one_serial_kernel_each():
    """Whole grids run the tiles' serial kernel on threads: no parallel twin shares (or
    needs) a cache entry of its own."""
    from render_inspect.machining import _cut_kernel, _envelope

    for module, name in ((_cut_kernel, "_cut_parallel"), (_envelope, "_fill_parallel")):
        assert not hasattr(module, name)
    for kernel in (_cut_kernel._cut_serial, _envelope._fill_serial):
        assert _options(kernel)["nogil"] and not _options(kernel).get("parallel")
