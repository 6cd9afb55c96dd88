"""Fringe-order failures, detected from the measurement itself.

A phase-shifting interferometer knows each pixel's height modulo half the effective
wavelength (the fringe order, ``lambda_eff / 2``); unwrapping carries the order from
pixel to pixel, and it fails where the phase jumps by more than half a fringe between
neighbours (a step higher than ``lambda_eff / 4``, a facet steeper than the pixel can
sample, noise in dark pixels).  No truth is needed to see it:

* **residues**: 2 x 2 loops of measured pixels whose wrapped phase differences do not
  sum to zero.  The phase around them is not single valued: some unwrapped path crosses
  a whole-fringe error (Goldstein, Zebker & Werner 1988 [1]_).
* **slips**: neighbouring measured pixels whose unwrapped heights differ by more than a
  quarter of the effective wavelength (half a fringe order): the flood fill never steps
  across such a pair, so one side carries a different order than the other.
* **modulation**: the fringe contrast of the pixels at slips, beside the map's median
  (a slip in dark, low-contrast pixels is noise; one in bright pixels is a surface step
  the instrument cannot follow).

The difference of two measurements is checked the same way: **jumps** (neighbours of
the levelled difference that differ by more than half a fringe order: one of the two
measurements slipped there) and **ambiguous regions** (regions that do not touch the
largest one and sit more than a quarter of a fringe order off its plane after the
nearest whole order is removed: their order is a guess).  A difference whose pixels of
unknown order exceed :data:`FAILED_FRACTION` is *failed*: it is not reported as a
measured difference.  Otherwise those pixels are masked and counted.

References
----------
.. [1] R. M. Goldstein, H. A. Zebker, C. L. Werner, "Satellite radar interferometry:
       two-dimensional phase unwrapping," Radio Science 23(4), 713-720 (1988).
       :DOI:`10.1029/RS023i004p00713`
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from ..core.lazy import lazy_module

from ..core.units import MM_TO_NM

if TYPE_CHECKING:
    from ._phase import PhaseResult

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["FAILED_FRACTION", "AMBIGUOUS_ORDER", "phase_residues", "fringe_order_check",
           "difference_order_check"]

#: A difference is failed when more than this fraction of the pixels both measured have
#: an unknown fringe order (next to a jump, in an ambiguous region, or in a region of
#: either measurement that slipped); assumed.
FAILED_FRACTION = 0.01
#: A separate region whose offset from the largest region's plane is more than this many
#: fringe orders from a whole number has an ambiguous order; assumed (a quarter: half way
#: to the wrong order's decision boundary).
AMBIGUOUS_ORDER = 0.25


def _wrap(a):
    return a - 2 * np.pi * np.round(a / (2 * np.pi))


def phase_residues(wrapped: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Residues of a wrapped phase (rad): (H-1, W-1) int, the sum of the wrapped
    differences around each 2 x 2 loop of valid pixels over 2 pi (0 elsewhere)."""
    p = np.where(valid, np.asarray(wrapped, np.float64), np.nan)
    d1 = _wrap(p[:-1, 1:] - p[:-1, :-1])
    d2 = _wrap(p[1:, 1:] - p[:-1, 1:])
    d3 = _wrap(p[1:, :-1] - p[1:, 1:])
    d4 = _wrap(p[:-1, :-1] - p[1:, :-1])
    s = (d1 + d2 + d3 + d4) / (2 * np.pi)
    return np.where(np.isfinite(s), np.round(s), 0).astype(np.int64)


def _jump_pixels(z, limit):
    """Pixels of ``z`` (NaN = none) next to a neighbour more than ``limit`` away, and the
    number of such neighbour pairs."""
    z = np.asarray(z, np.float64)
    out = np.zeros(z.shape, bool)
    n = 0
    with np.errstate(invalid="ignore"):
        jx = np.abs(np.diff(z, axis=1)) > limit
        jy = np.abs(np.diff(z, axis=0)) > limit
    n = int(jx.sum() + jy.sum())
    out[:, :-1] |= jx
    out[:, 1:] |= jx
    out[:-1, :] |= jy
    out[1:, :] |= jy
    return out, n


def _cut_off(ok, jump):
    """The pixels whose order a jump line leaves unknown: the jump pixels, and in each
    connected region of ``ok`` holding jumps, the parts that removing the jump pixels
    cuts off from its largest part."""
    unknown = jump.copy()
    if not jump.any():
        return unknown
    lab, _ = ndimage.label(ok)
    cut, _ = ndimage.label(ok & ~jump)
    for r in np.unique(lab[jump]):
        if r == 0:
            continue
        parts, counts = np.unique(cut[(lab == r) & (cut > 0)], return_counts=True)
        if parts.size > 1:
            keep = parts[np.argmax(counts)]
            unknown |= (lab == r) & (cut > 0) & (cut != keep)
    return unknown


def fringe_order_check(result: PhaseResult, *, fringe_order_mm: float | None) -> dict:
    """Fringe-order failures of one measurement (a :class:`~._phase.PhaseResult`), from
    the measurement alone.

    Returns a dict: ``residues``, ``slips`` (neighbour pairs more than half a fringe
    order apart), ``slip_pixels``, ``slip_regions`` (regions holding a slip),
    ``unknown_pixels``, ``slip_modulation`` and ``median_modulation`` (fringe
    contrast at the slips and over the map), and ``unknown_order`` ((H, W) bool: the
    slip pixels and what the slips cut off from the largest part of their region: their
    order is not measured).  Coherence scanning (absolute heights) has no order to
    check: ``fringe_order_mm`` None."""
    valid = np.asarray(result.valid, bool) & np.isfinite(result.height)
    out: dict[str, Any] = {"fringe_order_nm": None if fringe_order_mm is None else fringe_order_mm * MM_TO_NM,
           "residues": 0, "slips": 0, "slip_pixels": 0, "slip_regions": 0,
           "unknown_pixels": 0, "slip_modulation": None,
           "median_modulation": float(np.median(result.modulation[valid])) if valid.any() else None,
           "unknown_order": np.zeros(valid.shape, bool)}
    if not fringe_order_mm:
        out["method"] = "absolute heights (coherence scanning): no fringe order to check"
        return out
    res = phase_residues(result.wrapped, valid)
    jumps, n = _jump_pixels(np.where(valid, result.height, np.nan), fringe_order_mm / 2)
    jumps &= valid
    labels = np.where(valid, np.asarray(result.labels), 0)
    bad = np.unique(labels[jumps])
    bad = bad[bad > 0]
    unknown = _cut_off(valid, jumps)
    out.update(residues=int(np.count_nonzero(res)), slips=n, slip_pixels=int(jumps.sum()),
               slip_regions=int(bad.size), unknown_pixels=int(unknown.sum()),
               slip_modulation=float(np.median(result.modulation[jumps])) if jumps.any() else None,
               unknown_order=unknown,
               method="residues of the wrapped phase; neighbours of the unwrapped height more "
                      "than half a fringe order apart")
    return out


def difference_order_check(levelled: np.ndarray, *, fringe_order_mm: float | None,
                           checks: Sequence[dict] = (),
                           labels: np.ndarray | None = None) -> dict:
    """Fringe-order check of a levelled difference of two measurements (mm, NaN = not
    measured in both): ``jumps``, ``jump_pixels``, ``ambiguous_regions`` and their
    ``ambiguous_pixels``, the pixels of the two measurements' slipped regions
    (``checks``: their :func:`fringe_order_check` dicts), ``unknown_fraction`` of the
    pixels both measured, ``status`` ("ok", "masked": the unknown pixels are masked, or
    "failed": more than :data:`FAILED_FRACTION` unknown), ``reasons`` and ``mask`` ((H, W)
    bool, the pixels kept)."""
    z = np.asarray(levelled, np.float64)
    ok = np.isfinite(z)
    npx = int(ok.sum())
    out = {"status": "ok", "reasons": [], "jumps": 0, "jump_pixels": 0, "ambiguous_regions": 0,
           "ambiguous_pixels": 0, "slipped_pixels": 0, "unknown_fraction": 0.0, "pixels": npx,
           "failed_fraction": FAILED_FRACTION, "mask": ok}
    if not fringe_order_mm or npx == 0:
        return out
    fo = float(fringe_order_mm)
    jump, n = _jump_pixels(z, fo / 2)
    jump &= ok
    jump = _cut_off(ok, jump)
    lab = ndimage.label(ok)[0] if labels is None else np.where(ok, labels, 0)
    ids, counts = np.unique(lab[lab > 0], return_counts=True)
    amb = np.zeros(z.shape, bool)
    n_amb = 0
    if ids.size > 1:
        main = ids[np.argmax(counts)]
        z0 = float(np.median(z[lab == main]))
        for i in ids:
            if i == main:
                continue
            sel = lab == i
            frac = (float(np.median(z[sel])) - z0) / fo
            if abs(frac - round(frac)) > AMBIGUOUS_ORDER:
                amb |= sel
                n_amb += 1
    slipped = np.zeros(z.shape, bool)
    for c in checks:
        u = c.get("unknown_order")
        if u is not None and u.shape == z.shape:
            slipped |= u
    slipped &= ok
    unknown = jump | amb | slipped
    frac = float(unknown.sum()) / npx
    out.update(jumps=n, jump_pixels=int(jump.sum()), ambiguous_regions=n_amb,
               ambiguous_pixels=int(amb.sum()), slipped_pixels=int(slipped.sum()),
               unknown_fraction=frac, mask=ok & ~unknown)
    reasons = []
    if n:
        reasons.append(f"{n} neighbouring pixel pairs of the difference differ by more than half "
                       f"a fringe order ({fo / 2 * MM_TO_NM:.4g} nm): a measurement slipped")
    if n_amb:
        reasons.append(f"{n_amb} separate regions ({int(amb.sum())} pixels) sit between two "
                       f"fringe orders of the largest region: their order is a guess")
    if slipped.any():
        reasons.append(f"{int(slipped.sum())} pixels lie in regions where a measurement's "
                       f"unwrapping slipped (phase residues, jumps of more than half a fringe)")
    out["reasons"] = reasons
    if frac > FAILED_FRACTION:
        out["status"] = "failed"
    elif unknown.any():
        out["status"] = "masked"
    return out
