"""A cached kernel is compiled again when a module whose code or numbers it holds changes,
not only its own file: numba's cache keeps the machine code of the kernels a kernel calls
and of the numbers it imports, and by itself checks only the kernel's own file.  Built on a
small package of two modules in a fresh folder, run in fresh processes."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from render_inspect.core.lazy import kernel_sources

REPO = Path(__file__).resolve().parents[1]

_HELPER = """
from render_inspect.core.lazy import njit

SCALE = {scale}


@njit(cache=True)
def helper(x):
    return x * {factor}
"""

_MAIN = """
from render_inspect.core.lazy import njit

from .helper import SCALE, helper


@njit(cache=True)
def calls(x):
    return helper(x) + 1.0


@njit(cache=True)
def reads(x):
    return x * SCALE
"""

_RUN = """
import json
from stalepkg.main import calls, reads
values = [calls(3.0), reads(3.0)]
hits = [sum(k._dispatcher._cache_hits.values()) for k in (calls, reads)]
print(json.dumps({"values": values, "hits": hits}))
"""


def _write_helper(pkg: Path, scale: float, factor: float, when: float) -> None:
    path = pkg / "helper.py"
    path.write_text(_HELPER.format(scale=scale, factor=factor))
    os.utime(path, (when, when))


def _run(root: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), str(REPO)]))
    env.pop("NUMBA_CACHE_DIR", None)  # (numba's cache beside the sources, as installed)
    r = subprocess.run([sys.executable, "-c", _RUN], capture_output=True, text=True, env=env,
                       cwd=root, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_a_kernel_is_compiled_again_when_a_kernel_or_number_it_imports_changes(tmp_path):
    pkg = tmp_path / "stalepkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "main.py").write_text(textwrap.dedent(_MAIN))
    _write_helper(pkg, scale=2.0, factor=2.0, when=1_700_000_000)
    first = _run(tmp_path)
    assert first == {"values": [7.0, 6.0], "hits": [0, 0]}            # compiled
    assert _run(tmp_path) == {"values": [7.0, 6.0], "hits": [1, 1]}  # loaded from the cache
    # the helper module changes (its kernel and its number); the kernels' own file does not
    _write_helper(pkg, scale=5.0, factor=4.0, when=1_700_000_100)
    changed = _run(tmp_path)
    assert changed == {"values": [13.0, 15.0], "hits": [0, 0]}        # compiled again, not stale
    assert _run(tmp_path) == {"values": [13.0, 15.0], "hits": [1, 1]}


def test_the_sources_of_the_cut_kernel_are_its_helpers_modules():
    from render_inspect.machining import _cut_kernel

    files = {Path(f).relative_to(REPO / "render_inspect").as_posix()
             for f in kernel_sources(_cut_kernel._cut_rows)}
    # its own module, the pass window's, the grooves' and the envelope's step it inlines
    assert {"machining/_cut_kernel.py", "machining/_cut_window.py", "machining/_cut_grooves.py",
            "machining/_envelope_step.py", "machining/_envelope.py"} <= files
    # nothing outside the package (numpy, numba, math)
    assert all(not f.startswith("..") for f in files)



def test_finding_a_kernels_sources_imports_nothing_lazy():
    """A lazy module or name among a kernel's globals is not looked into (that would
    import it: here modules that do not exist, whose import would raise)."""
    namespace: dict = {"__name__": "render_inspect.not_a_module"}
    exec(textwrap.dedent("""
        from render_inspect.core.lazy import lazy_attr, lazy_module

        parse = lazy_attr("render_inspect_no_such_module", "parse")
        tree = lazy_module("render_inspect_no_such_module_either")


        def uses_them(x):
            return parse(x), tree.fromstring(x)
        """), namespace)
    assert kernel_sources(namespace["uses_them"]) == []



def test_a_kernels_sources_are_the_same_whatever_else_the_process_imported(tmp_path, monkeypatch):
    """The stamp must not change between processes (else each would compile the kernel
    again): the modules a number came through are read from the sources' imports, not
    looked for among the modules loaded (a module that imports the same number and is
    loaded in one process only does not count)."""
    pkg = tmp_path / "samepkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "main.py").write_text(textwrap.dedent(_MAIN))
    (pkg / "bystander.py").write_text("from .helper import SCALE\n")
    _write_helper(pkg, scale=2.0, factor=2.0, when=1_700_000_000)
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        import samepkg.main as main

        before = kernel_sources(main.reads.py_func)
        import samepkg.bystander  # noqa: F401  (binds the very same number)

        after = kernel_sources(main.reads.py_func)
        assert before == after == sorted(str(pkg / n) for n in ("helper.py", "main.py"))
    finally:
        for name in [n for n in sys.modules if n == "samepkg" or n.startswith("samepkg.")]:
            del sys.modules[name]


def test_the_stamp_is_extended_for_the_numba_release_checked_only():
    """numba's cache index is internal: its stamp is extended for the releases it was
    checked against (``STAMPED_RELEASES``), and left as numba made it for any other."""
    from types import SimpleNamespace

    from render_inspect.core import lazy
    from render_inspect.machining import _cut_kernel

    def dispatcher():
        return SimpleNamespace(_cache=SimpleNamespace(_cache_file=SimpleNamespace(_source_stamp=(1.0, 2))))

    checked = "%d.%d.0" % lazy.STAMPED_RELEASES[0]
    d = dispatcher()
    lazy._stamp_sources(d, _cut_kernel._cut_rows, SimpleNamespace(__version__=checked))
    own, sources = d._cache._cache_file._source_stamp
    assert own == (1.0, 2)
    assert {p for p, *_ in sources} >= {os.path.join("machining", "_cut_window.py")}
    for other in ("0.99.1", "1.0.0", "unknown"):
        d = dispatcher()
        lazy._stamp_sources(d, _cut_kernel._cut_rows, SimpleNamespace(__version__=other))
        assert d._cache._cache_file._source_stamp == (1.0, 2)
