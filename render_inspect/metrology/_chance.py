"""Is a registration better than chance?  A measured map is registered to a design by a
search (least squares or ICP from the file's place); a map of another surface of like
relief is registered too, and its residual can be as small as a real part's form error.
What tells them apart is the registration's score set against what the same search
reaches on surrogates of the measured map that keep its spectrum but not its structure.

- :func:`phase_surrogate`: a phase-randomised surrogate of a profile or a map (the same
  amplitude spectrum, random phases; Theiler et al. 1992 [1]_).
- :func:`plane_free_surrogates`: surrogates of a map with its plane removed: the same
  amplitude spectrum, random phases and no plane (Schreiber & Schmitz 1996 [2]_).
- :func:`explained_share`: the score: the share of the measured map's variance (a plane
  removed) that the registered design explains.
- :func:`registration_against_chance`: the score of a registration, the best score of
  :data:`NULL_SURROGATES` surrogates registered the same way, and whether it beats them.

References
----------
.. [1] J. Theiler, S. Eubank, A. Longtin, B. Galdrikian, J. D. Farmer, "Testing for
       nonlinearity in time series: the method of surrogate data," Physica D 58, 77-94
       (1992). :DOI:`10.1016/0167-2789(92)90102-S`
.. [2] T. Schreiber, A. Schmitz, "Improved surrogate data for nonlinearity tests,"
       Phys. Rev. Lett. 77, 635-638 (1996). :DOI:`10.1103/PhysRevLett.77.635`
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
import math
import time
from typing import Any

import numpy as np

from ..core.errors import InputError
from ._filters import pixel_xy, remove_form, valid_mask
from ._registration import (RIGID_KEYS, MovedSurface, _icp_solve, _icp_template,
                            register_lsq)

__all__ = ["NULL_SURROGATES", "NULL_POINTS", "NULL_GRID", "SURROGATE_TOLERANCE",
           "SURROGATE_ITERATIONS", "phase_surrogate", "plane_free_surrogates", "explained_share",
           "unreliable_registration_warning",
           "registration_against_chance"]

#: surrogates each registration is set against: the best of 19 is the 95 % level of a
#: map of the same spectrum unrelated to the design (a chance of 1 in 20 of beating it)
NULL_SURROGATES = 19
#: the map and each surrogate are registered on a seeded subset of at most this many points
NULL_POINTS = 2000
#: a map of more pixels is set against chance on every stride-th pixel (at most this many)
NULL_GRID = 90_000
#: a surrogate's amplitude spectrum is matched to the map's to this relative rms error ...
SURROGATE_TOLERANCE = 1e-3  # not a unit conversion
#: ... in at most this many iterations (:func:`plane_free_surrogates`)
SURROGATE_ITERATIONS = 20


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


def plane_free_surrogates(residual: np.ndarray, ok: np.ndarray, rng: np.random.Generator,
                          n: int, *, tol: float = SURROGATE_TOLERANCE,
                          max_iter: int = SURROGATE_ITERATIONS
                          ) -> Iterator[tuple[np.ndarray, int]]:
    """``n`` surrogates of a map's ``residual`` (a least-squares plane already removed over
    the points ``ok``; the others count as zero, as they do in its Fourier transform) with
    the same amplitude spectrum, random phases, no plane over ``ok``, zero elsewhere and
    the same variance: yields each surrogate and the number of iterations it took.

    A phase-randomised field (:func:`phase_surrogate`) has a plane of its own, at random,
    which the score removes: it is left with less variance than the residual, and with
    less of it at the longest wavelengths, where a design's features often lie.  The plane
    is removed (and the points outside ``ok`` set to zero) and the amplitude spectrum put
    back, in turn, until the spectrum is within ``tol`` (relative, rms over the spectrum)
    of the residual's, at most ``max_iter`` times (the alternating constraints of
    Schreiber & Schmitz 1996 [2]_, with "no plane over the map's points" in place of their
    value distribution); the surrogate is then scaled to the residual's variance (around
    large holes the spectrum converges slowly, to within a few %, a little short of it)."""
    r = np.where(ok, residual, 0.0)
    amp = np.abs(np.fft.rfftn(r - r.mean()))
    norm = float(np.linalg.norm(amp)) or 1.0
    total = float(np.sum(r[ok] ** 2))
    ny, nx = r.shape
    u, v = np.arange(nx) - 0.5 * (nx - 1), np.arange(ny) - 0.5 * (ny - 1)
    vv, uu = np.meshgrid(v, u, indexing="ij")
    fit = np.linalg.pinv(np.column_stack([np.ones(int(ok.sum())), uu[ok], vv[ok]]))

    def without_plane(f):  # like the residual: no plane over ``ok``, zero elsewhere
        c = fit @ f[ok]
        return np.where(ok, f - (c[0] + c[1] * u[None, :] + c[2] * v[:, None]), 0.0)

    for _ in range(n):
        s = phase_surrogate(r, rng, amp)
        it = 0
        for it in range(1, max_iter + 1):
            s = without_plane(s)
            spec = np.fft.rfftn(s)
            mag = np.abs(spec)
            if np.linalg.norm(mag - amp) <= tol * norm:
                break
            s = np.fft.irfftn(spec * np.divide(amp, mag, out=np.zeros_like(amp), where=mag > 0),
                              s=s.shape)
        else:
            s = without_plane(s)
        yield s * math.sqrt(total / max(float(np.sum(s[ok] ** 2)), 1e-300)), it


def registration_against_chance(z: np.ndarray, design: Any, registration: dict, *,
                                pixel: float | tuple[float, float],
                                origin: Sequence[float] = (0.0, 0.0),
                                mask: np.ndarray | None = None,
                                oversample: int = 10, seed: int = 0,
                                n: int = NULL_SURROGATES,
                                max_points: int = NULL_POINTS,
                                max_grid: int = NULL_GRID) -> dict:
    """Does the registration of ``z`` to ``design`` find more than a map of the same
    spectrum unrelated to the design would?

    The score (:func:`explained_share`) is the share of the measured map's variance (a
    plane removed) that the registered design explains.  The map and each of ``n``
    surrogates go through one search: registered the way ``registration`` was (its
    ``method``, its ``fitted`` parameters, from the file's place) on a seeded subset of
    at most ``max_points`` of their points, and scored on them.  The surrogates: the
    map's plane plus a :func:`plane_free_surrogates` of the rest (the same amplitude
    spectrum, random phases, no plane); missing and masked points kept missing.  The
    registration is ``reliable`` when the map's score beats every surrogate's: with 19
    surrogates, a map unrelated to the design does so by chance once in 20.

    Parameters
    ----------
    z : (ny, nx) array
        Measured heights, mm (NaN = missing).
    design : Surface
        The design (``height``, ``gradient``).
    registration : dict
        The map's :func:`register_lsq` / :func:`register_icp` result (its ``method`` and
        ``fitted`` parameters).
    pixel, origin
        mm.
    mask : bool array, optional
        The points the registration used (outliers left out).
    oversample : int
        ICP's template density (as the map's registration).
    seed : int
        Seed of the surrogates and of the point subsets (recorded in the result).
    n, max_points
        The surrogates; the points each search uses.
    max_grid : int
        A map of more pixels is set against chance (the map and its surrogates alike) on
        every ``stride``-th pixel along x and y, the smallest stride that leaves at most
        ``max_grid`` pixels: the search uses ``max_points`` of them anyway, and the
        surrogates' Fourier transforms stay cheap.

    Returns
    -------
    dict
        ``score``, ``null_score`` (the best surrogate's), ``null_scores``, ``reliable``,
        ``surrogates``, ``points``, ``stride``, ``surrogate_iterations`` (the most a
        surrogate took), ``seed``, ``search`` (how the map and the surrogates were
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
    # a large map is set against chance on every stride-th pixel (the map and the
    # surrogates alike): the surrogates' Fourier transforms stay cheap
    stride = max(1, math.ceil(math.sqrt(z.size / max_grid)))
    if stride > 1:
        z, ok, px, py = z[::stride, ::stride], ok[::stride, ::stride], px * stride, py * stride
        if ok.sum() < 16:
            raise InputError(f"the check against chance needs at least 16 valid points on "
                             f"every {stride}th pixel, got {int(ok.sum())}")
    ny, nx = z.shape
    xx, yy = np.meshgrid(origin[0] + px * np.arange(nx), origin[1] + py * np.arange(ny))
    res, form = remove_form(z, pixel=(px, py), method="plane", mask=ok)
    rng = np.random.default_rng(seed)
    k = min(int(max_points), int(ok.sum()))
    where = np.flatnonzero(ok.ravel())
    method = registration.get("method", "lsq")
    fit = list(registration.get("fitted") or [r.split("_")[0] for r in RIGID_KEYS])
    template = None
    if method == "icp":
        template = _icp_template(design, z.shape, pixel=(px, py), origin=origin,
                                 oversample=oversample)

    def searched(heights):
        """The score of ``heights`` registered from the file's place on a seeded subset."""
        sel = np.sort(rng.choice(where, k, replace=False))
        pts = np.stack([xx.ravel()[sel], yy.ravel()[sel], heights.ravel()[sel]])
        if method == "icp":
            reg = _icp_solve(pts.T, template, fit=fit)
        else:
            grid = np.full(z.shape, np.nan)
            grid.ravel()[sel] = pts[2]
            reg = register_lsq(grid, design, pixel=(px, py), origin=origin, fit=fit,
                               max_points=k, seed=seed)
        return _score(pts, design, reg)

    score = searched(z)
    null, iterations = [], []
    for sur, it in plane_free_surrogates(res, ok, rng, n):
        iterations.append(it)
        null.append(searched(sur + form))
    finite = [s for s in null if np.isfinite(s)]
    best = max(finite) if finite else None
    # a surrogate without a score (too few points) is not counted as beaten
    reliable = bool(np.isfinite(score) and len(finite) == n and score > best)
    return {"score": float(score), "null_score": best, "null_scores": [float(s) for s in null],
            "reliable": reliable, "surrogates": int(n), "points": k, "seed": int(seed),
            "surrogate_iterations": max(iterations),
            "stride": stride,
            "search": f"{method} from the file's place, fitting {', '.join(fit)}, on {k} "
                      f"points of the map and of each surrogate"
                      + (f" (of every {stride}th pixel)" if stride > 1 else ""),
            "rule": f"reliable when the share of the measured map's variance (a plane removed) "
                    f"that the registered design explains beats the best of {n} "
                    f"phase-randomised surrogates of the map (its amplitude spectrum, no "
                    f"plane) registered the same way (the 95 % level of a map of the same "
                    f"spectrum unrelated to the design)",
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
