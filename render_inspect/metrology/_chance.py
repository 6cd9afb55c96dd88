"""Is a registration better than chance?  A measured map is registered to a design by a
search (least squares or ICP from the file's place); a map of another surface of like
relief is registered too, and its residual can be as small as a real part's form error.
What tells them apart is the registration's score set against what the same search
reaches on surrogates of the measured map that keep its spectrum but not its structure.

- :func:`phase_surrogate`: a phase-randomised surrogate of a profile or a map (the same
  amplitude spectrum, random phases; Theiler et al. 1992 [1]_).
- :func:`explained_share`: the score: the share of the measured map's variance (a plane
  removed) that the registered design explains.
- :func:`registration_against_chance`: the score of a registration, the best score of
  :data:`NULL_SURROGATES` surrogates registered the same way, and whether it beats them.

References
----------
.. [1] J. Theiler, S. Eubank, A. Longtin, B. Galdrikian, J. D. Farmer, "Testing for
       nonlinearity in time series: the method of surrogate data," Physica D 58, 77-94
       (1992). :DOI:`10.1016/0167-2789(92)90102-S`
"""

from __future__ import annotations

from collections.abc import Sequence
import time
from typing import Any

import numpy as np

from ..core.errors import InputError
from ._filters import pixel_xy, remove_form, valid_mask
from ._registration import (RIGID_KEYS, MovedSurface, _icp_solve, _icp_template,
                            register_lsq)

__all__ = ["NULL_SURROGATES", "NULL_POINTS", "phase_surrogate", "explained_share",
           "unreliable_registration_warning",
           "registration_against_chance"]

#: surrogates each registration is set against: the best of 19 is the 95 % level of a
#: map of the same spectrum unrelated to the design (a chance of 1 in 20 of beating it)
NULL_SURROGATES = 19
#: each surrogate is registered on a seeded subset of at most this many of its points
NULL_POINTS = 2000


def phase_surrogate(a: np.ndarray, rng: np.random.Generator,
                    amplitude: np.ndarray | None = None) -> np.ndarray:
    """A surrogate of ``a`` (a profile or a map without missing points) with the same
    amplitude spectrum and random phases: the same roughness, waviness and periods, none
    of their structure (where the features lie, their shape).

    The mean is kept.  The phases are drawn uniformly on [0, 2 pi) for the half spectrum
    of the real transform (``numpy.fft.rfftn``) and made consistent with a real result
    where the half spectrum holds a frequency and its opposite (the columns of zero and,
    on an even width, of the Nyquist frequency along x): opposite phases at opposite
    frequencies, zero at a frequency that is its own opposite.  ``amplitude``: ``|rfftn(a -
    mean)|`` when it is already known (many surrogates of one map)."""
    a = np.asarray(a, dtype=np.float64)
    mean = float(a.mean())
    amp = np.abs(np.fft.rfftn(a - mean)) if amplitude is None else amplitude
    ph = rng.uniform(0, 2 * np.pi, amp.shape)
    if a.ndim == 1:
        ph[0] = 0.0
        if a.size % 2 == 0:
            ph[-1] = 0.0
    elif a.ndim == 2:
        ny = a.shape[0]
        i = np.arange(ny)
        mirror = (-i) % ny  # the row of the opposite frequency
        for c in [0] + ([a.shape[1] // 2] if a.shape[1] % 2 == 0 else []):
            own = ph[:, c].copy()
            ph[:, c] = np.where(i < mirror, own, -own[mirror])
            ph[i == mirror, c] = 0.0
    else:
        raise InputError(f"phase_surrogate takes a profile or a map, got {a.ndim} dimensions")
    return mean + np.fft.irfftn(amp * np.exp(1j * ph), s=a.shape)


def explained_share(x: np.ndarray, y: np.ndarray, z: np.ndarray,
                    design_heights: np.ndarray) -> float:
    """The share of the variance of the heights ``z`` at the points (``x``, ``y``) (mm)
    that ``design_heights`` there explain: ``1 - SS(res) / SS(z)``, a least-squares plane
    removed from ``z`` and from the residual ``res = z - design_heights`` (over the points
    where both are finite).  1 is a perfect match, 0 no better than a plane, a negative
    share a design that makes it worse."""
    x, y, h, d = (np.asarray(v, dtype=np.float64).ravel() for v in (x, y, z, design_heights))
    ok = np.isfinite(h) & np.isfinite(d)
    if ok.sum() < 4:
        return float("nan")
    a = np.column_stack([np.ones(int(ok.sum())), x[ok] - x[ok].mean(), y[ok] - y[ok].mean()])

    def ss(v):
        c, *_ = np.linalg.lstsq(a, v, rcond=None)
        return float(np.sum((v - a @ c) ** 2))

    total = ss(h[ok])
    if total <= 0:
        return float("nan")
    return 1.0 - ss(h[ok] - d[ok]) / total


def _score(pts, design, reg):
    moved = MovedSurface(design, reg)
    return explained_share(pts[0], pts[1], pts[2], moved.height(pts[0], pts[1]))


def registration_against_chance(z: np.ndarray, design: Any, registration: dict, *,
                                pixel: float | tuple[float, float],
                                origin: Sequence[float] = (0.0, 0.0),
                                mask: np.ndarray | None = None,
                                oversample: int = 10, seed: int = 0,
                                n: int = NULL_SURROGATES,
                                max_points: int = NULL_POINTS) -> dict:
    """Does the registration of ``z`` to ``design`` find more than a map of the same
    spectrum unrelated to the design would?

    The score (:func:`explained_share`) is the share of the measured map's variance (a
    plane removed) that the registered design explains.  The null: ``n`` surrogates of
    the measured map (its plane, plus :func:`phase_surrogate` of the rest; missing and
    masked points kept missing), each registered the same way as ``registration`` was
    (its ``method``, its ``fitted`` parameters, from the file's place) on a seeded subset
    of at most ``max_points`` of its points, and scored on them.  The registration is
    ``reliable`` when its score (on the same number of points of the map, drawn with the
    same seed) beats the best of them: with 19 surrogates, a map unrelated to the design
    does so by chance once in 20.

    Parameters
    ----------
    z : (ny, nx) array
        Measured heights, mm (NaN = missing).
    design : Surface
        The design (``height``, ``gradient``).
    registration : dict
        The map's :func:`register_lsq` / :func:`register_icp` result.
    pixel, origin
        mm.
    mask : bool array, optional
        The points the registration used (outliers left out).
    oversample : int
        ICP's template density (as the map's registration).
    seed : int
        Seed of the surrogates and of the point subsets (recorded in the result).

    Returns
    -------
    dict
        ``score``, ``null_score`` (the best surrogate's), ``null_scores``, ``reliable``,
        ``surrogates``, ``points``, ``seed``, ``search`` (how the surrogates were
        registered), ``rule``, ``seconds``.
    """
    t0 = time.perf_counter()
    if n < 1:
        raise InputError(f"n (surrogates) must be at least 1, got {n}")
    z = np.asarray(z, dtype=np.float64)
    ok = valid_mask(z, mask)
    if ok.sum() < 16:
        raise InputError(f"the check against chance needs at least 16 valid points, got "
                         f"{int(ok.sum())}")
    px, py = pixel_xy(pixel)
    ny, nx = z.shape
    xx, yy = np.meshgrid(origin[0] + px * np.arange(nx), origin[1] + py * np.arange(ny))
    res, form = remove_form(z, pixel=(px, py), method="plane", mask=ok)
    filled = np.where(ok, res, 0.0)
    amp = np.abs(np.fft.rfftn(filled - filled.mean()))
    rng = np.random.default_rng(seed)
    k = min(int(max_points), int(ok.sum()))
    where = np.flatnonzero(ok.ravel())

    def subset():
        return np.sort(rng.choice(where, k, replace=False))

    method = registration.get("method", "lsq")
    fit = list(registration.get("fitted") or [r.split("_")[0] for r in RIGID_KEYS])
    template = None
    if method == "icp":
        template = _icp_template(design, z.shape, pixel=(px, py), origin=origin,
                                 oversample=oversample)
    sel = subset()
    own = np.stack([xx.ravel()[sel], yy.ravel()[sel], z.ravel()[sel]])
    score = _score(own, design, registration)
    null = []
    for _ in range(n):
        sur = phase_surrogate(filled, rng, amp) + form
        sel = subset()
        pts = np.stack([xx.ravel()[sel], yy.ravel()[sel], sur.ravel()[sel]])
        if method == "icp":
            reg = _icp_solve(pts.T, template, fit=fit)
        else:
            grid = np.full(z.shape, np.nan)
            grid.ravel()[sel] = sur.ravel()[sel]
            reg = register_lsq(grid, design, pixel=(px, py), origin=origin, fit=fit,
                               max_points=k, seed=seed)
        null.append(_score(pts, design, reg))
    finite = [s for s in null if np.isfinite(s)]
    best = max(finite) if finite else None
    reliable = bool(np.isfinite(score) and (best is None or score > best))
    return {"score": float(score), "null_score": best, "null_scores": [float(s) for s in null],
            "reliable": reliable, "surrogates": int(n), "points": k, "seed": int(seed),
            "search": f"{method} from the file's place, fitting {', '.join(fit)}, on {k} "
                      f"points of each surrogate",
            "rule": f"reliable when the share of the measured map's variance (a plane removed) "
                    f"that the registered design explains beats the best of {n} "
                    f"phase-randomised surrogates of the map registered the same way (the "
                    f"95 % level of a map of the same spectrum unrelated to the design)",
            "seconds": time.perf_counter() - t0}


def unreliable_registration_warning(chance: dict) -> str | None:
    """The one-line warning of a registration no better than chance
    (:func:`registration_against_chance`); None when it is reliable."""
    if chance.get("reliable", True):
        return None
    best = chance.get("null_score")
    best_text = "n/a" if best is None else f"{best:.3g}"
    return (f"the registration is not reliable: the registered design explains "
            f"{chance['score']:.3g} of the measured map's variance (a plane removed), no more "
            f"than the {best_text} the same search reaches on the best of "
            f"{chance['surrogates']} maps of the same spectrum unrelated to the design "
            f"(phase-randomised surrogates, seed {chance['seed']}): the file may be a map of "
            f"another surface, and its differences from the design and the simulation are "
            f"not reliable")
