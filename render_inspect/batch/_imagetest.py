"""Image regression statistics: deterministic images against a reference with per-pixel
tolerances; Monte-Carlo images against a reference mean and variance with a per-pixel
two-sample t-test and a Sidak correction for the number of pixels (the scheme of
Mitsuba 3's own render tests).

Monte-Carlo images are rendered as independent passes (different seeds): the reference
keeps, per pixel and channel, the mean and the sample variance (``ddof = 1``) of ``M``
passes and the number of passes that gave a finite value; a test renders ``K`` passes
with the same samples per pixel.  Under the hypothesis that both come from the same
renderer and scene, a pass's value has one distribution on both sides, and

    t = (mean_test - mean_ref) / sqrt(s2 (1 / K + 1 / M)),
    s2 = ((K - 1) var_test + (M - 1) var_ref) / (K + M - 2)

follows Student's t with ``K + M - 2`` degrees of freedom (``variance="pooled"``, the
default).  ``variance="welch"`` uses ``var_test / K + var_ref / M`` and the
Welch-Satterthwaite degrees of freedom instead; it is the test to use when the two sides
were rendered with different sample counts, but with few test passes its variance
estimate is unreliable for pixels whose passes cluster (a pixel on a silhouette or a
light's edge sees it in some passes and not in others) and it then raises false alarms.
Pixels whose passes are sometimes finite and sometimes not (a measurement that drops
out) are tested with Fisher's exact test on the counts.  With ``N`` tests in an image,
each is held to ``1 - (1 - alpha) ** (1 / N)`` (Sidak), so an image of unchanged code
fails with probability at most ``alpha`` whatever ``N`` is (for independent pixels;
box-filtered Monte-Carlo pixels are independent).
"""

from __future__ import annotations

import numpy as np

from ..core.errors import InputError

__all__ = ["compare_deterministic", "image_t_test", "pass_statistics", "sidak_threshold",
           "flip_mean"]

#: References are stored as float32: their means carry a rounding error of up to this
#: fraction, which is added to the standard error (so that a pixel that does not vary
#: between passes is compared to float32 precision rather than exactly).
FLOAT32_EPS = float(np.finfo(np.float32).eps)
#: The smallest variance a float32 reference holds: a smaller one (a pass that met the
#: light with a weight of 1e-24) is stored as 0, so this much variance is added too (a
#: mean of 1e-26 against a test of exactly 0 is no difference).
FLOAT32_TINY = float(np.finfo(np.float32).smallest_subnormal)


def sidak_threshold(alpha: float, n_tests: int) -> float:
    """Per-test significance giving family-wise false-alarm probability ``alpha`` over
    ``n_tests`` independent tests: ``1 - (1 - alpha) ** (1 / n_tests)``."""
    if n_tests <= 0:
        return alpha
    return float(-np.expm1(np.log1p(-alpha) / n_tests))


def compare_deterministic(test: np.ndarray, ref: np.ndarray, *, atol: float,
                          rtol: float = 0.0) -> dict:
    """Per-pixel comparison of a deterministic image with its reference.

    A pixel passes when both are NaN, or both are finite and
    ``|test - ref| <= atol + rtol * |ref|``.

    Parameters
    ----------
    test, ref : ndarray, same shape (any number of dimensions), in the image's unit
    atol : float
        Absolute tolerance, the image's unit.
    rtol : float

    Returns
    -------
    dict
        ``passed``, ``n_values``, ``n_fail``, ``nan_mismatch`` (values NaN on one side
        only), ``max_abs_diff``, ``atol``, ``rtol``, and ``diff`` (test - ref, NaN where
        either is NaN) and ``fail_mask``.
    """
    t = np.asarray(test, dtype=np.float64)
    r = np.asarray(ref, dtype=np.float64)
    if t.shape != r.shape:
        return {"passed": False, "reason": f"shape {list(t.shape)} differs from the reference's "
                                           f"{list(r.shape)}", "n_values": int(r.size),
                "n_fail": int(r.size), "nan_mismatch": 0, "max_abs_diff": None,
                "atol": atol, "rtol": rtol, "diff": None, "fail_mask": None}
    nt, nr = np.isnan(t), np.isnan(r)
    mism = nt != nr
    both = ~nt & ~nr
    diff = np.where(both, t - r, np.nan)
    bad = mism | (both & (np.abs(np.nan_to_num(diff)) > atol + rtol * np.abs(np.nan_to_num(r))))
    mx = float(np.nanmax(np.abs(diff))) if both.any() else 0.0
    return {"passed": not bool(bad.any()), "n_values": int(r.size), "n_fail": int(bad.sum()),
            "nan_mismatch": int(mism.sum()), "max_abs_diff": mx, "atol": float(atol),
            "rtol": float(rtol), "diff": diff, "fail_mask": bad}


def pass_statistics(passes: np.ndarray) -> dict:
    """Mean, sample variance (``ddof = 1``) and count of the finite values of
    ``passes`` (shape ``(P, ...)``) along the first axis; mean and variance are NaN
    where fewer than 1 / 2 passes are finite."""
    p = np.asarray(passes, dtype=np.float64)
    fin = np.isfinite(p)
    n = fin.sum(axis=0)
    s1 = np.where(fin, p, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, s1 / np.maximum(n, 1), np.nan)
        dev = np.where(fin, p - mean, 0.0)
        var = np.where(n > 1, (dev * dev).sum(axis=0) / np.maximum(n - 1, 1), np.nan)
    return {"mean": mean, "var": var, "n": n.astype(np.int32)}


def _fisher_p(a: int, b: int, c: int, d: int) -> float:
    from scipy.stats import fisher_exact

    return float(fisher_exact([[a, b], [c, d]]).pvalue)


def image_t_test(test: dict, ref: dict, *, n_test: int, n_ref: int,
                     alpha: float = 1e-3, variance: str = "pooled") -> dict:
    """Per-pixel two-sample t-test of a Monte-Carlo image against its reference.

    Parameters
    ----------
    test, ref : dict
        :func:`pass_statistics` of the test passes and of the reference passes
        (``mean``, ``var``, ``n``: arrays of one shape).
    n_test, n_ref : int
        Passes rendered (K, M): a value finite in fewer passes is tested on its counts.
    alpha : float
        Family-wise false-alarm probability of the image (Sidak over its tests).
    variance : {"pooled", "welch"}
        Student's test with the pooled variance (same samples per pass on both sides) or
        Welch's (see the module docstring).

    Returns
    -------
    dict
        ``passed``, ``alpha``, ``threshold`` (per test), ``n_tests``, ``n_reject``,
        ``min_p``, ``p`` (per-value p-values, 1 where not tested), ``diff`` (test mean -
        reference mean), ``reject`` (mask), ``dof_median``.
    """
    mt, vt, kt = (np.asarray(test[k], dtype=np.float64) for k in ("mean", "var", "n"))
    mr, vr, kr = (np.asarray(ref[k], dtype=np.float64) for k in ("mean", "var", "n"))
    if mt.shape != mr.shape:
        return {"passed": False, "reason": f"shape {list(mt.shape)} differs from the "
                                           f"reference's {list(mr.shape)}",
                "alpha": alpha, "threshold": None, "n_tests": 0, "n_reject": int(mr.size),
                "min_p": 0.0, "p": None, "diff": None, "reject": None, "dof_median": None}
    from scipy.stats import t as student_t

    if variance not in ("pooled", "welch"):
        raise InputError(f"variance must be 'pooled' or 'welch', got {variance!r}")
    p = np.ones(mt.shape)
    full = (kt == n_test) & (kr == n_ref)
    none = (kt == 0) & (kr == 0)
    mixed = ~full & ~none
    # values finite in every pass on both sides: the t-test
    vt0, vr0 = np.nan_to_num(vt), np.nan_to_num(vr)
    if variance == "pooled":
        s2 = ((n_test - 1) * vt0 + (n_ref - 1) * vr0) / (n_test + n_ref - 2)
        se2 = np.where(full, s2 * (1.0 / n_test + 1.0 / n_ref), 0.0)
    else:
        se2 = np.where(full, vt0 / n_test + vr0 / n_ref, 0.0)
    d = np.where(full, mt - mr, 0.0)
    with np.errstate(invalid="ignore"):
        scale = np.where(full, np.maximum(np.abs(mt), np.abs(mr)), 0.0)
    se2_mc = se2
    se2 = se2 + np.where(full, (FLOAT32_EPS * scale) ** 2 + FLOAT32_TINY / n_ref, 0.0)
    pos = full  # se2 > 0 there: the float32 floor
    with np.errstate(invalid="ignore", divide="ignore"):
        tt = np.where(pos, d / np.sqrt(np.where(pos, se2, 1.0)), 0.0)
        dof = np.full(mt.shape, float(n_test + n_ref - 2))
        if variance == "welch":
            a, b = vt0 / n_test, vr0 / n_ref
            den = a * a / max(n_test - 1, 1) + b * b / max(n_ref - 1, 1)
            dof = np.where(full & (den > 0), se2_mc * se2_mc / np.where(den > 0, den, 1.0), dof)
    p[pos] = 2.0 * student_t.sf(np.abs(tt[pos]), dof[pos])
    # finite in some passes only: Fisher's exact test on (finite, not finite) x (test, ref)
    if mixed.any():
        cache: dict = {}
        for idx in zip(*np.nonzero(mixed)):
            key = (int(kt[idx]), int(kr[idx]))
            if key not in cache:
                cache[key] = _fisher_p(key[0], n_test - key[0], key[1], n_ref - key[1])
            p[idx] = cache[key]
    tested = full | mixed
    n_tests = int(tested.sum())
    thr = sidak_threshold(alpha, n_tests)
    reject = tested & (p < thr)
    diff = np.where(np.isfinite(mt) & np.isfinite(mr), mt - mr, np.nan)
    return {"passed": not bool(reject.any()), "alpha": float(alpha), "threshold": thr,
            "variance": variance,
            "n_tests": n_tests, "n_reject": int(reject.sum()),
            "min_p": float(p[tested].min()) if n_tests else 1.0, "p": p, "diff": diff,
            "reject": reject, "dof_median": float(np.median(dof[pos])) if pos.any() else None}


def flip_mean(test_rgb: np.ndarray, ref_rgb: np.ndarray) -> float | None:
    """Mean FLIP (LDR, sRGB-encoded, 67 pixels per degree) between two linear RGB images,
    or None when flip-evaluator is not installed.  Reported beside the statistical test
    as a perceptual measure of the difference; the test decides."""
    try:
        import flip_evaluator
    except ImportError:
        return None

    def srgb(a):
        a = np.clip(np.nan_to_num(np.asarray(a, dtype=np.float64)), 0.0, 1.0)
        return np.where(a <= 0.0031308, 12.92 * a, 1.055 * np.power(a, 1 / 2.4) - 0.055)

    _, m, _ = flip_evaluator.evaluate(srgb(ref_rgb).astype(np.float32),
                                      srgb(test_rgb).astype(np.float32), "LDR",
                                      applyMagma=False)
    return float(m)
