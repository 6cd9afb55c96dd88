"""Loading the kernels' cached machine code in the background
(:func:`render_inspect.core.lazy.preload_cached`): what the cache holds is loaded and
nothing is compiled; the turning process names every kernel its plan and cut call.

Each check runs in a fresh Python process, where no kernel is loaded yet."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.slow  # (each check starts a fresh Python)

REPO = Path(__file__).resolve().parents[1]


#: records, in the child, every kernel numba is asked to compile or load, and by which thread
_RECORD = """
import json, threading
from numba.core import dispatcher as _d
CALLS = []
_compile = _d.Dispatcher.compile
def _recording(self, sig):
    had = len(self.overloads)
    out = _compile(self, sig)
    CALLS.append({"kernel": self.py_func.__module__ + ":" + self.py_func.__qualname__,
                  "thread": threading.current_thread().name, "new": len(self.overloads) > had,
                  "hits": sum(self._cache_hits.values()), "misses": sum(self._cache_misses.values())})
    return out
_d.Dispatcher.compile = _recording
"""


def _python(code: str, tmp_path: Path, *, record: bool = False, extra_path: Path | None = None) -> dict:
    """Run ``code`` in a fresh interpreter (after :data:`_RECORD` when ``record``); it
    prints one JSON line last."""
    env = dict(os.environ, HOME=str(tmp_path), XDG_CACHE_HOME=str(tmp_path / "cache"))
    paths = [str(REPO)] + ([str(extra_path)] if extra_path else [])
    env["PYTHONPATH"] = os.pathsep.join(paths + [env.get("PYTHONPATH", "")])
    code = (_RECORD if record else "") + textwrap.dedent(code)
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                       text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    return json.loads(p.stdout.strip().splitlines()[-1])


def test_what_the_cache_holds_is_loaded_in_the_background(tmp_path):
    # a first process makes sure the kernel is in numba's cache (loaded, or compiled and saved)
    _python("""
        import json, numpy as np
        from render_inspect.io import heightmap_channels
        heightmap_channels(np.zeros((3, 3)), np.ones((3, 3)))
        print(json.dumps({}))""", tmp_path)
    out = _python("""
        from render_inspect.core.lazy import preload_cached
        from render_inspect.io._exr import _to_float32
        t = preload_cached(["render_inspect.io._exr:_to_float32"])
        t.join(300)
        d = _to_float32._realise()
        print(json.dumps({"alive": t.is_alive(), "calls": CALLS, "signatures": len(d.signatures),
                          "thread": t.name}))""", tmp_path, record=True)
    assert not out["alive"]
    assert out["signatures"] >= 1
    loads = [c for c in out["calls"] if c["kernel"].endswith(":_to_float32")]
    assert loads and all(c["thread"] == out["thread"] for c in loads)
    # loaded from the cache, never compiled
    assert loads[-1]["hits"] >= 1 and loads[-1]["misses"] == 0


def test_nothing_is_compiled_for_a_kernel_the_cache_does_not_hold(tmp_path):
    mod = tmp_path / "never_called_kernels.py"
    mod.write_text(textwrap.dedent("""
        from render_inspect.core.lazy import njit

        @njit(cache=True)
        def plus_one(x):
            return x + 1
        """))
    out = _python("""
        from render_inspect.core.lazy import preload_cached
        import never_called_kernels as m
        t = preload_cached(["never_called_kernels:plus_one", "never_called_kernels:missing",
                            "no_such_module:f"])
        t.join(300)
        from render_inspect.core.lazy import _kernel
        loaded = len(_kernel("never_called_kernels:plus_one").signatures)
        print(json.dumps({"alive": t.is_alive(), "calls": CALLS, "signatures": loaded,
                          "works": m.plus_one(1)}))""", tmp_path, record=True, extra_path=tmp_path)
    assert not out["alive"]
    # (the names that do not resolve are passed over; the kernel is made on its first call)
    assert out["signatures"] == 0 and out["works"] == 2
    assert [c["thread"] for c in out["calls"]] == ["MainThread"]


@pytest.mark.parametrize("scene", ["sts_sinusoidal_grid", "sts_fig16_overcut", "hts_toric_msa", "sts_mla_2x2",
                                   "compound_sinusoid", "rcse_circular_array", "sculpt_quad_mla"])
def test_the_turning_process_names_the_kernels_its_simulation_calls(tmp_path, scene):
    """A window of each turning scene simulated and written as the command does: every
    kernel of the package it calls is among the process's and the writing's kernels."""
    out = _python(f"""
        from pathlib import Path
        from render_inspect.scene import load_scene, find_scene
        from render_inspect.pipeline._simulate import simulate, write_simulation
        from render_inspect.pipeline._simulate_command import WRITE_KERNELS
        from render_inspect.processes import process_of
        from render_inspect.core.lazy import _kernel
        s = load_scene(find_scene({scene!r}))
        x0, y0, x1, y1 = s.simulation.region
        cx, cy, h = (x0 + x1) / 2, (y0 + y1) / 2, 30 * s.simulation.pixel
        s = load_scene(find_scene({scene!r}), [f"simulation.region=[{{cx - h}}, {{cy - h}}, {{cx + h}}, {{cy + h}}]"])
        sim = simulate(s)
        write_simulation(sim, Path({str(tmp_path / "out")!r}))
        named = [*process_of(s).kernels, *WRITE_KERNELS]
        listed = {{_kernel(n).py_func.__module__ + ":" + _kernel(n).py_func.__qualname__ for n in named}}
        called = sorted({{c["kernel"] for c in CALLS if c["kernel"].startswith("render_inspect.")}})
        print(json.dumps({{"listed": sorted(listed), "called": called, "n": len(named)}}))""", tmp_path,
                  record=True)
    assert len(out["listed"]) == out["n"], "a name is listed twice or names another's kernel"
    missing = sorted(set(out["called"]) - set(out["listed"]))
    assert not missing, f"kernels called but not preloaded: {missing}"
