"""``compare``'s difference of the two measurements: formed from the measurements alone
(piston and tilt removed, and piston only), checked for fringe-order failures, with its
noise floor from the measurements' own noise estimates, set beside the truth at the same
camera pixels, and, with ``repeat``, its repeatability over fresh camera noise."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..core.units import MM_TO_NM, NM_TO_MM
from ..instruments import height_instrument
from ..metrology import (difference_noise, difference_order_check, difference_stats, fringe_order_check,
                         level_map, measure_frames, measured_difference, measurement_seeds,
                         repeat_statistics, resolution)

if TYPE_CHECKING:
    from ..scene import Scene


def _instrument(scene: Scene):
    """The instrument compare measures through and its section of the scene."""
    entry = height_instrument()
    return entry, getattr(scene.render, entry.name)


def _fringe_order(frames) -> float | None:
    """``lambda_eff / 2`` (mm) of phase-shifting frames: the step a PSI height is known
    up to between regions that do not touch; None for coherence scanning."""
    return frames.lambda_eff_nm * NM_TO_MM / 2 if frames.mode == "psi" else None


def _fringe_summary(check: dict) -> dict:
    """A fringe-order check's numbers (its masks left out)."""
    return {k: x for k, x in check.items() if k not in ("unknown_order", "mask")}


def _levelled_difference(ra, rb, *, pixel, fringe_order_mm, checks=()):
    """The measurements' difference (piston and tilt removed), checked for fringe-order
    failures; pixels of unknown order masked (NaN).  Returns (levelled mm, info, order)."""
    common = dict(pixel=pixel, labels_a=ra.labels, labels_b=rb.labels,
                  fringe_order_mm=fringe_order_mm)
    ha = np.where(ra.valid, ra.height, np.nan)
    hb = np.where(rb.valid, rb.height, np.nan)
    tilt, info = measured_difference(ha, hb, terms="piston and tilt", **common)
    order = difference_order_check(tilt, fringe_order_mm=fringe_order_mm, checks=checks)
    if order["status"] == "masked":  # level again without the pixels of unknown order
        keep = order["mask"]
        tilt, info = measured_difference(np.where(keep, ha, np.nan), np.where(keep, hb, np.nan),
                                         terms="piston and tilt", **common)
    return tilt, info, order


def _window_difference(a, b) -> dict:
    """The two measurements' difference over the common window, formed from the
    measurements alone (:func:`~render_inspect.metrology.measured_difference`: piston
    and tilt removed, and piston only), checked for fringe-order failures (pixels of
    unknown order masked; a failed difference flagged), with its noise floor from the two
    measurements' own noise estimates; and the truth at the same camera pixels with the
    same terms removed."""
    ig = a.ig
    ra, rb = a.reported, b.reported
    fo = _fringe_order(ig)
    tilt, info, order = _levelled_difference(ra, rb, pixel=ig.pixel, fringe_order_mm=fo,
                                             checks=(a.fringe, b.fringe))
    keep = np.isfinite(tilt)
    common = dict(pixel=ig.pixel, labels_a=ra.labels, labels_b=rb.labels, fringe_order_mm=fo)
    piston, pinfo = measured_difference(np.where(keep, ra.height, np.nan),
                                        np.where(keep, rb.height, np.nan), terms="piston",
                                        **common)
    true_cam = np.where(keep, a.ig.height_true - b.ig.height_true, np.nan)
    true_lev, tinfo = level_map(true_cam, pixel=ig.pixel, terms="piston and tilt")
    noise = difference_noise(ra.height_noise, rb.height_noise, valid=keep)
    noise["seeds"] = {a.name: int(a.noise_seed), b.name: int(b.noise_seed)}
    return {"levelled": tilt * MM_TO_NM, "piston_removed": piston * MM_TO_NM,
            "true_levelled": true_lev * MM_TO_NM, "info": info, "piston_info": pinfo,
            "true_info": tinfo, "order": order, "noise": noise}


def _repeat_differences(a, b, wdiff: dict, *, icfg, repeat: int, seed: int,
                        t) -> dict:
    """Measure both variants ``repeat - 1`` more times, each with fresh camera noise
    (:func:`~render_inspect.metrology.measurement_seeds`), and the repeatability of their
    difference (:func:`~render_inspect.metrology.repeat_statistics`)."""
    entry, _ = _instrument(a.scene)
    fo = _fringe_order(a.ig)
    mcfg = a.scene.metrology
    first = wdiff["levelled"]
    ok0 = np.isfinite(first)
    st0 = wdiff["order"]["status"]
    maps, seeds, status = [first], [[int(a.noise_seed), int(b.noise_seed)]], [st0]
    rms = [float(np.sqrt(np.mean(first[ok0] ** 2))) if ok0.any() and st0 != "failed" else None]
    for r in range(1, int(repeat)):
        sa, sb = measurement_seeds(seed, 2, repeat=r)
        res = []
        for v, s in ((a, sa), (b, sb)):
            t.update(f"repeat {r + 1}/{repeat}: {v.name}")
            ig = entry.render(v.heightmap, icfg, surface="machined", seed=s)
            rr = measure_frames(ig.recorded(), algorithm=mcfg.phase_algorithm,
                                csi_refine=mcfg.csi_refine, min_modulation=mcfg.min_modulation)
            res.append((rr, fringe_order_check(rr, fringe_order_mm=fo)))
        (ra, ca), (rb, cb) = res
        d, _, order = _levelled_difference(ra, rb, pixel=a.ig.pixel, fringe_order_mm=fo,
                                           checks=(ca, cb))
        d = d * MM_TO_NM
        ok = np.isfinite(d)
        maps.append(d)
        rms.append(float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() and order["status"] != "failed"
                   else None)
        seeds.append([int(sa), int(sb)])
        status.append(order["status"])
    stack = np.stack([np.where(np.isfinite(m), m, np.nan) for m in maps])
    failed = [i for i, st in enumerate(status) if st == "failed"]
    if failed:
        stack = np.delete(stack, failed, axis=0)
    out = repeat_statistics(stack, [x for i, x in enumerate(rms) if i not in failed])
    out.update(seeds=seeds, status=status, failed_repeats=len(failed),
               method="both variants measured again with fresh camera noise; the "
                      "difference formed each time as in the first (piston and tilt "
                      "removed); an MSA-style repeatability of the difference")
    return out


def _difference_numbers(a, b, diff, profile: dict, wdiff: dict) -> dict:
    ok = np.isfinite(diff)
    rc = a.metrics["residual"], b.metrics["residual"]
    fa, fb = a.metrics["filtered"].get("Sq_nm"), b.metrics["filtered"].get("Sq_nm")
    m = {"machined_rms_nm": float(np.sqrt(np.mean(diff[ok] ** 2))) if ok.any() else None,
         "machined_pv_nm": float(np.ptp(diff[ok])) if ok.any() else None,
         "min_nm_change": rc[0]["min_nm"] - rc[1]["min_nm"],
         "Sq_nm_change": rc[0]["Sq_nm"] - rc[1]["Sq_nm"],
         "filtered_Sq_nm_change": None if fa is None or fb is None else fa - fb,
         **profile["metrics"]}
    w = m["window"] = dict(m["window"])
    # ``true``: the simulation's machined maps (truth); ``measured``: the two measurements
    # alone, piston and tilt removed as instrument software does (said in ``measured``)
    w["true"] = {**w["true"], "source": "truth: the simulated machined maps, nothing removed"}
    order = wdiff["order"]
    meas = {**w["measured"], "form_removed": wdiff["info"]["removed"],
            "source": "the two measurements alone (height.exr of each variant)",
            "levelling": wdiff["info"], "status": order["status"],
            "fringe_order": _fringe_summary(order), "noise": wdiff["noise"]}
    if order["status"] == "failed":
        # a failed measurement is no measured difference: its numbers are kept apart
        meas["unreliable"] = {k: meas.pop(k) for k in ("rms_nm", "pv_nm", "mean_nm")}
        meas.update(rms_nm=None, pv_nm=None, mean_nm=None)
        meas["resolution"] = resolution(None, None)
        meas["resolution"]["verdict"] = "failed"
    else:
        meas["resolution"] = resolution(meas.get("rms_nm"), wdiff["noise"]["floor_nm"])
    w["measured"] = meas
    pist = {**difference_stats(wdiff["piston_removed"]), "form_removed": "piston",
            "levelling": wdiff["piston_info"], "status": order["status"]}
    if order["status"] == "failed":
        pist["unreliable"] = {k: pist.pop(k) for k in ("rms_nm", "pv_nm", "mean_nm")}
        pist.update(rms_nm=None, pv_nm=None, mean_nm=None)
    w["measured_piston_removed"] = pist
    w["true_same_form_removed"] = {**difference_stats(wdiff["true_levelled"]),
                                   "form_removed": wdiff["true_info"]["removed"],
                                   "source": "truth at the camera pixels both measured"}
    return m
