"""The part's texture: a Gaussian random field of the position (random Fourier modes),
summed on a grid as one matrix product in row blocks, and added to a machined map.

The field is a sum of ``2 M`` products of a factor along y and a factor along x
(cos(kx x + ky y + p) = cos(ky y) cos(kx x + p) - sin(ky y) sin(kx x + p)), so on a grid it
is the matrix product of an (ny, 2 M) and a (2 M, nx) factor.  The product is taken in
blocks of :data:`BLOCK_ROWS` rows from the grid's first row, each block one product on one
OpenBLAS thread: a block's numbers do not depend on which thread takes it, or on how many
cores the machine has (a product on several threads sums some elements in another order).
Blocks are taken on threads side by side (:func:`unit_field`), or on a thread of their own
while the caller works on other things (:class:`TextureJob`): the same numbers either way.
"""

from __future__ import annotations

import math
import threading
from typing import Any

import numpy as np

from ..core import trig
from ..core.blas import one_blas_thread
from ..core.errors import InputError, check_range
from ..core.lazy import njit  # numba, imported on first use
from ..core.threads import over_rows

__all__ = ["texture_field", "add_texture_field", "textured", "unit_field", "TextureJob", "TEXTURE_MODES",
           "BLOCK_ROWS"]

#: modes of the texture's random field
TEXTURE_MODES = 128
#: rows of the grid per block of the matrix product (about 5 ms on one core for a row of
#: 4001 points; the product's own packing costs about a tenth more than in one piece)
BLOCK_ROWS = 128


def _modes(correlation_length: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The modes' wave vectors (M, 2) (1/mm) and phases (M,) drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    k = rng.normal(0.0, 1.0 / correlation_length, size=(TEXTURE_MODES, 2))
    ph = rng.uniform(0.0, 2 * math.pi, size=TEXTURE_MODES)
    return k, ph


def _factors(x: np.ndarray, y: np.ndarray, correlation_length: float, seed: int,
             cache: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The field's factors: [cos(ky y), -sin(ky y)] (ny, 2 M) and [cos(kx x + p); sin(kx x +
    p)] (2 M, nx), by the package's vectorised cosine and sine (:mod:`render_inspect.core.trig`).
    ``cache``: a dict that keeps the factor along ``x`` for the next call with the same
    ``x`` (the tiles of a column)."""
    k, ph = _modes(correlation_length, seed)
    kept = cache.get("texture_x") if cache is not None else None
    if kept is not None and kept[0] == (correlation_length, seed) and np.array_equal(kept[1], x):
        fx = kept[2]
    else:
        ax = np.multiply.outer(k[:, 0], x) + ph[:, None]
        fx = np.concatenate(trig.cos_sin(ax))
        if cache is not None:
            cache["texture_x"] = ((correlation_length, seed), np.array(x, copy=True), fx)
    cy, sy = trig.cos_sin(np.multiply.outer(y, k[:, 1]))
    fy = np.concatenate([cy, np.negative(sy, out=sy)], axis=1)
    return fy, fx


def _blocks(fy: np.ndarray, fx: np.ndarray, out: np.ndarray, b0: int, b1: int) -> None:
    """Row blocks b0 .. b1 - 1 of the product fy fx into ``out`` (each block one product)."""
    ny = out.shape[0]
    for b in range(b0, b1):
        r0, r1 = b * BLOCK_ROWS, min((b + 1) * BLOCK_ROWS, ny)
        np.matmul(fy[r0:r1], fx, out=out[r0:r1])


def _block_count(ny: int) -> int:
    return -(-ny // BLOCK_ROWS)


def _grid(x: Any, y: Any) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(x, dtype=np.float64).reshape(-1), np.asarray(y, dtype=np.float64).reshape(-1)


def unit_field(x: Any, y: Any, correlation_length: float, seed: int, *, cache: dict | None = None,
               out: np.ndarray | None = None) -> np.ndarray:
    """The texture's unit field before its scale, sum over the modes of cos(kx x + ky y +
    p), on the grid ``x`` (nx,) by ``y`` (ny,): (ny, nx) float64, in ``out`` where given
    (a C-contiguous float64 array of that shape).  Its row blocks run on threads side by
    side where the caller may start them (:func:`~render_inspect.core.threads.over_rows`)."""
    x, y = _grid(x, y)
    fy, fx = _factors(x, y, correlation_length, seed, cache)
    if out is None:
        out = np.empty((y.size, x.size))
    with one_blas_thread():
        over_rows(_blocks, _block_count(y.size), fy, fx, out)
    return out


def _scale(rms: float) -> float:
    return rms * math.sqrt(2.0 / TEXTURE_MODES)


def texture_field(x: np.ndarray, y: np.ndarray, *, rms: float, correlation_length: float,
                  seed: int) -> np.ndarray:
    """The part's texture on the grid ``x`` (nx,) by ``y`` (ny,) (mm): a unit-variance
    Gaussian random field of the position with covariance exp(-r^2 / (2 l^2)) (random
    Fourier modes from ``seed``), times ``rms``.  It depends on the position only: the same
    seed gives the same texture on any grid and for any tool path (to the last bits of
    the sum over the modes, whose order of summation follows the grid's row blocks).

    Returns
    -------
    (ny, nx) float64, mm
    """
    check_range("rms", rms, 0.0, 1.0)
    check_range("correlation_length", correlation_length, 0.0, None, lo_open=True)
    x, y = _grid(x, y)
    if rms == 0:
        return np.zeros((y.size, x.size))
    return unit_field(x, y, correlation_length, seed) * _scale(rms)


class TextureJob:
    """The texture's unit field on a grid (:func:`unit_field`'s numbers) computed on a
    thread of its own while the caller does other work, to use a core the caller leaves
    idle; :meth:`result` takes the blocks not yet done in the calling thread too.

    While the job runs, every OpenBLAS of the process computes on one thread (its blocks
    are products on one thread; the caller's own products in that time are too).
    :meth:`pause` makes the thread stop before its next block (while the caller's work
    uses every core), :meth:`resume` lets it go on.  :meth:`close` ends the job (its
    result no longer wanted, an error or a stop in the caller); :meth:`result` closes it.

    Parameters
    ----------
    x, y : (nx,), (ny,) arrays, mm
    correlation_length : float, mm
    seed : int
    out : (ny, nx) float64 array, optional
        Where the field is written (C-contiguous; any contents); default: a new array.
    """

    def __init__(self, x: Any, y: Any, correlation_length: float, seed: int, *,
                 out: np.ndarray | None = None) -> None:
        self._x, self._y = _grid(x, y)
        self._length, self._seed = float(correlation_length), int(seed)
        self._blocks = _block_count(self._y.size)
        self._lock = threading.Lock()
        shape = (self._y.size, self._x.size)
        if out is not None and not (isinstance(out, np.ndarray) and out.shape == shape and out.dtype == np.float64
                                    and out.flags.c_contiguous and out.flags.writeable):
            raise ValueError(f"TextureJob: out must be a writeable C-contiguous float64 array of shape {shape}")
        self._out = out
        self._go = threading.Event()
        self._go.set()
        self._ready = threading.Event()
        self._next = 0
        self._stop = False
        self._error: BaseException | None = None
        self._parts: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._blas = one_blas_thread()
        self._blas.__enter__()
        self._open = True
        self._thread = threading.Thread(target=self._run, name="render_inspect-texture", daemon=True)
        try:
            self._thread.start()
        except BaseException:
            self._open = False
            self._blas.__exit__(None, None, None)
            raise

    def _run(self) -> None:
        try:
            fy, fx = _factors(self._x, self._y, self._length, self._seed)
            out = self._out if self._out is not None else np.empty((self._y.size, self._x.size))
            self._parts = (fy, fx, out)
        except BaseException as exc:  # (raised again by result)
            self._error = exc
        finally:
            self._ready.set()
        if self._error is None:
            self._work(wait=True)

    def _take(self) -> int:
        with self._lock:
            b = self._next
            if self._stop or b >= self._blocks:
                return -1
            self._next = b + 1
            return b

    def _work(self, wait: bool) -> None:
        fy, fx, out = self._parts  # type: ignore[misc]
        while True:
            if wait:
                self._go.wait()
            b = self._take()
            if b < 0:
                return
            try:
                _blocks(fy, fx, out, b, b + 1)
            except BaseException as exc:
                with self._lock:
                    self._error = self._error or exc
                    self._stop = True
                return

    def pause(self) -> None:
        """The thread stops before its next block (the one it is computing is finished)."""
        self._go.clear()

    def resume(self) -> None:
        """The thread goes on with the blocks not yet taken."""
        self._go.set()

    def result(self) -> np.ndarray:
        """The unit field, (ny, nx) float64: the calling thread takes blocks too until none
        is left, then waits for the thread's last one."""
        try:
            self._go.set()
            self._ready.wait()
            if self._error is None:
                self._work(wait=False)
            self._thread.join()
            if self._error is not None:
                raise self._error
            assert self._parts is not None
            return self._parts[2]
        finally:
            self.close()

    def close(self) -> None:
        """End the job: no further blocks are started, the thread's block in progress is
        waited for (a few milliseconds) and OpenBLAS gets back its threads.  Once: later
        calls do nothing."""
        if not self._open:
            return
        self._open = False
        with self._lock:
            self._stop = True
        self._go.set()
        self._thread.join()
        self._blas.__exit__(None, None, None)


@njit(cache=True, nogil=True)
def _add_rows(m, unit, sq, scale, res, finite_rows, i0, i1):
    """In place: ``res`` (``unit`` or ``m`` itself) becomes the map with the texture (the
    unit field times ``scale``) added where it is finite (unchanged elsewhere), ``sq`` the
    texture's square there and NaN elsewhere; the finite pixels of each row counted (rows
    i0 .. i1 - 1)."""
    ny, nx = m.shape
    for i in range(i0, i1):
        n = 0
        for j in range(nx):
            t = unit[i, j] * scale
            v = m[i, j]
            if math.isfinite(v):
                res[i, j] = v + t
                sq[i, j] = t * t
                n += 1
            else:
                res[i, j] = v
                sq[i, j] = math.nan
        finite_rows[i] = n


def textured(machined: np.ndarray, x: np.ndarray, y: np.ndarray, *, rms: float,
             correlation_length: float, seed: int,
             cache: dict | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(``machined`` with :func:`texture_field` added where it is finite, the texture's
    square there (other pixels: undefined)), new (ny, nx) arrays; ``machined`` a
    C-contiguous float64 map and ``rms`` > 0.  The same numbers, to the last bit, as
    ``np.where(ok, machined + tex, machined)`` and ``tex ** 2`` with numpy, ``tex`` the
    unit field times the scale.  ``cache``: a dict kept between calls on the same columns
    ``x`` (the field's factor along x is taken from it: the same numbers)."""
    check_range("rms", rms, 0.0, 1.0)
    check_range("correlation_length", correlation_length, 0.0, None, lo_open=True)
    out = unit_field(x, y, correlation_length, seed, cache=cache)
    sq = np.empty(out.shape)
    over_rows(_add_rows, machined.shape[0], machined, out, sq, _scale(rms), out,
              np.empty(machined.shape[0], dtype=np.int64))
    return out, sq


def add_texture_field(machined: np.ndarray, x: np.ndarray, y: np.ndarray, *, rms: float,
                      correlation_length: float, seed: int, overwrite: bool = False,
                      buffers: tuple = (), unit: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """``machined`` (ny, nx) with :func:`texture_field` on the grid ``x`` by ``y`` added
    where it is finite (a new array; NaN and infinite pixels unchanged), and the added
    texture's root mean square over those pixels (mm; 0 when there are none).  The same
    numbers, to the last bit, as adding the field with numpy; one pass over the map.

    ``overwrite``: the texture is added into ``machined`` itself (when it is a
    C-contiguous float64 array) and that array is returned.  ``buffers``: up to two
    (ny, nx) arrays whose content the caller no longer needs; the unit field and the
    texture's squares are computed into them instead of into new arrays (one that is not
    C-contiguous float64 of the map's shape, or that shares memory with ``machined``, is
    not used).  Either saves the memory of a map and the time of touching it first.
    ``unit``: the unit field on this grid already computed (:class:`TextureJob`), used
    as it is (and as the first buffer)."""
    m = np.ascontiguousarray(machined, dtype=np.float64)
    if rms == 0 or m.ndim != 2 or m.size == 0:
        tex = texture_field(x, y, rms=rms, correlation_length=correlation_length, seed=seed)
        ok = np.isfinite(m)
        out = np.where(ok, m + tex, m)
        return out, (float(np.sqrt(np.mean(tex[ok] ** 2))) if ok.any() else 0.0)
    check_range("rms", rms, 0.0, 1.0)
    check_range("correlation_length", correlation_length, 0.0, None, lo_open=True)
    x, y = _grid(x, y)
    if m.shape != (y.size, x.size):
        raise InputError(f"machined must have the grid's shape {(y.size, x.size)}, "
                         f"received {m.shape}")
    free: list = []
    if unit is not None:
        if unit.shape != m.shape or unit.dtype != np.float64:
            raise InputError(f"the texture's unit field must be float64 of the grid's shape {m.shape}, "
                             f"received {unit.dtype} {unit.shape}")
        free.append(unit)
    for b in buffers:
        if len(free) < 2 and _usable_buffer(b, m) and not any(np.may_share_memory(b, f) for f in free):
            free.append(b)
    free += [None] * (2 - len(free))
    field = unit if unit is not None else unit_field(x, y, correlation_length, seed, out=free[0])
    sq = free[1] if free[1] is not None else np.empty(m.shape)
    out = m if overwrite and m.flags.writeable and m is machined else field
    rows = np.empty(m.shape[0], dtype=np.int64)
    over_rows(_add_rows, m.shape[0], m, field, sq, _scale(rms), out, rows)
    n_ok = int(rows.sum())
    if n_ok == 0:
        return out, 0.0
    # the mean of the squares as numpy takes it over the finite pixels in order (the
    # squares are NaN where the map is not finite)
    squares = sq.ravel() if n_ok == m.size else sq[np.isfinite(sq)]
    return out, float(np.sqrt(np.mean(squares)))


def _usable_buffer(b, m: np.ndarray) -> bool:
    """Whether ``b`` can take one of the texture's factors for the map ``m``."""
    return (isinstance(b, np.ndarray) and b.shape == m.shape and b.dtype == np.float64
            and b.flags.c_contiguous and b.flags.writeable and not np.may_share_memory(b, m))
