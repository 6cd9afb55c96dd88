"""EXR files are compressed by OpenEXR's threads, one per usable CPU, while they are
written: the file's bytes are those a single thread writes, and no threads are left
behind afterwards."""

import numpy as np
import pytest

from render_inspect.io import _exr
from render_inspect.io._exr import compression_threads, write_exr


def _channels():
    rng = np.random.default_rng(3)
    y, x = np.mgrid[0:200, 0:170]
    return {f"frame_{k:03d}": (np.rint((0.5 + 0.3 * np.cos(0.1 * x + 0.07 * y + k)
                                        + rng.normal(0, 0.01, x.shape)) * 4095) / 4095
                               ).astype(np.float32) for k in range(6)}


@pytest.mark.parametrize("tile", [None, 64])
def test_threaded_compression_writes_the_single_thread_bytes(tmp_path, monkeypatch, tile):
    import OpenEXR

    ch = _channels()
    monkeypatch.setattr(_exr, "usable_cpus", lambda: 1)
    write_exr(tmp_path / "one.exr", ch, {"note": "x"}, tile=tile)
    monkeypatch.setattr(_exr, "usable_cpus", lambda: 4)
    seen = []
    real = OpenEXR.File

    class Spy(real):  # the pool's size while the file is written
        def write(self, *a, **k):
            seen.append(OpenEXR.global_thread_count())
            return super().write(*a, **k)

    monkeypatch.setattr(OpenEXR, "File", Spy)
    write_exr(tmp_path / "four.exr", ch, {"note": "x"}, tile=tile)
    assert seen == [4]
    assert OpenEXR.global_thread_count() == 0
    assert (tmp_path / "one.exr").read_bytes() == (tmp_path / "four.exr").read_bytes()


def test_nested_writers_keep_the_pool_until_the_last_leaves(monkeypatch):
    import OpenEXR

    monkeypatch.setattr(_exr, "usable_cpus", lambda: 3)
    with compression_threads():
        with compression_threads():
            assert OpenEXR.global_thread_count() == 3
        assert OpenEXR.global_thread_count() == 3
    assert OpenEXR.global_thread_count() == 0
