"""Heavy libraries loaded where they are used, not when the package is imported.

The command line checks a scene and its arguments before it computes anything; numba
(about 0.4 s to import), SciPy (up to 0.8 s for ``scipy.signal`` / ``scipy.stats``) and
the renderers would make a typing mistake wait for seconds.  The modules that define the
scene's sections also hold the kernels, so the kernels and the SciPy functions they call
are declared through this module:

* :func:`njit` is ``numba.njit`` that imports numba and creates the dispatcher on the
  first call (or the first use of a dispatcher attribute: ``py_func`` is there at once).
  The compiled code is the same, and numba's on-disk cache is used as before (it is keyed
  by the Python function's file and name).  A kernel calling another kernel, and
  ``prange`` (from this module) inside a kernel, work as with numba's own: when the first
  kernel of a module is made, every lazy kernel and ``prange`` among its globals is
  replaced by numba's, in that module and in the modules of the kernels it names.
* :func:`lazy_module` is a module that is imported on its first attribute access
  (``ndimage = lazy_module("scipy.ndimage")``), and :func:`lazy_attr` one of its
  attributes, loaded when first called or looked into (``Rotation``, ``least_squares``).
* :func:`load_numba` is numba itself, for kernels built with numba's own decorators.  In
  the ``render-inspect`` program (:func:`quick_cache_loads`), numba loads a kernel from
  its cache without first setting up its whole compiler, which only a compilation needs.

numba's cache keeps a kernel's machine code with the date and size of the kernel's own
file, and loads it while that file is unchanged; but the machine code also holds the
kernels it calls and the numbers it reads from other modules, compiled in.  A kernel of
:func:`njit` with ``cache=True`` is also stamped with those modules' files
(:func:`kernel_sources`): a change to any of them compiles it again, where numba's own
stamp would load the old code.

Only the standard library is imported here.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import importlib
import importlib.util
import os
import re
import sys
import threading
import types
from collections.abc import Callable, Iterator
from typing import Any, Generic, ParamSpec, TypeVar, overload

__all__ = ["njit", "prange", "lazy_module", "lazy_attr", "LazyDispatcher", "passive_omp_wait",
           "load_numba", "quick_cache_loads", "collector_paused", "freeze_after_pauses", "freeze_lasting",
           "kernel_sources"]

_LOCK = threading.RLock()
#: blocks running with the collector paused (collector_paused), and whether it was on
#: before the first of them
_PAUSES = {"count": 0, "was_on": False, "freeze": False}
#: numba's cache loads without its compiler's set-up: asked for (quick_cache_loads), made
_NUMBA = {"quick": False, "made": False}
#: the numba releases (major, minor) whose cache loads were checked without the set-up
QUICK_LOAD_RELEASES = ((0, 61),)
#: the numba releases whose cache index keeps the source stamp :func:`_stamp_sources` extends
STAMPED_RELEASES = ((0, 61),)
#: (date, size) of the files the kernels' stamps name, read once per process
_FILE_STAMPS: dict[str, tuple[float, int]] = {}
#: each module's names imported from another module ({name: (module, its name there)}),
#: read from its source once per process
_FROM_IMPORTS: dict[str, dict[str, tuple[str, str]]] = {}
#: ``from MODULE import NAMES`` at the start of a line (NAMES in parentheses over lines)
_FROM_RE = re.compile(r"^[ \t]*from[ \t]+([\w.]+)[ \t]+import[ \t]+(\([^)]*\)|[^\n]+)", re.M)
_MISSING = object()


@contextlib.contextmanager
def collector_paused() -> Iterator[None]:
    """Run the block with Python's cyclic garbage collector paused: for blocks that import
    libraries or load the scene's schema, which make tens of thousands of objects that live
    as long as the process and almost no garbage, and over which the collector's passes
    (young and full) cost tenths of a CPU-second for nothing.  When the last such block
    (of any thread) ends, the collector is put back as it was before the first; in the
    ``render-inspect`` program (:func:`freeze_after_pauses`), what was made is also left out of the collector's later
    passes (``gc.freeze``).  Not elsewhere: frozen objects are never collected, so a host
    that embeds the package (Blender, a user's script, a Dask worker) would keep its own
    objects past their end (Blender 4.5 then hangs at exit, its objects' cleanup never run)."""
    with _LOCK:
        if _PAUSES["count"] == 0:
            _PAUSES["was_on"] = gc.isenabled()
            gc.disable()
        _PAUSES["count"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _PAUSES["count"] -= 1
            if _PAUSES["count"] == 0:
                freeze_lasting()
                if _PAUSES["was_on"]:
                    gc.enable()


def freeze_after_pauses() -> None:
    """From now on, what the blocks of :func:`collector_paused` made is left out of the
    collector's later passes (``gc.freeze``) when the last of them ends: for the
    ``render-inspect`` program only, whose objects from its start live as long as it."""
    _PAUSES["freeze"] = True


def freeze_lasting() -> None:
    """Leave the objects made so far out of the collector's later passes (``gc.freeze``):
    in the ``render-inspect`` program (:func:`freeze_after_pauses`), whose modules and
    scene live as long as it; elsewhere nothing (a host's frozen objects would never be
    collected)."""
    if _PAUSES["freeze"]:
        gc.freeze()


def passive_omp_wait() -> None:
    """Let the threads of numba's parallel kernels sleep rather than spin while they wait
    for work (``OMP_WAIT_POLICY=PASSIVE``, unless the environment sets it).  Between short
    parallel kernels OpenMP's threads spin by default, burning a core that the process's
    own single-threaded stages or another process need (measured: a fit evaluation
    1.05-1.22 CPU-s spinning against 0.85-0.95 passive; the PSI render 0.3-0.4 CPU-s
    less), with the same numbers bit for bit.  Read by the OpenMP runtime when it starts
    (the process's first parallel kernel); no effect after."""
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

_P = ParamSpec("_P")
_R = TypeVar("_R")


def prange(*args: int) -> range:
    """``numba.prange`` inside a kernel (replaced by it when the kernel is compiled);
    ``range`` when the kernel's Python function is called directly."""
    return range(*args)


def _numba() -> Any:  # the numba module (imported here, on first use)
    import numba

    if _NUMBA["quick"] and not _NUMBA["made"]:
        with _LOCK:
            if not _NUMBA["made"]:
                _NUMBA["made"] = True
                _load_without_set_up(numba)
    return numba


def load_numba() -> Any:
    """The numba module, imported now (for the kernels built with numba's own decorators:
    numba set up as for the lazy kernels)."""
    return _numba()


def quick_cache_loads() -> None:
    """From now on, numba loads a CPU kernel from its on-disk cache without first setting
    up its whole compiler: for the ``render-inspect`` program only (see below).

    Before numba loads a kernel's machine code from its cache, it makes ready everything
    a compilation needs: it imports its whole library of compilable numpy and Python
    functions (its linear algebra with SciPy's BLAS, random numbers, typed containers:
    about 0.25 s and 0.4 CPU-s in every fresh process, more than the loads themselves).
    Loading code compiled before needs only numba's runtime (its memory management),
    which is started.  The set-up is not skipped, only put off: numba's compiler makes it
    at the start of every compilation (a kernel missing from the cache, a new signature),
    as it always does; a kernel loaded from the cache is the machine code numba wrote,
    unchanged, so every result is the same.  Only for the numba releases this was checked
    with (:data:`QUICK_LOAD_RELEASES`, and where numba's cache has that layout; numba's own
    order otherwise), and never in a host process (Blender, a user's script, a Dask
    worker), whose numba is shared with whatever else it runs."""
    _NUMBA["quick"] = True
    if "numba" in sys.modules:  # (numba imported already: the change made now)
        _numba()


def _load_without_set_up(numba: Any) -> None:
    """numba's cache loads of CPU kernels without the compiler's set-up
    (:func:`quick_cache_loads`), where ``numba`` is a release checked and its cache has the
    layout this was written against."""
    if not quick_loads_checked(getattr(numba, "__version__", "")):
        return
    try:
        from numba.core import caching, cpu
        from numba.core.runtime import rtsys
    except ImportError:
        return
    cache = caching.Cache
    load = cache.__dict__.get("load_overload")
    if (load is None or getattr(load, "_quick", False) or "_load_overload" not in cache.__dict__
            or "_guard_against_spurious_io_errors" not in cache.__dict__
            or not hasattr(rtsys, "initialize")):
        return

    def load_overload(self: Any, sig: Any, target_context: Any) -> Any:
        if not isinstance(target_context, cpu.CPUContext):
            return load(self, sig, target_context)
        # what a loaded CPU kernel needs of the set-up: numba's runtime (started once)
        rtsys.initialize(target_context)
        with self._guard_against_spurious_io_errors():
            return self._load_overload(sig, target_context)

    load_overload._quick = True  # type: ignore[attr-defined]
    load_overload.__doc__ = load.__doc__
    cache.load_overload = load_overload


def _release_in(version: str, releases: tuple[tuple[int, int], ...]) -> bool:
    """Whether ``version`` (e.g. "0.61.2") is one of ``releases`` ((major, minor) pairs)."""
    parts = version.split(".")
    try:
        return (int(parts[0]), int(parts[1])) in releases
    except (IndexError, ValueError):
        return False


def quick_loads_checked(version: str) -> bool:
    """Whether numba ``version`` (e.g. "0.61.2") is a release whose cache loads were
    checked without the compiler's set-up (:data:`QUICK_LOAD_RELEASES`)."""
    return _release_in(version, QUICK_LOAD_RELEASES)


def _code_names(code: types.CodeType) -> set[str]:
    """The global and attribute names a function's code (and the code it defines) uses."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _code_names(const)
    return names


def _number_like(value: Any) -> bool:
    """A value numba compiles into a kernel as a constant (a number, a string, a tuple, a
    numpy array or scalar)."""
    return (isinstance(value, (int, float, complex, str, bytes, tuple))
            or type(value).__module__ == "numpy")


def _kernel_function(value: Any) -> Any:
    """The Python function of a lazy kernel or of a numba dispatcher, else None (looked up
    on those types only: a lazy module or name is not made to import here)."""
    if isinstance(value, LazyDispatcher):
        return value.py_func
    if type(value).__module__.startswith("numba."):
        inner = getattr(value, "py_func", None)
        if hasattr(inner, "__code__") and hasattr(inner, "__globals__"):
            return inner
    return None


def _from_imports(module: types.ModuleType) -> dict[str, tuple[str, str]]:
    """``{name: (module, its name there)}`` of the ``from ... import ...`` statements in a
    module's source (relative modules made absolute); {} where the source is not there."""
    name = module.__name__
    found = _FROM_IMPORTS.get(name)
    if found is None:
        found = {}
        try:
            with open(module.__dict__["__file__"], encoding="utf-8") as f:
                text = f.read()
        except (OSError, KeyError, TypeError, UnicodeDecodeError):
            text = ""
        package = module.__dict__.get("__package__") or name.rpartition(".")[0]
        for m in _FROM_RE.finditer(text):
            source = m.group(1)
            try:
                source = importlib.util.resolve_name(source, package) if source.startswith(".") else source
            except (ImportError, ValueError):
                continue
            for part in m.group(2).strip().strip("()").split(","):
                part = part.split("#")[0].strip()
                if part and part != "*":
                    imported, _, alias = part.partition(" as ")
                    found[(alias or imported).strip()] = (source, imported.strip())
        _FROM_IMPORTS[name] = found
    return found


def _constant_sources(module: types.ModuleType, name: str, ours: Callable[[str], bool]) -> set[str]:
    """The files of the package's modules a constant that ``module`` names ``name`` was
    imported through, to the one that defines it (from the sources' ``from ... import``
    statements: the same files in every process, whatever else it imported)."""
    files: set[str] = set()
    seen: set[tuple[str, str]] = set()
    while (module.__name__, name) not in seen:
        seen.add((module.__name__, name))
        source, name = _from_imports(module).get(name, ("", ""))
        nxt = sys.modules.get(source) if source and ours(source) else None
        if nxt is None or not nxt.__dict__.get("__file__"):
            break
        files.add(nxt.__dict__["__file__"])
        module = nxt
    return files


def kernel_sources(py_func: Callable[..., Any]) -> list[str]:
    """The files of the modules whose code or numbers a kernel's machine code holds: its
    own module's; those of the kernels it calls (a lazy kernel or a numba dispatcher among
    its globals), in turn; of the package's modules it reads attributes of; and, for a
    number, string, tuple or array it names that its module imports, of the modules it
    came through from the one that defines it.  Sorted; the same in every process."""
    top = (py_func.__module__ or "").split(".")[0]

    def ours(name: str) -> bool:
        return bool(top) and (name == top or name.startswith(top + "."))

    files: set[str] = set()
    seen: set[int] = set()
    todo = [py_func]
    while todo:
        fn = todo.pop()
        if id(fn) in seen:
            continue
        seen.add(id(fn))
        own = getattr(sys.modules.get(fn.__module__ or "", None), "__file__", None)
        if own:
            files.add(own)
        namespace = fn.__globals__
        for name in _code_names(fn.__code__):
            value = namespace.get(name, _MISSING)
            if value is _MISSING:
                continue
            inner = _kernel_function(value)
            if inner is not None:
                todo.append(inner)
            elif isinstance(value, types.ModuleType):
                if ours(value.__name__) and value.__dict__.get("__file__"):
                    files.add(value.__dict__["__file__"])
            elif _number_like(value):
                module = sys.modules.get(fn.__module__ or "")
                if module is not None:
                    files |= _constant_sources(module, name, ours)
    return sorted(files)


def _file_stamp(path: str) -> tuple[float, int]:
    stamp = _FILE_STAMPS.get(path)
    if stamp is None:
        st = os.stat(path)
        stamp = _FILE_STAMPS[path] = (st.st_mtime, st.st_size)
    return stamp


def _stamp_sources(dispatcher: Any, py_func: Callable[..., Any], numba: Any) -> None:
    """numba's stamp of a cached kernel (its own file's date and size) extended with those
    of :func:`kernel_sources`: the cache entry of a kernel whose callees or imported
    numbers changed is not loaded but compiled again (and replaced).  For the numba
    releases whose cache index this was checked against; elsewhere numba's own stamp."""
    if not _release_in(getattr(numba, "__version__", ""), STAMPED_RELEASES):
        return
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)
    if cache_file is None or not hasattr(cache_file, "_source_stamp"):
        return
    own = getattr(sys.modules.get(py_func.__module__ or "", None), "__file__", None)
    if not isinstance(own, str):
        return
    try:
        # (paths relative to the folder above the kernel's module's: the same wherever the
        # package is installed)
        root = os.path.dirname(os.path.dirname(os.path.abspath(own)))
        sources = tuple((os.path.relpath(f, root), *_file_stamp(f)) for f in kernel_sources(py_func))
    except (OSError, ValueError):
        return  # (numba's own stamp, as without this)
    cache_file._source_stamp = (cache_file._source_stamp, sources)


def _realise_globals(namespace: dict[str, Any], seen: set[int]) -> None:
    """Put numba's objects in place of the lazy ones among a module's globals (and, in
    turn, among the globals of the modules whose kernels it names)."""
    if id(namespace) in seen:
        return
    seen.add(id(namespace))
    numba = _numba()
    for name, value in list(namespace.items()):
        if value is prange:
            namespace[name] = numba.prange
        elif isinstance(value, LazyDispatcher):
            namespace[name] = value._realise(seen)


class LazyDispatcher(Generic[_P, _R]):
    """A numba kernel made on first use (see the module notes).  Called as the Python
    function it wraps (the same parameters and return)."""

    def __init__(self, py_func: Callable[_P, _R], options: dict[str, Any]) -> None:
        self.py_func = py_func
        self._options = dict(options)
        # numba's Dispatcher once made (Any: numba is not imported by this module)
        self._dispatcher: Any = None
        functools.update_wrapper(self, py_func)

    def _realise(self, seen: set[int] | None = None) -> Any:
        if self._dispatcher is not None:
            return self._dispatcher
        with _LOCK:
            if self._dispatcher is None:
                numba = _numba()
                dispatcher = numba.njit(**self._options)(self.py_func)
                if self._options.get("cache"):
                    _stamp_sources(dispatcher, self.py_func, numba)
                # (set before the globals: a kernel naming itself ends the recursion)
                self._dispatcher = dispatcher
                _realise_globals(self.py_func.__globals__, set() if seen is None else seen)
        return self._dispatcher

    def __call__(self, *args: _P.args, **kwargs: _P.kwargs) -> _R:
        return (self._dispatcher or self._realise())(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:  # an attribute of numba's Dispatcher
        if name.startswith("__") or name in ("_dispatcher", "_options", "py_func"):
            raise AttributeError(name)
        return getattr(self._realise(), name)

    def __reduce__(self) -> tuple[Callable[[str, str], object], tuple[str, str]]:
        return (_module_attr, (self.py_func.__module__, self.py_func.__qualname__))

    def __repr__(self) -> str:
        state = "made" if self._dispatcher is not None else "not made yet"
        return f"<lazy numba kernel {self.py_func.__qualname__} ({state})>"


@overload
def njit(func: Callable[_P, _R], /) -> LazyDispatcher[_P, _R]: ...


@overload
def njit(**options: Any) -> Callable[[Callable[_P, _R]], LazyDispatcher[_P, _R]]: ...


def njit(*args: Callable[_P, _R], **options: Any
         ) -> LazyDispatcher[_P, _R] | Callable[[Callable[_P, _R]], LazyDispatcher[_P, _R]]:
    """``numba.njit`` made on first use: ``@njit``, ``@njit(cache=True, ...)`` or
    ``njit(cache=True)(function)``.  The kernel keeps the Python function's signature."""
    if len(args) == 1 and callable(args[0]) and not options:
        return LazyDispatcher(args[0], {})
    if args:
        raise TypeError("njit: signatures are not supported here; pass options only")

    def decorate(func: Callable[_P, _R]) -> LazyDispatcher[_P, _R]:
        return LazyDispatcher(func, options)

    return decorate


def _module_attr(module: str, qualname: str) -> object:
    obj: object = importlib.import_module(module)
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


class _LazyModule(types.ModuleType):
    def __init__(self, name: str) -> None:
        super().__init__(name)
        self.__dict__["_lazy_target"] = name

    def __getattr__(self, attr: str) -> Any:  # an attribute of the module imported
        if attr.startswith("__"):
            raise AttributeError(attr)
        return getattr(importlib.import_module(self.__dict__["_lazy_target"]), attr)

    def __repr__(self) -> str:
        return f"<lazy module {self.__dict__['_lazy_target']!r}>"


def lazy_module(name: str) -> types.ModuleType:
    """The module ``name``, imported on its first attribute access."""
    return _LazyModule(name)


class _LazyAttr:
    def __init__(self, module: str, name: str) -> None:
        self._where = (module, name)
        self._obj: Any = None

    def _get(self) -> Any:
        if self._obj is None:
            module, name = self._where
            self._obj = getattr(importlib.import_module(module), name)
        return self._obj

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self._get()(*args, **kwargs)

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__") or attr in ("_where", "_obj"):
            raise AttributeError(attr)
        return getattr(self._get(), attr)

    def __repr__(self) -> str:
        return f"<lazy {self._where[0]}.{self._where[1]}>"


def lazy_attr(module: str, name: str) -> Any:
    """``from module import name``, imported when first called or looked into."""
    # Any: the stand-in for whatever ``module`` holds under ``name`` (a function, a
    # class); its type cannot be named here without importing the module, which is what
    # this function avoids
    return _LazyAttr(module, name)
