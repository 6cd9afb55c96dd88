"""Compiled kernel of the quality-guided phase unwrapping (:mod:`._unwrap`).

The functions sit at module level so that numba's cache finds them again in the next
process (a kernel built inside a function refers to its helpers through a closure, and
the cache's key of a closure differs from process to process: it compiled anew every
time).  Imported on first use: numba loads with it.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from ..core.lazy import load_numba

njit = load_numba().njit

__all__ = ["flood"]


@njit(cache=True)
def _heap_push(hq: npt.NDArray[np.float64], hi: npt.NDArray[np.int64], hs: npt.NDArray[np.int64],
               n: int, q: float, i: int, s: int) -> int:
    hq[n] = q
    hi[n] = i
    hs[n] = s
    k = n
    while k > 0:
        parent = (k - 1) // 2
        if hq[parent] >= hq[k]:
            break
        hq[parent], hq[k] = hq[k], hq[parent]
        hi[parent], hi[k] = hi[k], hi[parent]
        hs[parent], hs[k] = hs[k], hs[parent]
        k = parent
    return n + 1


@njit(cache=True)
def _heap_pop(hq: npt.NDArray[np.float64], hi: npt.NDArray[np.int64], hs: npt.NDArray[np.int64],
              n: int) -> tuple[int, int, int]:
    i, s = hi[0], hs[0]
    n -= 1
    hq[0], hi[0], hs[0] = hq[n], hi[n], hs[n]
    k = 0
    while True:
        l = 2 * k + 1
        r = l + 1
        m = k
        if l < n and hq[l] > hq[m]:
            m = l
        if r < n and hq[r] > hq[m]:
            m = r
        if m == k:
            break
        hq[m], hq[k] = hq[k], hq[m]
        hi[m], hi[k] = hi[k], hi[m]
        hs[m], hs[k] = hs[k], hs[m]
        k = m
    return i, s, n


@njit(cache=True)
def flood(phase: npt.NDArray[np.float64], valid: npt.NDArray[np.bool_],
          quality: npt.NDArray[np.float64], order: npt.NDArray[np.int64]
          ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.int32]]:
    """The wrapped ``phase`` (rad) unwrapped inside ``valid`` from the seeds ``order``
    (flat indices, most reliable first), each step to the neighbour of highest
    ``quality``: (unwrapped phase, NaN outside; label of each pixel's connected region,
    0 = invalid)."""
    h, w = phase.shape
    npx = h * w
    out = np.full(npx, np.nan)
    labels = np.zeros(npx, dtype=np.int32)
    ph = phase.ravel()
    va = valid.ravel()
    qu = quality.ravel()
    cap = 4 * npx + 4
    hq = np.empty(cap)
    hi = np.empty(cap, dtype=np.int64)
    hs = np.empty(cap, dtype=np.int64)
    twopi = 2.0 * np.pi
    label = 0
    for seed in order:  # seeds in decreasing quality: one per connected region
        if not va[seed] or labels[seed] != 0:
            continue
        label += 1
        out[seed] = ph[seed]
        labels[seed] = label
        n = np.int64(0)  # (not the literal 0: one compilation of the heap's functions, not two)
        cur = seed
        while True:
            r, c = cur // w, cur % w
            for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                rr, cc = r + dr, c + dc
                if rr < 0 or rr >= h or cc < 0 or cc >= w:
                    continue
                j = rr * w + cc
                if va[j] and labels[j] == 0:
                    n = _heap_push(hq, hi, hs, n, qu[j], j, cur)
            found = False
            while n > 0:
                j, s, n = _heap_pop(hq, hi, hs, n)
                if labels[j] == 0:
                    d = ph[j] - ph[s]
                    d -= twopi * np.round(d / twopi)
                    out[j] = out[s] + d
                    labels[j] = label
                    cur = j
                    found = True
                    break
            if not found:
                break
    return out.reshape(h, w), labels.reshape(h, w)
