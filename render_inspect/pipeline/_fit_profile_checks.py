"""The checks of a profile fit (``fit`` on a measured profile,
:func:`~render_inspect.pipeline._fit_profile.run_fit_profile`): before it, whether the scene
can describe the window at all (:func:`_check_before`: its marks, their period within the
free keys' reach, a virtual instrument that follows the simulated cut); after it, whether
the fitted scene describes the window's marks (:func:`_check_after`)."""

from __future__ import annotations

from typing import cast

import numpy as np

from ..core.errors import InputError
from ..core.units import MM_TO_UM
from ..fit import MARK_KEYS, PERIOD_TOLERANCE, make_profile_target, within_reach
from ._fit_profile_model import MIN_POINTS, after_verdict, simulated_cut


def _cut_period(model, values, target, lag, n, spacing, spec):
    """The marks' period (mm) of the scene's simulated cut itself over the window (no
    instrument; the measured profile's estimator), or None."""
    z = simulated_cut(model.task(values))[lag:lag + n]
    if np.count_nonzero(np.isfinite(z)) < MIN_POINTS:
        return None
    z = np.where(np.isfinite(z), z, np.nanmean(z))
    t = make_profile_target(z, spacing=spacing, lag=0, spec=spec)
    return None if not t.peak else 1.0 / t.peak


def _instrument_check(mp, pp, cut_period, mode) -> None:
    """Refuse a virtual measurement that does not follow the cut it measured: the scene's
    predicted period ``pp`` (through the instrument) against its simulated cut's
    (``cut_period()``), where ``pp`` is off the measured ``mp``."""
    cp = cut_period() if cut_period is not None else None
    if cp is None or abs(pp / cp - 1.0) <= PERIOD_TOLERANCE:
        return
    psi = mode == "psi"
    lost = " (phase shifting loses the fringe orders on its slopes)" if psi else ""
    fix = ("measure as the part was measured, e.g. a white-light instrument: --set "
           "'render.interferometer.mode=\"csi\"'" if psi else
           "check the instrument's [render.interferometer] settings (objective, pixel, "
           "field of view) against the instrument that measured the part")
    raise InputError(
        f"render.interferometer.mode: the virtual instrument ({mode!r}) does not follow the "
        f"scene's own cut{lost}: it measures the marks' period as {pp * MM_TO_UM:.4g} um where "
        f"the simulated cut's is {cp * MM_TO_UM:.4g} um ({100 * (pp / cp - 1):+.3g} %; the "
        f"measured {mp * MM_TO_UM:.4g} um); {fix}")


def _check_before(target, pred, keys, reach, family, *, cut_period=None,
                  mode: str = "") -> dict:
    """Refuse a window the scene cannot describe (marks in one and not the other, a period
    out of the free keys' reach or, with no key that sets it free, more than 3 % off).
    Where the scene's period is off, its virtual measurement is checked first against the
    simulated cut it measured (``cut_period``: a callable giving the cut's period, mm):
    an instrument mode that cannot follow the cut is named as the cause."""
    mp = None if not target.peak else 1.0 / target.peak
    pp = None if not pred.centroid else 1.0 / pred.centroid
    out = {"measured_period_um": None if mp is None else mp * MM_TO_UM,
           "scene_period_um": None if pp is None else pp * MM_TO_UM,
           "family": family}
    if (mp is None) != (pp is None):
        which = ("the measured profile has feed marks but the scene predicts none"
                 if pp is None else "the scene predicts feed marks but the measured profile "
                                    "has none")
        raise InputError(f"this scene does not describe this measurement: {which} (a "
                         f"different process, the wrong file or window)")
    if mp is not None:
        rel = pp / mp - 1.0
        out["period_difference"] = rel
        if reach is not None and not within_reach(mp, reach):
            raise InputError(f"this scene does not describe this measurement: the marks' period "
                             f"{mp * MM_TO_UM:.4g} um lies outside the {reach[0] * MM_TO_UM:.4g}.."
                             f"{reach[1] * MM_TO_UM:.4g} um the free keys' bounds can reach; "
                             f"widen --bounds or check the scene's spindle speed")
        if (reach is None and not any(k in MARK_KEYS for k in keys)
                and abs(rel) > PERIOD_TOLERANCE and family["one_family"]):
            _instrument_check(mp, pp, cut_period, mode)
            raise InputError(f"this scene does not describe this measurement: the marks' period "
                             f"in the window is {mp * MM_TO_UM:.4g} um, the scene's "
                             f"{cast(float, pp) * MM_TO_UM:.4g} um ({100 * rel:+.3g} %), "
                             f"and no key that sets it is free (a program's path fixes it); "
                             f"check the window's place (--at, --line) and the program")
    return out


def _check_after(target, best, family, goodness) -> dict:
    findings = []
    if not family["one_family"]:
        findings.append(family["reason"])
    elif target.peak and best.centroid:
        rel = best.centroid / target.peak - 1.0
        sf = target.sigma_frequency or target.spec.sigma_frequency
        if abs(rel) > max(5 * sf, 0.01):
            findings.append(f"the fitted marks' period differs from the measured one by "
                            f"{100 * rel:+.3g} % (no values of the free keys give the "
                            f"measured period and the marks' shape together)")
    return after_verdict(findings, goodness, "the model describes the marks of this window")
