"""Benchmark: ``render-inspect fit`` on a measured profile - the time of one evaluation and of
a two-key fit.

The case is the known answer of ``tests/test_fit_profile.py``: the example turned scene
(``docs/examples/turned/scene.toml`` without its program: a planned spiral of one feed per
revolution, the white-light virtual instrument) cut with a feed of 36 um/rev (3.6 mm/min at
100 rpm) and a 0.25 mm nose, measured along the radius from 0.1 to 0.5 mm at 0.87 um
spacing with the camera's noise (seed 7), then fitted over a 0.3 mm window centred 0.3 mm
from the axis from the scene's 39.6 um/rev and 0.2 mm (feed and nose radius free, no Sobol
design, at most 60 evaluations, as the test).

Figures (printed and returned by :func:`main`):

* ``evaluation_s``: one evaluation (the band about the window simulated at the evaluations'
  pixel, imaged by the virtual interferometer at the profile's spacing, measured and
  sampled along the line), median of 3 in this process, on the fit's own solution task;
* ``fit_s``, ``fit_evaluations``, ``fit_per_evaluation_s``: the two-key fit (serial; its
  clean prediction and six realisations of the camera's noise included), its status,
  values, errors and standard errors;
* ``simulate_profile_s``: making the measured profile (the same chain with the noise on,
  over the whole 0.4 mm line).

With ``--random``, the known answer of ``tests/test_fit_profile_random.py`` instead: the
same cut with a 100 Hz Z servo loop and 5 nm rms of Z following-error noise, fitted from
39.6 um/rev and 2.5 nm (``process.feed_mm_per_min`` and ``machine.z.noise_nm`` free, the
amplitude through the profile's ``psd`` bands): ``fit_s``, its evaluations, status, values,
errors and standard errors, and the bands used.

Run: ``nice .venv/bin/python benchmarks/bench_fit_profile.py [--random]`` (or ``make bench
ONLY=fit_profile``).
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import tempfile
import time
import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "docs" / "examples" / "turned" / "scene.toml"
TRUTH = {"process.feed_mm_per_min": 3.6, "tool.nose_radius": 0.25}
SPACING_MM = 0.00087


def _turned(feed=3.96, nose=0.2):
    """The example turned scene with a planned spiral (its program left out), white light."""
    from render_inspect.scene import scene_from_dict

    d = tomllib.loads(SCENE.read_text())
    d["process"].pop("program", None)
    d["process"]["feed_mm_per_min"] = feed
    d["tool"]["nose_radius"] = nose
    d["render"]["interferometer"]["mode"] = "csi"
    return scene_from_dict(d, "turned (planned spiral)")


def _write_profile(path: Path, s_mm, z_mm) -> None:
    import numpy as np

    lines = ["x (um), height (um)"]
    lines += [f"{s * 1e3:.6f}, " + ("" if not np.isfinite(z) else f"{z * 1e3:.7f}")
              for s, z in zip(s_mm, z_mm)]
    path.write_text("\n".join(lines) + "\n")


def main() -> dict:
    from render_inspect.instruments import height_instrument
    from render_inspect.pipeline import _fit_profile, run_fit_profile

    out = {"cpus": os.cpu_count(),
           "affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
           "load_average": round(os.getloadavg()[0], 2)}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        t0 = time.perf_counter()
        s, z = _fit_profile.simulate_profile(_turned(feed=3.6, nose=0.25), (0.1, 0.0),
                                             (0.5, 0.0), SPACING_MM, seed=7)
        out["simulate_profile_s"] = round(time.perf_counter() - t0, 2)
        p = tmp / "simulated.csv"
        _write_profile(p, s, z)
        # the evaluations' tasks are recorded on their way to the forward model, so that one
        # of them can be timed on its own afterwards
        tasks = []
        evaluate = _fit_profile.predict_profile

        def recording(spec):
            tasks.append(spec)
            return evaluate(spec)

        _fit_profile.predict_profile = recording
        try:
            t0 = time.perf_counter()
            rec = run_fit_profile(p, _turned(), [",".join(TRUTH)], tmp / "fit",
                                  line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.3,
                                  global_points=0, max_evaluations=60, profile_points=0,
                                  cache=tmp / "cache")
            out["fit_s"] = round(time.perf_counter() - t0, 1)
        finally:
            _fit_profile.predict_profile = evaluate
        out["fit_status"] = rec["status"]
        out["fit_evaluations"] = rec["evaluations"]
        out["fit_per_evaluation_s"] = round(rec["timing_s"]["per_evaluation"], 3)
        out["forward_model_calls"] = len(tasks)
        for k, v in TRUTH.items():
            par = rec["parameters"][k]
            out[f"fit_{k}"] = par["value"]
            out[f"fit_{k}_error_percent"] = round(100 * (par["value"] - v) / v, 4)
            out[f"fit_{k}_stderr_percent"] = (None if par["stderr"] is None
                                              else round(100 * par["stderr"] / v, 4))
        # one evaluation: the last one the fit asked for (near its solution; the camera's
        # noise off, as in every evaluation)
        name = height_instrument().name
        spec = [t for t in tasks if t["scene"]["render"][name].get("noise") is False][-1]
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            _fit_profile.predict_profile(spec)
            times.append(time.perf_counter() - t0)
        out["evaluation_s"] = round(statistics.median(times), 3)
        out["evaluation_points"] = int(spec["line"]["count"])
        region = spec["scene"]["simulation"]["region"]
        out["evaluation_region_mm"] = [round(v, 4) for v in region]
        out["evaluation_pixel_um"] = round(spec["scene"]["simulation"]["pixel"] * 1e3, 4)
    out["load_average_after"] = round(os.getloadavg()[0], 2)
    print(json.dumps(out, indent=2))
    return out


RANDOM_TRUTH = {"process.feed_mm_per_min": 3.6, "machine.z.noise_nm": 5.0}


def _with_z_noise(feed: float, z_noise_nm: float):
    """:func:`_turned` (0.2 mm nose) with a 100 Hz Z servo loop and Z following-error noise
    (nm rms)."""
    from render_inspect.scene import scene_from_dict

    d = _turned(feed=feed).to_dict()
    d["machine"]["z"] = {"bandwidth_hz": 100.0, "noise_nm": z_noise_nm}
    return scene_from_dict(d, "turned (planned spiral, Z noise)")


def main_random() -> dict:
    """The fit of a random part's amplitude and the feed on a profile (``--random``)."""
    from render_inspect.pipeline import _fit_profile, run_fit_profile

    out = {"cpus": os.cpu_count(), "load_average": round(os.getloadavg()[0], 2)}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        s, z = _fit_profile.simulate_profile(_with_z_noise(3.6, 5.0), (0.1, 0.0), (0.5, 0.0),
                                             SPACING_MM, seed=7)
        p = tmp / "simulated.csv"
        _write_profile(p, s, z)
        t0 = time.perf_counter()
        c0 = time.process_time()
        rec = run_fit_profile(p, _with_z_noise(3.96, 2.5), [",".join(RANDOM_TRUTH)],
                              tmp / "fit", line="0.1,0,0.5,0", at=(0.3, 0.0), window_mm=0.3,
                              global_points=0, max_evaluations=60, profile_points=0,
                              cache=tmp / "cache")
        out["fit_s"] = round(time.perf_counter() - t0, 1)
        out["fit_cpu_s"] = round(time.process_time() - c0, 1)
        out["fit_status"] = rec["status"]
        out["fit_evaluations"] = rec["evaluations"]
        out["psd_bands"] = rec["random_parts"]["psd_bands"]["bands"]
        for k, v in RANDOM_TRUTH.items():
            par = rec["parameters"][k]
            out[f"fit_{k}"] = par["value"]
            out[f"fit_{k}_error_percent"] = round(100 * (par["value"] - v) / v, 4)
            out[f"fit_{k}_stderr_percent"] = (None if par["stderr"] is None
                                              else round(100 * par["stderr"] / v, 4))
    out["load_average_after"] = round(os.getloadavg()[0], 2)
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    sys.exit(0 if (main_random() if "--random" in sys.argv[1:] else main()) else 1)
