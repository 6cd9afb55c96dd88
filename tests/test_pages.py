"""Arrays whose memory is made ready in a background thread (core.pages), and the cut
that writes into them."""

from __future__ import annotations

import sys
import threading

import numpy as np
import pytest

from render_inspect.core.pages import MIN_BYTES, Prefaulted


def _rss_bytes() -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no VmRSS")


def _page_threads() -> list:
    return [t for t in threading.enumerate() if t.name == "render_inspect-pages"]


def test_prefaulted_arrays_have_their_shape_and_are_handed_over_once():
    p = Prefaulted((3, 5), 2, dtype=np.float32)
    got = p.take()
    assert len(got) == 2 and all(a.shape == (3, 5) and a.dtype == np.float32 for a in got)
    assert got[0] is not got[1] and p.take() == []
    # small arrays come from memory the process has: no thread
    assert p._thread is None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status (Linux)")
def test_prefaulted_pages_are_resident_when_taken():
    # a fresh 64 MB array is not in memory until written; the prefaulted one is, once
    # taken, and its thread has ended
    n = (2 * MIN_BYTES) // 8
    before = _rss_bytes()
    plain = np.empty(n)
    assert _rss_bytes() - before < n * 8 // 4
    before = _rss_bytes()
    p = Prefaulted((n,), 1)
    (a,) = p.take()
    assert _rss_bytes() - before > 0.95 * n * 8
    assert not _page_threads()
    a[:] = 1.0
    assert a.sum() == n
    del plain


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
