"""Every shipped seed scene next to its paper's measured value, compared like with like.

The papers measured their parts with an instrument and removed the form before quoting a
roughness.  This script simulates each shipped scene (or the window of it named below)
and reports the residual machined - design three ways:

* ``raw``: mean removed (as ``metrics.json``'s ``residual``);
* ``poly2``: a second-order polynomial (the form) removed;
* ``instrument``: through the 20x interference objective's linear transfer function
  (NA 0.4, LED 600 nm / 120 nm, the illumination pupil filled or stopped down to
  ``--illumination-na``), the camera pixel's box (0.9 mm / 1024), then poly2 removed: what
  the coherence-correlation interferometer of Li et al. (2018) would report;
* the spread of ``instrument`` over the settings the paper does not give
  (:data:`UNSTATED_SETTINGS`: aperture, pixel, form, S-filter), its uncertainty, and
  whether the paper's band can discriminate at all (:func:`settings_spread`).

Usage::

    python tools/paper_comparison.py [--scene NAME ...] [--illumination-na 0.3] [--json OUT]
          [--set KEY=VALUE ...]

Prints a Markdown table.  ``tools/docs_numbers.py`` makes the numbers
docs/machine_and_material.md quotes from the same functions (``compare_sim``).
"""

from __future__ import annotations

import argparse
import functools
import json
import sys
import time

import numpy as np

from render_inspect.core.units import MM_TO_NM
from render_inspect.instruments import Microscope, led
from render_inspect.pipeline import simulate
from render_inspect.scene import load_scene

#: the 20x CCI 3000 field: 0.9 mm on 1024 camera pixels
CAMERA_PIXEL_MM = 0.9 / 1024
#: the paper's values (mean +- the stated uncertainty, nm) and the window compared
PAPERS = {
    "sts_sinusoidal_grid": {"metric": "Sq", "value": 7.1, "sd": 0.3,
                            "paper": "Li et al. (2018), sinusoidal grid, CCI 3000 20x",
                            "windows": {"scene (centre)": [],
                                        "off axis": ["simulation.region=[1.5, 1.5, 2.4, 2.4]"]}},
    "sts_mla_2x2": {"metric": "Sq", "value": 7.4, "sd": 0.34,
                    "paper": "Li et al. (2018), 2 x 2 MLA, CCI 3000 20x",
                    "windows": {"scene (lenslet rim)": []}},
    "sts_fig16_overcut": {"metric": None, "paper": "Li et al. (2018), Fig. 16: a simulation, "
                                                   "no measurement", "windows": {"scene": []}},
    "compound_sinusoid": {"metric": None, "paper": "Ra 89 nm (stylus, direction and cut-off "
                                                   "not given), PV 4.25 um (whole part)",
                          "windows": {"scene": []}},
    "hts_toric_msa": {"metric": None, "paper": "lenslet form error Sa 0.112-0.836 um; "
                                               "dislocations 13.5-144 um (Table 3)",
                      "windows": {"scene": []}},
    "rcse_circular_array": {"metric": None, "paper": "Sa 60.6 % lower than the conventional "
                                                     "path, spread 91.7 % lower",
                            "windows": {"scene": []}},
    "sculpt_quad_mla": {"metric": None, "paper": "single lenslet Sa 4 nm, Sz 0.13 um (HFUVAS); "
                                                 "edge form error E2 0.2 um",
                        "windows": {"scene": []}},
}


def _design_matrix(shape, degree, ok):
    """The columns x^i y^j (i + j <= ``degree``) at the points ``ok`` of a map of ``shape``."""
    ny, nx = shape
    y, x = np.mgrid[0:ny, 0:nx]
    x = (x - nx / 2) / nx
    y = (y - ny / 2) / ny
    cols = [x ** i * y ** j for i in range(degree + 1) for j in range(degree + 1 - i)]
    return np.stack([c[ok] for c in cols], 1)


@functools.lru_cache(maxsize=2)
def _full_design(shape, degree):
    """The design matrix of a map of ``shape`` without NaN: the spread over the instrument
    settings removes the form of one map size, at degrees 2 and 3, many times over (kept
    for two at a time: a 1000 x 1000 map's are 48-80 MB)."""
    return _design_matrix(shape, degree, np.ones(shape, bool))


def poly_remove(r, degree=2):
    """``r`` minus its least-squares polynomial of ``degree`` in x and y (NaN kept)."""
    ok = np.isfinite(r)
    a = _full_design(r.shape, degree) if ok.all() else _design_matrix(r.shape, degree, ok)
    coef, *_ = np.linalg.lstsq(a, r[ok], rcond=None)
    out = np.full_like(r, np.nan)
    out[ok] = r[ok] - a @ coef
    return out


#: Instrument settings a paper may not give, each with the values a 20x CCI could have
#: had (assumed plausible): the illumination aperture (filled, stopped down to NA 0.3),
#: the camera pixel (0.9 mm on 1024 or on 512 pixels, binned), the form removed
#: (second or third order) and an ISO 16610-61 S-filter (none, or 2.5 um).
UNSTATED_SETTINGS = {"illumination_na": (None, 0.3),
                     "camera_pixel_mm": (CAMERA_PIXEL_MM, 2 * CAMERA_PIXEL_MM),
                     "form_degree": (2, 3),
                     "s_filter_mm": (None, 0.0025)}
#: ISO 16610-61 Gaussian: transmission exp(-pi (alpha lambda f)^2), alpha = sqrt(ln 2 / pi)
_GAUSS_ALPHA = float(np.sqrt(np.log(2) / np.pi))


def instrument_filter(r, pixel, *, illumination_na=None, camera_pixel_mm=CAMERA_PIXEL_MM,
                      s_filter_mm=None):
    """``r`` (mm) through the 20x objective's linear ITF, the camera pixel's box and, when
    given, an ISO 16610-61 Gaussian S-filter of cut-off ``s_filter_mm``."""
    mic = Microscope(source=led(600.0, bandwidth_nm=120.0), illumination_na=illumination_na)
    rr = np.where(np.isfinite(r), r, np.nanmean(r))
    fy = np.fft.fftfreq(r.shape[0], pixel)
    fx = np.fft.fftfreq(r.shape[1], pixel)
    gx, gy = np.meshgrid(fx, fy)
    f = np.hypot(gx, gy)
    h = mic.itf(f) * np.sinc(gx * camera_pixel_mm) * np.sinc(gy * camera_pixel_mm)
    if s_filter_mm:
        h = h * np.exp(-np.pi * (_GAUSS_ALPHA * s_filter_mm * f) ** 2)
    return np.real(np.fft.ifft2(np.fft.fft2(rr) * h))


def sq_nm(a):
    a = a[np.isfinite(a)]
    a = a - a.mean()
    return float(np.sqrt(np.mean(a * a)) * MM_TO_NM)


def sa_nm(a):
    a = a[np.isfinite(a)]
    return float(np.mean(np.abs(a - a.mean())) * MM_TO_NM)


def compare_sim(sim, *, illumination_na=None) -> dict:
    """Sq and Sa of a simulation's residual raw, poly2 and through the instrument."""
    r = sim.heightmap.machined - sim.heightmap.design
    px = sim.scene.simulation.pixel
    p2 = poly_remove(r)
    it = poly_remove(instrument_filter(r, px, illumination_na=illumination_na))
    return {"raw_Sq_nm": sq_nm(r), "raw_Sa_nm": sa_nm(r), "poly2_Sq_nm": sq_nm(p2),
            "instrument_Sq_nm": sq_nm(it), "instrument_Sa_nm": sa_nm(it),
            "scallop_Sq_nm": sim.metrics.get("scallop", {}).get("Sq_nm")}


def settings_spread(sim, *, value=None, sd=None) -> dict:
    """The instrument Sq of one simulation over every combination of
    :data:`UNSTATED_SETTINGS` (the settings the paper does not give): ``lo_nm``,
    ``hi_nm``, ``n`` and, against a paper's band ``value +- sd``, ``verdict``: "inside" or
    "outside" (for every setting) or "cannot discriminate" (the settings move the same
    surface across the band's edge), and ``wider_than_band`` (the spread exceeds the
    band's width: the settings matter more than the paper's uncertainty)."""
    import itertools

    r = sim.heightmap.machined - sim.heightmap.design
    px = sim.scene.simulation.pixel
    keys = list(UNSTATED_SETTINGS)
    vals = []
    filtered: dict = {}  # the form degree does not change the filtered map: one per filter
    for combo in itertools.product(*(UNSTATED_SETTINGS[k] for k in keys)):
        c = dict(zip(keys, combo))
        f = (c["illumination_na"], c["camera_pixel_mm"], c["s_filter_mm"])
        if f not in filtered:
            filtered[f] = instrument_filter(r, px, illumination_na=f[0], camera_pixel_mm=f[1],
                                            s_filter_mm=f[2])
        vals.append(sq_nm(poly_remove(filtered[f], c["form_degree"])))
    out = {"lo_nm": min(vals), "hi_nm": max(vals), "n": len(vals),
           "settings": {k: [None if v is None else float(v) for v in UNSTATED_SETTINGS[k]]
                        for k in keys}}
    if value is not None and sd is not None:
        lo, hi = value - sd, value + sd
        if out["lo_nm"] >= lo and out["hi_nm"] <= hi:
            out["verdict"] = "inside"
        elif out["lo_nm"] > hi or out["hi_nm"] < lo:
            out["verdict"] = "outside"
        else:
            out["verdict"] = "cannot discriminate"
        out["wider_than_band"] = bool(out["hi_nm"] - out["lo_nm"] > 2 * sd)
    return out


def compare(name, overrides=(), *, illumination_na=None) -> dict:
    """Sq and Sa of one scene's residual raw, poly2 and through the instrument."""
    scene = load_scene(name, list(overrides))
    t0 = time.perf_counter()
    out = compare_sim(simulate(scene), illumination_na=illumination_na)
    out["seconds"] = time.perf_counter() - t0
    return out


def table_row(name, label, res) -> str:
    """One Markdown row of the table: the scene, its window, raw and instrument Sq / Sa,
    the paper's value and whether the instrument's Sq lies inside its band."""
    spec = PAPERS[name]
    if spec["metric"]:
        inside = abs(res["instrument_Sq_nm"] - spec["value"]) <= spec["sd"]
        return (f"| {name}, {label} | {res['raw_Sq_nm']:.2f} / {res['raw_Sa_nm']:.2f} | "
                f"{res['instrument_Sq_nm']:.2f} / {res['instrument_Sa_nm']:.2f} | "
                f"{spec['value']} +- {spec['sd']} ({spec['paper']}) | "
                f"{'inside' if inside else 'outside'} |")
    return (f"| {name}, {label} | {res['raw_Sq_nm']:.2f} / {res['raw_Sa_nm']:.2f} | "
            f"{res['instrument_Sq_nm']:.2f} / {res['instrument_Sa_nm']:.2f} | {spec['paper']} | |")


TABLE_HEAD = ("| scene, window | raw Sq / Sa (nm) | through the instrument, poly2: Sq / Sa (nm) | "
              "paper | |\n|---|---|---|---|---|")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", action="append", help="scene (default: every one in PAPERS)")
    ap.add_argument("--illumination-na", type=float, default=None,
                    help="illumination NA of the objective (default: the pupil filled, 0.4)")
    ap.add_argument("--set", action="append", default=[], help="a scene override for every run")
    ap.add_argument("--json", help="write the numbers here too")
    a = ap.parse_args(argv)
    rows, out = [], {}
    for name in a.scene or list(PAPERS):
        for label, over in PAPERS[name]["windows"].items():
            res = compare(name, over + a.set, illumination_na=a.illumination_na)
            out[f"{name}: {label}"] = res
            rows.append(table_row(name, label, res))
            print(rows[-1], file=sys.stderr, flush=True)
    print(TABLE_HEAD)
    print("\n".join(rows))
    if a.json:
        with open(a.json, "w") as fh:
            json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
