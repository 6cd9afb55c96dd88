"""Benchmark: phase retrieval and ``render-inspect compare``.

- PSI 4-step and 5-step retrieval with quality-guided unwrapping on a 1024^2 camera
  (a tilted sphere, about 50 fringes, at least 7 pixels per fringe), error against the known height;
- CSI envelope retrieval on 256^2 pixels x the scan a 3 um height range needs;
- ``compare`` on ``scenes/sts_fig16_overcut.toml`` (seed 000 Fig. 16) with its default
  render sizes: wall time, the stages, and the overcut figures.
Prints the figures and returns them (docs/report.md quotes them).
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _psi_frames(h, steps, lam):
    return np.stack([0.5 + 0.4 * np.cos(4 * np.pi * h / lam + d) for d in steps])


def main(n: int = 1024, compare: bool = True) -> dict:
    from render_inspect.instruments import Camera, Microscope, csi_frames, led
    from render_inspect.metrology import height_error, retrieve_csi, retrieve_psi

    out = {}
    lam_nm = 550.0
    lam = lam_nm * 1e-6
    x = (np.arange(n) - n / 2) * 0.001
    xx, yy = np.meshgrid(x, x)
    h = 20.0 - np.sqrt(400.0 - xx ** 2 - yy ** 2) + 2e-3 * xx  # sag + tilt, mm
    out["psi_fringes"] = float(np.ptp(h) / (lam / 2))
    retrieve_psi(_psi_frames(h[:16, :16], np.arange(4) * np.pi / 2, lam), wavelength_nm=lam_nm)  # JIT
    for k, steps in (("4step", np.arange(4) * np.pi / 2), ("5step", (np.arange(5) - 2) * np.pi / 2)):
        f = _psi_frames(h, steps, lam)
        t = time.perf_counter()
        res = retrieve_psi(f, wavelength_nm=lam_nm, steps_rad=steps)
        out[f"psi_{k}_{n}px_s"] = time.perf_counter() - t
        out[f"psi_{k}_rms_nm"] = height_error(res.height, h, valid=res.valid)[1]["rms_nm"]

    m = 256
    rng = np.random.default_rng(0)
    # a smooth random surface, +-1.5 um, imaged by the 20x objective model (600 / 120 nm LED)
    from scipy.ndimage import gaussian_filter

    hc = gaussian_filter(rng.standard_normal((m, m)), 12, mode="wrap")
    hc *= 0.0015 / np.abs(hc).max()
    fr = csi_frames(hc, pixel=0.001, microscope=Microscope(source=led(600.0, bandwidth_nm=120.0),
                                                           camera=Camera(noise=False)))
    frames, scan = fr.frames, fr.scan_positions
    out["csi_frames"] = int(frames.shape[0])
    for refine in ("envelope", "phase"):
        t = time.perf_counter()
        res = retrieve_csi(frames, scan, wavelength_nm=fr.effective_wavelength_nm, refine=refine)
        out[f"csi_{refine}_{m}px_s"] = time.perf_counter() - t
        out[f"csi_{refine}_rms_nm"] = height_error(res.height, hc, valid=res.valid,
                                                   piston="none")[1]["rms_nm"]

    if compare:
        from render_inspect.pipeline import run_compare
        from render_inspect.scene import load_scene

        scene = load_scene(REPO / "scenes" / "sts_fig16_overcut.toml")
        with tempfile.TemporaryDirectory() as d:
            t = time.perf_counter()
            mt = run_compare(scene, Path(d) / "cmp")
            out["compare_fig16_wall_s"] = time.perf_counter() - t
            out["compare_fig16_report_html_kB"] = (Path(d) / "cmp" / "report.html").stat().st_size / 1024
        for v in ("compensated", "uncompensated"):
            out[f"compare_fig16_{v}_timing_s"] = {k: round(s, 3) for k, s in mt[v]["timing_s"].items()}
            out[f"compare_fig16_{v}_min_nm"] = mt[v]["residual"]["min_nm"]
            out[f"compare_fig16_{v}_Sq_nm"] = mt[v]["residual"]["Sq_nm"]
            out[f"compare_fig16_{v}_measured_rms_nm"] = mt[v]["measured"]["rms_nm"]
        out["compare_fig16_interferometer_shape"] = mt["compensated"]["interferometer"]["shape"]
        out["compare_mitsuba_variant"] = mt["mitsuba_variant"]
    print(json.dumps(out, indent=2, default=str))
    return out


if __name__ == "__main__":
    main(compare="--no-compare" not in sys.argv)
