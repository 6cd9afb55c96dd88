"""A random part's amplitude fitted on a profile: its power in the profile's spectrum
(:func:`render_inspect.fit.set_profile_psd`), measured on realisations of the part alone at
its start value; a part the profile does not see is refused, and an amplitude the profile
does not tell from 0 is given as an upper limit."""

from __future__ import annotations

import numpy as np

from ..core.errors import InputError
from ..core.progress import task
from ..fit import amplitude_scan, set_profile_psd
from ._fit_model import FLOOR_DRAWS
from ._fit_profile_model import compute_profiles

__all__ = ["SEEN_SHARE"]


#: a fitted random part whose realisations at the start value hold less than this share of
#: the expected power in every band of the profile's spectrum is not seen by the profile
SEEN_SHARE = 0.02


def _check_free_random(free_random, random) -> None:
    """A random part's amplitude is fitted through the power it adds to the profile's
    spectrum, scaled from its start value: a start of 0 is refused."""
    for k in free_random:
        if k not in random:
            raise InputError(f"--free {k}: the amplitude of a random part is fitted through the "
                             f"power it adds to the profile's spectrum, scaled from its start "
                             f"value, which is 0 here; start it above 0 with --set {k}=VALUE")


def _random_part_power(model, params, start_values, target, clean0, noisy, store, client,
                       compute):
    """The ``psd`` term of the fitted random parts (:mod:`render_inspect.fit._profile_psd`):
    six realisations of each part alone at its start value give the power it adds to the
    profile's bands; refused, naming the key, when a part adds almost none (the profile
    does not see it).  Returns (full realisations: ``noisy`` with each fitted part's
    realisation added, for the terms' scales and the random parts' standard error; what
    ``fit.json`` records of the bands)."""
    free_random = model.free_random
    with task(f"fit: the power of the fitted random parts ({FLOOR_DRAWS} realisations each)"):
        runs = [model.draw(start_values, r, only=k) for k in free_random
                for r in range(FLOOR_DRAWS)]
        alone = compute_profiles(store, runs, client, compute)
    index = {p.key: i for i, p in enumerate(params)}
    scaled = [(index[k], start_values[k], alone[j * FLOOR_DRAWS:(j + 1) * FLOOR_DRAWS])
              for j, k in enumerate(free_random)]
    info = set_profile_psd(target, clean0, noisy, scaled, draws=FLOOR_DRAWS)
    for k in free_random:
        share = info["seen"].get(index[k], 0.0)
        if share < SEEN_SHARE:
            raise InputError(
                f"--free {k}: this profile does not see that random part: its realisations "
                f"at {start_values[k]:g} add at most {100 * share:.2g} % of the power in any "
                f"band of the profile's spectrum (a part that moves the tool only along the "
                f"cut leaves a rotationally symmetric surface unchanged); hold it with "
                f"--set, or fit it on an areal map")
    if not info["bands"]:
        raise InputError(f"--free {free_random[0]}: no band of the profile's spectrum is left "
                         f"to the random parts (the marks' own power fills them all)")
    # full realisations: the fixed parts and the camera's noise (``noisy``) and each fitted
    # part at its start (independent of them: their effects add)
    c = np.asarray(clean0, dtype=np.float64)
    base = [np.asarray(z, dtype=np.float64) for z in noisy] or [c] * FLOOR_DRAWS
    full = []
    for r, z in enumerate(base):
        z = z.copy()
        for j in range(len(free_random)):
            z = z + (np.asarray(alone[j * FLOOR_DRAWS + r], dtype=np.float64) - c)
        full.append(z)
    info["seen"] = {params[i].key: v for i, v in info["seen"].items()}
    return full, info


def _random_part_verdicts(record: dict, free_random, target=None, best=None) -> None:
    """A fitted random amplitude the profile does not tell from 0 (the ``psd`` term's
    chi-square at 0 less than 4 above its least, or the value within two standard errors
    of 0) is not determined by the profile (below the noise floor of its bands): it is
    given as an upper limit (where that chi-square has risen by 4), without a standard
    error."""
    keys = list(record["parameters"])
    for k in free_random:
        p = record["parameters"].get(k)
        if p is None:
            continue
        se = p.get("stderr")
        scan = None
        if target is not None and best is not None and best.psd is not None:
            values = [record["parameters"][q]["value"] for q in keys]
            scan = amplitude_scan(best, target, values, keys.index(k))
            p["psd_scan"] = scan
        at_zero = scan is not None and scan["chi2_at_zero_rise"] < 4.0
        if se is not None and p["value"] - 2 * se > 0 and not at_zero:
            # determined: its power stands clear of 0, however wide its relative error (a
            # random amplitude is read from a few periods' worth of values)
            ident = record.get("identifiability") or {}
            for d in ident.get("directions", []):
                if set(d.get("weights", {})) == {k} and not d["determined"]:
                    d["determined"] = True
                    d["why"] = "a random part's amplitude, clear of 0 in the profile's spectrum"
            if ident.get("undetermined"):
                ident["undetermined"] = [d for d in ident["undetermined"]
                                         if set(d.get("weights", {})) != {k}]
            continue
        limit = scan["upper_2se"] if scan is not None else (
            None if se is None else p["value"] + 2 * se)
        p["upper_limit_2se"] = limit
        p["stderr_hidden"] = se
        p["stderr"] = None
        p["relative_stderr"] = None
        p["confident"] = False
        p["not_determined"] = (
            "not determined by this profile: its power stays within the noise of the "
            "spectrum's bands (the camera's noise and the other random parts)"
            + ("" if limit is None else f"; at most {limit:.3g} (where the spectrum's "
                                        f"misfit has risen by 4, two standard errors)"))
