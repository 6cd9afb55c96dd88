"""Arrays whose memory is made ready in a background thread (core.pages), and the cut
that writes into them."""

from __future__ import annotations

import ctypes
import mmap
import sys
import threading

import numpy as np
import pytest

from render_inspect.core.pages import MIN_BYTES, Prefaulted


def _resident(a: np.ndarray) -> np.ndarray:
    """Whether each system page under ``a`` is in memory (``mincore``): of these very
    pages, whatever the process's other memory or its counters say."""
    libc = ctypes.CDLL(None, use_errno=True)
    libc.mincore.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_void_p)
    page = mmap.PAGESIZE
    start = a.ctypes.data // page * page
    n = -(-(a.ctypes.data + a.nbytes - start) // page)
    vec = (ctypes.c_ubyte * n)()
    assert libc.mincore(start, n * page, vec) == 0, ctypes.get_errno()
    return np.frombuffer(vec, np.uint8) & 1 == 1


def _page_threads() -> list:
    return [t for t in threading.enumerate() if t.name == "render_inspect-pages"]


def test_prefaulted_arrays_have_their_shape_and_are_handed_over_once():
    p = Prefaulted((3, 5), 2, dtype=np.float32)
    got = p.take()
    assert len(got) == 2 and all(a.shape == (3, 5) and a.dtype == np.float32 for a in got)
    assert got[0] is not got[1] and p.take() == []
    # small arrays come from memory the process has: no thread
    assert p._thread is None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="mincore as Linux has it")
def test_prefaulted_pages_are_resident_when_taken(monkeypatch):
    # fresh pages of the system are not in memory until written (a new mapping: the
    # control that the check can say no); the prefaulted arrays' pages are, every one,
    # once taken, and their thread has ended.  Two usable CPUs assumed (the thread's
    # condition), so that the same thing is tested on a machine of one
    import render_inspect.core.pages as pages

    n = (2 * MIN_BYTES) // 8
    with mmap.mmap(-1, n * 8) as m:
        fresh = np.frombuffer(m, np.float64)
        assert not _resident(fresh).any()
        fresh[:] = 1.0
        assert _resident(fresh).all()
        del fresh
    monkeypatch.setattr(pages, "usable_cpus", lambda: 2)
    p = Prefaulted((n,), 2)
    assert p._thread is not None
    got = p.take()
    assert len(got) == 2 and all(_resident(a).all() for a in got)
    assert not _page_threads() and p._thread is None
    got[0][:] = 1.0
    assert got[0].sum() == n


def test_prefaulted_arrays_on_one_cpu_are_plain_and_made_when_taken(monkeypatch):
    # a machine of one usable CPU: no thread (it would only share the core); the arrays
    # are made when taken, of their shape and type
    import render_inspect.core.pages as pages

    monkeypatch.setattr(pages, "usable_cpus", lambda: 1)
    n = (2 * MIN_BYTES) // 4
    p = Prefaulted((n,), 1, dtype=np.float32)
    assert p._thread is None and p.arrays == []
    (a,) = p.take()
    assert a.shape == (n,) and a.dtype == np.float32 and not _page_threads()


def test_the_cut_writes_into_given_maps_the_maps_it_would_make(tmp_path):
    # maps given to the cut (any contents) come back as the result's, with the numbers of
    # the cut's own maps; maps of another shape or type are refused in one line
    from render_inspect.machining import Grooves, cut_turning, prepare_cut
    from render_inspect.toolpath import ToolPath

    th = np.linspace(0.0, 40 * 2 * np.pi, 40 * 360 + 1)
    path = ToolPath(th, 0.2 - 0.004 * th / (2 * np.pi), 1e-4 * np.cos(3 * th), th)
    cp = prepare_cut(path, nose_radius=0.5, half_width=0.25, h_min=1e-5, kappa=0.05)
    region, px = (0.02, -0.03, 0.08, 0.03), 0.001
    want = cut_turning(cp, Grooves.of(rms=1e-6, seed=2), region=region, pixel=px)
    maps = [np.full(want["machined"].shape, v) for v in (np.nan, -7.0, 1e300)]
    got = cut_turning(cp, Grooves.of(rms=1e-6, seed=2), region=region, pixel=px, out=maps)
    for k, m in zip(("machined", "pass_theta", "added"), maps):
        assert got[k] is m and np.array_equal(m, want[k], equal_nan=True), k
    for bad in ([maps[0], maps[1]], [maps[0], maps[1], maps[2].astype(np.float32)],
                [maps[0], maps[1], np.asfortranarray(maps[2])[:, :-1]]):
        with pytest.raises(ValueError, match="out"):
            cut_turning(cp, Grooves.none(), region=region, pixel=px, out=bad)
