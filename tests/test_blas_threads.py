"""The registration's products and solves of points x 6 run on one OpenBLAS thread
(render_inspect.core.blas): every OpenBLAS of the process (numpy's, SciPy's) is set to one
thread in the block and back to its count after it, nested blocks and errors included;
register_lsq, registration_covariance and the ICP's steps run so, with the same numbers."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest
import scipy.optimize  # noqa: F401  (SciPy's OpenBLAS mapped before the blocks run)

from render_inspect.core import blas
from render_inspect.metrology import _registration


class Wavy:
    """A surface with no symmetry: the six parameters are determined."""

    def height(self, x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        return x * x / 40.0 + y * y / 70.0 + 2e-3 * np.sin(12.6 * x) * np.cos(9.0 * y)

    def gradient(self, x, y):
        x, y = np.asarray(x, float), np.asarray(y, float)
        return (x / 20.0 + 2e-3 * 12.6 * np.cos(12.6 * x) * np.cos(9.0 * y),
                y / 35.0 - 2e-3 * 9.0 * np.sin(12.6 * x) * np.sin(9.0 * y))


def _numpy_blas() -> str:
    """The name of the BLAS numpy was built with ("" where its configuration says none)."""
    try:
        return str(np.show_config(mode="dicts")["Build Dependencies"]["blas"]["name"]).lower()
    except (TypeError, KeyError):
        return ""


@pytest.fixture
def two_threads():
    """Every OpenBLAS found set to two threads for the test (their counts set back after
    it); the counts seen."""
    switches = blas._switches()
    if sys.platform.startswith("linux") and "openblas" in _numpy_blas():
        # numpy's own OpenBLAS is mapped in this process: not finding it is a failure
        assert switches, "numpy's OpenBLAS was not found among the process's mapped files"
    before = [get() for get, _ in switches]
    for _, put in switches:
        put(2)
    counts = [get() for get, _ in switches]
    if not counts or max(counts) < 2:
        for (_, put), n in zip(switches, before):
            put(n)
        pytest.skip("no OpenBLAS that runs more than one thread here (one usable CPU, or no OpenBLAS)")
    yield counts
    for (_, put), n in zip(switches, before):
        put(n)


def test_one_thread_in_the_block_and_back_after(two_threads):
    ones = [1] * len(two_threads)
    assert blas.blas_threads() == two_threads
    with blas.one_blas_thread():
        assert blas.blas_threads() == ones
        with blas.one_blas_thread():
            assert blas.blas_threads() == ones
        assert blas.blas_threads() == ones  # the outer block still runs
    assert blas.blas_threads() == two_threads
    with pytest.raises(ValueError), blas.one_blas_thread():
        raise ValueError("stop")
    assert blas.blas_threads() == two_threads


def test_registration_solves_on_one_thread(two_threads, monkeypatch):
    """Each solve of register_lsq, the covariance's normal matrix and each ICP step run
    with every OpenBLAS on one thread."""
    seen = {}

    def spy(name, fn):
        def wrapped(*a, **k):
            seen.setdefault(name, []).append(blas.blas_threads())
            return fn(*a, **k)
        return wrapped

    monkeypatch.setattr(_registration, "least_squares",
                        spy("least_squares", _registration.least_squares))
    monkeypatch.setattr(_registration, "_normal_inverse",
                        spy("normal", _registration._normal_inverse))
    monkeypatch.setattr(np.linalg, "lstsq", spy("icp", np.linalg.lstsq))
    design = Wavy()
    x = -0.6 + 0.02 * np.arange(60)
    z = design.height(x[None, :] - 3e-3, x[:, None] + 2e-3) + 1e-3
    kw = {"pixel": 0.02, "origin": (x[0], x[0])}
    reg = _registration.register_lsq(z, design, **kw)
    assert reg["tx_mm"] == pytest.approx(3e-3, abs=1e-6)
    _registration.registration_covariance(z, design, reg, **kw)
    _registration.register_icp(z, design, oversample=2, max_iter=3, **kw)
    assert set(seen) == {"least_squares", "normal", "icp"}
    ones = [1] * len(two_threads)
    assert all(c == ones for calls in seen.values() for c in calls), seen
    assert blas.blas_threads() == two_threads


def test_the_mapped_files_are_read_again_only_after_an_import(monkeypatch):
    """A registration's blocks come one after another: the process's mapped files are read
    once, and again only once a module was imported (which may load another OpenBLAS)."""
    reads = []
    real = blas._mapped_openblas
    monkeypatch.setattr(blas, "_mapped_openblas", lambda: reads.append(1) or real())
    monkeypatch.setitem(blas._SCANNED, "modules", -1)
    for _ in range(5):
        with blas.one_blas_thread():
            pass
    assert len(reads) == 1
    monkeypatch.setitem(sys.modules, "render_inspect_test_newly_imported", types.ModuleType("x"))
    with blas.one_blas_thread():
        pass
    assert len(reads) == 2
