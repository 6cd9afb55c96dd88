"""Tool accessibility (Li et al. 2018 [1]_, eq. 4-5; the compound sinusoidal grid paper
[2]_): can the tool reach every point?

Checks on the radial sections (the tool edge lies in the radial plane):
1. nose radius <= the smallest radius of curvature of concave radial sections;
2. included angle >= 2 x the largest radial slope angle (the nose flanks must not hit);
3. clearance angle > the largest slope angle seen in the cutting direction
   (circumferential), so the flank face does not rub.

References
----------
.. [1] D. Li, Z. Qiao, K. Walton, Y. Liu, J. Xue, B. Wang, X. Jiang, "Theoretical and
       experimental investigation of surface topography generation in slow tool servo
       ultra-precision machining of freeform surfaces," Materials 11(12), 2566 (2018).
       :DOI:`10.3390/ma11122566`
.. [2] "Compound sinusoidal grid surface" machined by slow tool servo diamond turning
       (the project's copy lacks authors, journal and year: docs/references.md).
"""

from __future__ import annotations

from collections.abc import Sequence
import math
from typing import Any

import numpy as np

from ._tool import Tool


def _grid(region, n):
    x0, y0, x1, y1 = region
    x = np.linspace(x0, x1, n)
    y = np.linspace(y0, y1, n)
    return np.meshgrid(x, y)


def check_accessibility(surface: Any, tool: Tool, region: Sequence[float], *,
                        samples: int = 201) -> dict:
    """Report where and by how much ``tool`` cannot reach ``surface`` over ``region``.

    Returns a dict: ``ok`` (bool) and, for each check (``nose_radius``, ``included_angle``,
    ``clearance_angle``): ``ok``, the worst value, the limit, the fraction of the sampled
    area that violates it and the worst location (x, y) in mm."""
    X, Y = _grid(region, samples)
    th = np.arctan2(Y, X)
    c, s = np.cos(th), np.sin(th)
    gx, gy = surface.gradient(X, Y)
    hxx, hxy, hyy = surface.hessian(X, Y)
    f_r = gx * c + gy * s
    f_t = -gx * s + gy * c
    f_rr = hxx * c * c + 2 * hxy * c * s + hyy * s * s
    kappa = f_rr / (1 + f_r * f_r) ** 1.5  # > 0: concave radial section
    report: dict[str, Any] = {"samples": int(samples * samples), "region": list(map(float, region))}

    def entry(name, value, limit, bad, unit, worst_idx):
        iy, ix = np.unravel_index(worst_idx, X.shape)
        report[name] = {"ok": not bool(bad.any()), "worst": float(value), "limit": float(limit),
                        "unit": unit, "violating_fraction": float(bad.mean()),
                        "worst_at_mm": [float(X[iy, ix]), float(Y[iy, ix])]}

    Rc = tool.nose_radius
    kmax_idx = int(np.nanargmax(kappa))
    kmax = float(kappa.flat[kmax_idx])
    min_roc = 1.0 / kmax if kmax > 0 else math.inf
    entry("nose_radius", min_roc, Rc, kappa * Rc > 1.0 + 1e-9, "mm (smallest concave radius of curvature)",
          kmax_idx)
    report["nose_radius"]["excess_mm"] = float(max(Rc - min_roc, 0.0))

    slope_r = np.degrees(np.arctan(np.abs(f_r)))
    i = int(np.nanargmax(slope_r))
    need = 2 * slope_r.flat[i]
    entry("included_angle", need, math.degrees(tool.included_angle),
          2 * slope_r > math.degrees(tool.included_angle), "deg (2 x largest radial slope)", i)

    slope_t = np.degrees(np.arctan(np.abs(f_t)))
    i = int(np.nanargmax(slope_t))
    entry("clearance_angle", slope_t.flat[i], math.degrees(tool.clearance_angle),
          slope_t >= math.degrees(tool.clearance_angle), "deg (largest slope in the cutting direction)", i)
    report["ok"] = all(report[k]["ok"] for k in ("nose_radius", "included_angle", "clearance_angle"))
    return report


def describe_accessibility(report: dict) -> str:
    lines = []
    for k in ("nose_radius", "included_angle", "clearance_angle"):
        e = report[k]
        if not e["ok"]:
            lines.append(f"{k}: worst {e['worst']:.6g} vs limit {e['limit']:.6g} {e['unit']}, "
                         f"{100 * e['violating_fraction']:.2f} % of the region, worst at "
                         f"({e['worst_at_mm'][0]:.4f}, {e['worst_at_mm'][1]:.4f}) mm")
    return "; ".join(lines) if lines else "tool reaches the whole region"
