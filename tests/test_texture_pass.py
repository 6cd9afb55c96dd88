"""The part's texture: its unit field (row blocks of one matrix product on one OpenBLAS
thread each) against the sum of its random modes, the same bits on threads side by side, on
a thread of its own (paused, resumed, its result taken early or late) and for any core
count; and the texture added in one compiled pass gives the numbers of the array
expressions it replaced, to the last bit (the heights and the measured rms go into
heightmap.exr and metrics.json)."""

import math

import numpy as np
import pytest

from render_inspect.core.blas import blas_threads
from render_inspect.machining import TextureJob, add_texture_field, texture_field
from render_inspect.machining._texture import BLOCK_ROWS, TEXTURE_MODES, _modes, unit_field


def _modes_sum(x, y, correlation_length, seed):
    """The unit field by its definition: the sum over the modes of cos(kx x + ky y + p)."""
    k, ph = _modes(correlation_length, seed)
    yy, xx = np.meshgrid(y, x, indexing="ij")
    return sum(np.cos(k[i, 0] * xx + k[i, 1] * yy + ph[i]) for i in range(TEXTURE_MODES))


def _reference(machined, x, y, *, rms, correlation_length, seed):
    """The texture added as numpy array expressions on the unit field."""
    f = unit_field(x, y, correlation_length, seed)
    tex = f * (rms * math.sqrt(2.0 / TEXTURE_MODES)) if rms else np.zeros(f.shape)
    ok = np.isfinite(machined)
    out = np.where(ok, machined + tex, machined)
    return out, (float(np.sqrt(np.mean(tex[ok] ** 2))) if ok.any() else 0.0)


def _maps():
    rng = np.random.default_rng(2)
    y, x = np.mgrid[0:203, 0:317] * 0.001
    z = 0.002 * np.sin(x / 0.05) * np.cos(y / 0.07) + rng.normal(scale=1e-6, size=x.shape)
    holes = z.copy()
    holes[::7, ::3] = np.nan
    holes[5] = np.inf
    holes[:, 11] = -np.inf
    signed_zero = np.zeros((9, 13))
    signed_zero[::2] = -0.0
    return {"finite": z, "holes": holes, "all_nan": np.full((4, 6), np.nan),
            "one_row": z[:1], "one_column": z[:, :1], "zeros": signed_zero}


@pytest.mark.parametrize("name", list(_maps()))
@pytest.mark.parametrize("rms", [0.0, 3e-6])
def test_texture_pass_matches_the_array_expressions_bit_for_bit(name, rms):
    m = _maps()[name]
    ny, nx = m.shape
    x = -0.3 + 0.001 * np.arange(nx)
    y = 0.25 + 0.001 * np.arange(ny)
    ref, ref_rms = _reference(m, x, y, rms=rms, correlation_length=0.03, seed=7)
    got, got_rms = add_texture_field(m, x, y, rms=rms, correlation_length=0.03, seed=7)
    assert got.dtype == np.float64 and got.shape == m.shape
    assert np.array_equal(got.view(np.int64), ref.view(np.int64))   # NaN, -0.0 included
    assert got_rms == ref_rms
    assert got is not m and (name == "all_nan" or not np.array_equal(got, m) or rms == 0)


def test_texture_field_keeps_its_numbers():
    x = np.linspace(0.0, 0.4, 57)
    y = np.linspace(-0.1, 0.2, 31)
    ref, _ = _reference(np.zeros((31, 57)), x, y, rms=2e-6, correlation_length=0.05, seed=3)
    assert np.array_equal(texture_field(x, y, rms=2e-6, correlation_length=0.05, seed=3) + 0.0, ref)


def test_unit_field_is_the_sum_of_its_modes():
    """The matrix product of the factors (the package's cosine and sine) equals the sum of
    the modes' cosines to rounding, over several row blocks and a last partial one."""
    x = np.linspace(-0.3, 0.5, 41)
    y = np.linspace(-0.2, 0.6, 2 * BLOCK_ROWS + 37)
    got = unit_field(x, y, 0.03, 9)
    want = _modes_sum(x, y, 0.03, 9)
    assert np.max(np.abs(got - want)) < 1e-12 * math.sqrt(TEXTURE_MODES)
    assert np.std(want) == pytest.approx(math.sqrt(TEXTURE_MODES / 2), rel=0.3)


def _grid(ny=3 * BLOCK_ROWS + 11, nx=203):
    return 0.2 + 0.0007 * np.arange(nx), -0.4 + 0.0009 * np.arange(ny)


def test_texture_job_gives_the_unit_fields_bits():
    """The field computed on a thread of its own: taken at once, after pauses and resumes,
    with the calling thread's help or after the thread did all: the same bits as on
    threads side by side; OpenBLAS has its threads back afterwards (on one meanwhile)."""
    x, y = _grid()
    want = unit_field(x, y, 0.02, 4)
    before = blas_threads()
    job = TextureJob(x, y, 0.02, 4)
    assert job.result().tobytes() == want.tobytes()
    job = TextureJob(x, y, 0.02, 4, out=np.full((y.size, x.size), 9.0))
    job.pause()
    if before and max(before) > 1:
        assert max(blas_threads()) == 1
    job.resume()
    job.pause()
    job.resume()
    got = job.result()
    assert got.tobytes() == want.tobytes()
    assert blas_threads() == before
    job.close()                                  # (once: nothing more)
    assert blas_threads() == before


def test_texture_job_closed_early_stops_and_gives_back_the_threads():
    x, y = _grid(ny=20 * BLOCK_ROWS)
    before = blas_threads()
    job = TextureJob(x, y, 0.02, 4)
    job.pause()
    job.close()
    assert blas_threads() == before
    assert not job._thread.is_alive()


def test_unit_field_does_not_depend_on_the_threads():
    """Each row block is one product on one OpenBLAS thread: the same bits computed in one
    thread of the caller (as inside a pool that runs tiles side by side) as on threads."""
    import threading

    x, y = _grid()
    want = unit_field(x, y, 0.02, 6)
    box = {}
    t = threading.Thread(target=lambda: box.setdefault("f", unit_field(x, y, 0.02, 6)), name="pool-thread")
    t.start()
    t.join()
    assert box["f"].tobytes() == want.tobytes()


def test_texture_pass_checks_the_grid():
    from render_inspect.core.errors import InputError

    with pytest.raises(InputError, match="grid's shape"):
        add_texture_field(np.zeros((3, 4)), np.arange(5.0), np.arange(3.0), rms=1e-6,
                          correlation_length=0.03, seed=0)


def test_textured_with_the_factors_kept_along_x_equals_it_without():
    """``textured(..., cache=)`` (the tiles of a column share their columns): the same
    bits as the definition, on rows that follow each other, and after the columns change."""
    from render_inspect.machining._texture import textured

    z = _maps()["holes"]
    x = 0.3 + 0.001 * np.arange(z.shape[1])
    cache: dict = {}
    for rows, xs in ((slice(0, 90), x), (slice(60, 203), x), (slice(10, 50), x + 0.001), (slice(0, 203), x)):
        m = np.ascontiguousarray(z[rows])
        y = -0.1 + 0.001 * np.arange(rows.start, rows.stop)
        got, sq = textured(m, xs, y, rms=1e-6, correlation_length=0.03, seed=5, cache=cache)
        want, _ = _reference(m, xs, y, rms=1e-6, correlation_length=0.03, seed=5)
        assert got.tobytes() == want.tobytes()
        assert np.array_equal(cache["texture_x"][1], xs)
    assert textured(m, x, y, rms=1e-6, correlation_length=0.03, seed=5)[0].tobytes() == got.tobytes()


@pytest.mark.parametrize("name", ["finite", "holes", "all_nan", "one_row", "zeros"])
def test_texture_added_in_place_with_given_buffers_keeps_the_numbers(name):
    """``overwrite=True`` (the map itself becomes the textured map) and ``buffers`` (maps
    the products are computed in, full of earlier numbers): the same bits and rms as the
    definition; the map returned is the one given; a buffer of another shape, or one that
    shares memory with the map, is not written."""
    m0 = _maps()[name]
    ny, nx = m0.shape
    x = -0.3 + 0.001 * np.arange(nx)
    y = 0.25 + 0.001 * np.arange(ny)
    ref, ref_rms = _reference(m0, x, y, rms=3e-6, correlation_length=0.03, seed=7)
    m = m0.copy()
    bufs = (np.full(m.shape, 5.0), np.full(m.shape, -7.0))
    got, got_rms = add_texture_field(m, x, y, rms=3e-6, correlation_length=0.03, seed=7,
                                     overwrite=True, buffers=bufs)
    assert got is m
    assert np.array_equal(got.view(np.int64), ref.view(np.int64))
    assert got_rms == ref_rms
    assert not np.array_equal(bufs[0], np.full(m.shape, 5.0))         # computed in
    wrong = np.full((ny + 1, nx), 3.0)
    m = m0.copy()
    got, got_rms = add_texture_field(m, x, y, rms=3e-6, correlation_length=0.03, seed=7,
                                     overwrite=True, buffers=(wrong, m[::-1]))
    assert np.array_equal(got.view(np.int64), ref.view(np.int64)) and got_rms == ref_rms
    assert (wrong == 3.0).all()
