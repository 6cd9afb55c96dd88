"""Large arrays whose memory is made ready on a spare core before they are written.

A new array of a megapixel map gets fresh memory from the system, which supplies and
zeroes each page the first time it is written: about 0.05 s per 128 MB map here, paid by
whichever thread writes first (on a virtual machine that hands its free memory back to its
host, more).  Where the calling thread has other work to do first (the machine following
the program before the cut), :class:`Prefaulted` writes one value to each page of the
arrays in a background thread (numpy does that without the interpreter's lock), so the
system's share is done on a spare core meanwhile; :meth:`Prefaulted.take` waits for it and
hands the arrays over.  Their contents are undefined, as ``numpy.empty``'s: the results do
not depend on it.

Only arrays of at least :data:`MIN_BYTES` are worth it (smaller ones come from memory the
process already has), and only where the process may use more than one core.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence

import numpy as np

from .limits import usable_cpus

__all__ = ["Prefaulted", "MIN_BYTES"]

#: bytes: smaller arrays are taken from memory freed before (glibc's mmap threshold as the
#: command sets it), so they are not written ahead
MIN_BYTES = 32 * 1024 * 1024
#: bytes between the values written (the system's page)
_PAGE = 4096


class Prefaulted:
    """``count`` new arrays of ``shape`` and ``dtype`` whose pages a background thread
    writes once (for arrays of at least :data:`MIN_BYTES` on a machine with a spare
    core; otherwise plain ``numpy.empty`` arrays, made when they are taken).

    Parameters
    ----------
    shape : sequence of int
    count : int
    dtype : numpy dtype, default float64
    """

    def __init__(self, shape: Sequence[int], count: int, dtype=np.float64) -> None:
        self._shape, self._count, self._dtype = tuple(int(n) for n in shape), int(count), np.dtype(dtype)
        self.arrays: list[np.ndarray] = []
        self._thread: threading.Thread | None = None
        nbytes = int(np.prod(self._shape)) * self._dtype.itemsize
        if self._count > 0 and nbytes >= MIN_BYTES and usable_cpus() > 1:
            self.arrays = [np.empty(self._shape, dtype=self._dtype) for _ in range(self._count)]
            self._thread = threading.Thread(target=self._touch, name="render_inspect-pages", daemon=True)
            self._thread.start()

    def _touch(self) -> None:
        for a in self.arrays:
            flat = a.reshape(-1)
            flat[::max(1, _PAGE // a.itemsize)] = 0
            # (an array need not start on a page: its last values may lie on one more)
            flat[-1:] = 0

    def take(self) -> list[np.ndarray]:
        """The arrays, once their pages are written (waits for the thread); arrays not
        written ahead are made now.  Once: a second call returns []."""
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        elif self._count and not self.arrays:
            self.arrays = [np.empty(self._shape, dtype=self._dtype) for _ in range(self._count)]
        self._count = 0
        arrays, self.arrays = self.arrays, []
        return arrays
