"""Benchmark: metrology on realistic map sizes.

- areal parameters and the ISO 16610-61 Gaussian filter (masked, normalised) on 2048^2;
- outliers + 6-DOF least-squares registration of a 300 x 300 map, and ICP of 100 x 100;
- seed 002's 7 x 7 lenslet array (pitch 2 mm, aperture 1 mm, radius 10 mm) at 10 um:
  separation + per-lenslet sphere-centre fits (``lenslet_table``), and the full
  ``characterise_msa`` chain with registration;
- X3P write + read of a 1024^2 map;
- the one-map analysis (plane, slopes, Sal/Str) on 2048^2, Sal/Str alone, the
  correlated-residual registration uncertainty on 300 x 300, and reading each real
  instrument file in ../shared/realdata.
Prints seconds per task and returns them with the recovered figures.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np


def _t(fn, *a, **k):
    t = time.perf_counter()
    r = fn(*a, **k)
    return time.perf_counter() - t, r


def main(n_areal: int = 2048) -> dict:
    from render_inspect.design import LensletArray
    from render_inspect.io import read_x3p, write_x3p
    from render_inspect.metrology import (
        RIGID_KEYS,
        areal_parameters,
        characterise_msa,
        detect_outliers,
        gaussian_filter,
        lenslet_table,
        register_icp,
        register_lsq,
        rigid_resample,
    )

    out = {}
    rng = np.random.default_rng(0)
    x = 0.001 * np.arange(n_areal)
    z = 1e-4 * np.sin(2 * np.pi * x / 0.1)[None, :] * np.cos(2 * np.pi * x / 0.13)[:, None]
    z = z + rng.normal(0, 1e-6, z.shape)
    out["areal_parameters_2048_s"], _ = _t(areal_parameters, z, pixel=0.001)
    zn = z.copy()
    zn[100:200, 300:500] = np.nan
    out["gaussian_filter_2048_lc0.08_s"], _ = _t(gaussian_filter, zn, pixel=0.001, cutoff=0.08)

    class Freeform:
        def height(self, x, y):
            return (x * x / 40.0 + y * y / 70.0
                    + 2e-3 * np.sin(2 * np.pi * x / 0.5) * np.cos(2 * np.pi * y / 0.7))

        def gradient(self, x, y):
            k1, k2 = 2 * np.pi / 0.5, 2 * np.pi / 0.7
            return (x / 20.0 + 2e-3 * k1 * np.cos(k1 * x) * np.cos(k2 * y),
                    y / 35.0 - 2e-3 * k2 * np.sin(k1 * x) * np.sin(k2 * y))

    true = dict(zip(RIGID_KEYS, (8e-3, -5e-3, 3e-3, 4e-4, -3e-4, 1.5e-3)))
    for n, key in ((300, "lsq_300"), (100, "icp_100")):
        p = 1.2 / n
        g = -0.6 + p * np.arange(n)
        m = rigid_resample(Freeform(), true, g[None, :], g[:, None]) + rng.normal(0, 2e-6, (n, n))
        t0, (cl, ol) = _t(detect_outliers, m, pixel=p)
        fn = register_lsq if key.startswith("lsq") else register_icp
        t1, reg = _t(fn, cl, Freeform(), pixel=p, origin=(-0.6, -0.6), mask=~ol)
        out[f"outliers_{n}_s"] = t0
        out[f"register_{key}_s"] = t1
        out[f"register_{key}_err_um_mrad"] = [round(abs(reg[k] - true[k]) * 1e3, 4) for k in RIGID_KEYS]

    la = LensletArray(rows=7, cols=7, pitch_x=2.0, pitch_y=2.0, aperture_radius=1.0,
                      lens_radius=10.0)
    p = 0.01
    g = -7.0 + p * np.arange(1401)
    zl = np.asarray(la.height(g[None, :], g[:, None])) + rng.normal(0, 5e-6, (1401, 1401))
    out["lenslet_table_7x7_1401px_s"], tab = _t(lenslet_table, (zl, p, (-7.0, -7.0)), la)
    out["lenslet_table_max_dislocation_um"] = max(np.hypot(e["dx_um"], e["dy_um"]) for e in tab)
    sub = -3.0 + p * np.arange(601)  # 3 x 3 lenslets with registration
    zs = rigid_resample(la, true, sub[None, :], sub[:, None]) + rng.normal(0, 5e-6, (601, 601))
    with warnings.catch_warnings():  # the 40 lenslets outside the 6 x 6 mm map are left out
        warnings.simplefilter("ignore")
        out["characterise_msa_601px_s"], res = _t(characterise_msa, zs, la, pixel=p,
                                                  origin=(-3.0, -3.0))
    out["characterise_msa_lenslets"] = res["summary"]["n_lenslets"]
    with tempfile.TemporaryDirectory() as tmp:
        big = z[:1024, :1024]
        out["x3p_write_1024_s"], _ = _t(write_x3p, Path(tmp) / "m.x3p", big, pixel=0.001)
        out["x3p_read_1024_s"], _ = _t(read_x3p, Path(tmp) / "m.x3p")
    from render_inspect.io import read_surface
    from render_inspect.metrology import analyze_map, registration_covariance, spatial_parameters

    out["analyze_map_2048_s"], _ = _t(analyze_map, z, pixel=0.001)
    out["spatial_parameters_2048_s"], _ = _t(spatial_parameters, z, pixel=0.001)
    n = 300
    p = 1.2 / n
    g = -0.6 + p * np.arange(n)
    m = rigid_resample(Freeform(), true, g[None, :], g[:, None]) + rng.normal(0, 2e-6, (n, n))
    reg = register_lsq(m, Freeform(), pixel=p, origin=(-0.6, -0.6))
    res = m - rigid_resample(Freeform(), reg, g[None, :], g[:, None])
    out["registration_covariance_300_s"], _ = _t(registration_covariance, m, Freeform(), reg,
                                                 pixel=p, origin=(-0.6, -0.6), residual=res)
    real = Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata"
    for f in sorted(real.glob("*")):
        if f.suffix in (".md", ".yaml"):
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out[f"read_{f.name}_s"], _ = _t(read_surface, f)
    out = {k: (round(v, 4) if isinstance(v, float) else v) for k, v in out.items()}
    print(json.dumps(out, indent=2))
    return out


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:]))
