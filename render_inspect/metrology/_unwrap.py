"""Phase unwrapping in 2-D inside a mask: each pixel's reliability from its wrapped second
differences (after Herraez et al. 2002 [1]_) and a quality-guided flood fill from the most
reliable pixel of each connected region.

References
----------
.. [1] M. A. Herraez, D. R. Burton, M. J. Lalor, M. A. Gdeisat, "Fast two-dimensional
       phase-unwrapping algorithm based on sorting by reliability following a
       noncontinuous path," Applied Optics 41(35), 7437-7444 (2002).
       :DOI:`10.1364/AO.41.007437`
"""

from __future__ import annotations

import numpy as np

from ..core.errors import InputError

__all__ = ["phase_quality", "unwrap_phase"]


def _check_valid(valid, shape) -> np.ndarray:
    if valid is None:
        return np.ones(shape, dtype=bool)
    v = np.asarray(valid)
    if v.shape != shape:
        raise InputError(f"valid must have the frames' image shape {shape}, got {v.shape}")
    return v > 0.5 if v.dtype != bool else v.copy()


def _wrap(a):
    """Wrap to (-pi, pi]."""
    return a - 2 * np.pi * np.round(a / (2 * np.pi))


def phase_quality(phase: np.ndarray, *, valid: np.ndarray | None = None) -> np.ndarray:
    """Reliability of each pixel for unwrapping: ``1 / (1 + D)`` with D the root sum of
    squares of the wrapped second differences (horizontal, vertical, both diagonals;
    Herraez et al. 2002).  Pixels next to invalid ones or the border get lower quality;
    invalid pixels get 0.

    Parameters
    ----------
    phase : (H, W) wrapped phase, rad
    valid : (H, W) bool, optional
    """
    p = np.asarray(phase, dtype=np.float64)
    v = _check_valid(valid, p.shape) & np.isfinite(p)
    q = np.where(v, p, np.nan)
    pad = np.pad(q, 1, constant_values=np.nan)
    c = pad[1:-1, 1:-1]

    def sd(a, b):
        return _wrap(a - c) - _wrap(c - b)

    terms = [sd(pad[1:-1, :-2], pad[1:-1, 2:]), sd(pad[:-2, 1:-1], pad[2:, 1:-1]),
             sd(pad[:-2, :-2], pad[2:, 2:]), sd(pad[:-2, 2:], pad[2:, :-2])]
    penalty = 2 * np.pi  # a missing neighbour counts like a large second difference
    d2 = sum(np.where(np.isfinite(t), t * t, penalty ** 2) for t in terms)
    out = 1.0 / (1.0 + np.sqrt(d2))
    out[~v] = 0.0
    return out


def _build_kernel():
    """The flood-fill kernel (numba loads on first use; cached across processes)."""
    # numba is imported with the kernel, on first use (metrology imports without it)
    from ._unwrap_kernel import flood

    return flood


_KERNEL = None


def unwrap_phase(phase: np.ndarray, *, valid: np.ndarray | None = None,
                 quality: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Unwrap a 2-D wrapped phase inside a mask (quality-guided flood fill).

    Starting from the most reliable pixel of each connected valid region (4-connected),
    pixels are unwrapped in decreasing order of ``quality`` from an already unwrapped
    neighbour: ``u_j = u_i + wrap(phi_j - phi_i)``.  Noisy or steep areas (low quality)
    are reached last, so their errors do not spread.  Regions that do not touch are
    unwrapped independently (their relative offset is unknown to any interferometer).

    Parameters
    ----------
    phase : (H, W) float, rad
        Wrapped phase (any range; only differences mod 2 pi are used).
    valid : (H, W) bool, optional
        Pixels to unwrap; others come back NaN.  NaN phases are invalid too.
    quality : (H, W) float, optional
        Higher = more reliable.  Default :func:`phase_quality`.

    Returns
    -------
    unwrapped : (H, W) float64, rad (NaN outside the mask)
    labels : (H, W) int32, connected region of each pixel (0 = invalid)
    """
    global _KERNEL
    p = np.asarray(phase, dtype=np.float64)
    if p.ndim != 2:
        raise InputError(f"phase must be a 2-D array, got shape {p.shape}")
    v = _check_valid(valid, p.shape) & np.isfinite(p)
    q = phase_quality(p, valid=v) if quality is None else np.asarray(quality, dtype=np.float64)
    if q.shape != p.shape:
        raise InputError(f"quality must have the phase's shape {p.shape}, got {q.shape}")
    q = np.where(np.isfinite(q), q, -np.inf)
    if _KERNEL is None:
        _KERNEL = _build_kernel()
    order = np.argsort(-q.ravel(), kind="stable").astype(np.int64)
    out, labels = _KERNEL(np.ascontiguousarray(np.where(v, p, 0.0)), np.ascontiguousarray(v),
                          np.ascontiguousarray(q), order)
    return out, labels
