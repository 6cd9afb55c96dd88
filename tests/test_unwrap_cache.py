"""The phase-unwrapping kernel is loaded from numba's cache in a second process, not
compiled again (it was rebuilt, and a new cache entry written, in every process)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

_CODE = """
import json
import numpy as np
from render_inspect.metrology import unwrap_phase
from render_inspect.metrology._unwrap_kernel import flood
y, x = np.mgrid[0:24, 0:30]
unwrap_phase(np.angle(np.exp(1j * 0.9 * (x + 0.5 * y))))
print(json.dumps({"hits": sum(flood.stats.cache_hits.values()),
                  "misses": sum(flood.stats.cache_misses.values())}))
"""


def _run(env):
    out = subprocess.run([sys.executable, "-c", _CODE], env=env, capture_output=True, text=True,
                         check=True, cwd=ROOT)
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_second_process_loads_the_unwrap_kernel_from_the_cache(tmp_path):
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    first = _run(env)
    assert first["misses"] >= 1          # compiled (a fresh cache folder)
    second = _run(env)
    assert second == {"hits": 1, "misses": 0}
    files = list((tmp_path / "numba").rglob("*.nbi"))
    third = _run(env)
    assert third == {"hits": 1, "misses": 0}
    assert sorted((tmp_path / "numba").rglob("*.nbi")) == sorted(files)   # nothing new written
