"""The one compiled pass over a program's blocks (``toolpath/_verify_scan.py``) gives what
the array form of the checks gave, to the block: where each check of the moves first
fails, the points of the cut, the counts, the lowest rapid and a turning program's first
block over the spindle speed and the X and Z velocities, on planned programs of both
dialects with faults put in (moves sideways, rapids low, NaN axes, steps too long,
roles and motions swapped)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from render_inspect.core.toolpath import ROLE_CUT, ROLE_PLUNGE, ROLE_RETRACT
from render_inspect.design import make_surface
from render_inspect.io import program_blocks
from render_inspect.processes import process_of
from render_inspect.scene import load_scene
from render_inspect.toolpath._verify import _ROUND, _tip
from render_inspect.toolpath._verify_scan import scan_blocks

SCENES = {"turning": ("sts_sinusoidal_grid", ["process.workpiece_radius=0.35",
                                              "process.points_per_rev=720",
                                              "simulation.region=[-0.12,-0.12,0.12,0.12]"]),
          "linear": ("sculpt_quad_mla", [])}


def _first(mask):
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else None


def _array_form(b, x, y, z, zc, max_step, rpm_max, v_max):
    """The checks as numpy array expressions (the form the pass replaced)."""
    n = b.count
    rapid = b.motion == 0
    role = b.role
    zs = np.r_[z[0], z[:-1]]
    feedmove = ~rapid & (role != ROLE_CUT)
    moved = np.zeros(n, dtype=bool)
    for a in [a for a in b.axes if a != "Z"]:
        moved[1:] |= np.abs(np.diff(b.axes[a])) > _ROUND / 2
    lower = feedmove & (z <= zs)
    lower[:-1] |= feedmove[1:] & (z[1:] >= zs[1:])
    step = np.r_[0.0, np.sqrt(np.diff(x) ** 2 + np.diff(y) ** 2 + np.diff(z) ** 2)]
    rz = np.minimum(z, zs)[rapid & (np.arange(n) > 0)]
    out = {"low": _first(rapid & ((z < zc - _ROUND) | (zs < zc - _ROUND))),
           "sideways": _first(feedmove & moved),
           "short": _first(feedmove & (np.maximum(z, zs) < zc - _ROUND)),
           "direction": _first(((role == ROLE_PLUNGE) & (z > zs)) |
                                ((role == ROLE_RETRACT) & (z < zs))),
           "step": _first((role == ROLE_CUT) & (step > max_step + 4 * _ROUND)),
           "cutpt": ((role == ROLE_CUT) | lower) & np.isfinite(x) & np.isfinite(y),
           "rapids": int(rapid.sum()), "plunges": int((role == ROLE_PLUNGE).sum()),
           "retracts": int((role == ROLE_RETRACT).sum()), "cuts": int((role == ROLE_CUT).sum()),
           "rapid_lowest": float(rz.min()) if rz.size else None}
    if b.dialect == "turning":
        fm = np.r_[False, b.motion[1:] == 1]
        with np.errstate(invalid="ignore", divide="ignore"):
            dt = np.full(n, np.nan)
            dt[fm] = 60.0 / b.feed[fm]
            rpm = np.zeros(n)
            dc = np.maximum(np.abs(np.r_[0.0, np.diff(b.axes["C"])]) - 2 * _ROUND, 0.0)
            rpm[fm] = (np.radians(dc) / (2 * math.pi))[fm] / dt[fm] * 60.0
            speeds = {"C": _first(rpm > rpm_max)}
            for a in ("X", "Z"):
                mv = np.maximum(np.abs(np.r_[0.0, np.diff(b.axes[a])]) - 2 * _ROUND, 0.0)
                speeds[a] = _first(np.where(fm & (dt > 0), mv / dt, 0.0) > v_max[a])
        out["speeds"] = speeds
    return out


@pytest.mark.parametrize("dialect", sorted(SCENES))
def test_the_pass_over_the_blocks_equals_the_array_form(dialect):
    name, keys = SCENES[dialect]
    scene = load_scene(name, keys)
    process = process_of(scene)
    cfg = process.inputs_of(scene)
    surface = make_surface(scene.design)
    plan = process.plan(cfg, surface, region=tuple(scene.simulation.region))
    links, part = process.program_links_part(cfg, surface, plan)
    base = program_blocks(plan.program, links)
    rng = np.random.default_rng(5)
    found = set()
    for case in range(60):
        b = copy.deepcopy(base)
        ax, names = b.axes, [a for a in b.axes if a != "Z"]
        i = int(rng.integers(1, b.count))
        kind = case % 10
        if kind == 0:  # the block before a rapid low (the rapid starts below the plane)
            k = int(rng.choice(np.flatnonzero(b.motion[1:] == 0))) + 1
            ax["Z"][k - 1] -= rng.uniform(1e-3, 1)
        elif kind == 8:  # a plunge or retract that does not move (its ends equal)
            k = int(rng.choice(np.flatnonzero((b.role == ROLE_PLUNGE) | (b.role == ROLE_RETRACT))))
            ax["Z"][k] = ax["Z"][k - 1]
        elif kind == 9:  # a cut at the height of the block before it
            ax["Z"][i] = ax["Z"][i - 1]
        elif kind == 1:
            ax["Z"][i] -= rng.uniform(0, 1)
        elif kind == 2:
            ax[names[1]][i] += rng.uniform(-0.01, 0.01)
        elif kind == 3:
            ax[rng.choice(["Z", *names])][i] = np.nan
        elif kind == 4:
            b.motion[i] = 1 - b.motion[i]
        elif kind == 5:
            b.role[i] = rng.integers(0, 4)
        elif kind == 6:
            k = int(rng.choice(np.flatnonzero(b.role != ROLE_CUT)))
            ax[names[1]][k] += rng.uniform(-1e-5, 1e-5)
        elif kind == 7:
            ax[names[1]][i:i + 3] += 0.05
        x, y, z = _tip(b)
        zc = float(links.clearance_z)
        max_step = float(part.max_step)
        rpm_max, v_max = 50.0 * rng.uniform(0.2, 1.2), {"X": rng.uniform(0.001, 0.1),
                                                         "Z": rng.uniform(0.001, 0.1)}
        got = scan_blocks(b, x, y, z, zc, _ROUND, max_step, to_s=60.0, rpm_max=rpm_max,
                          v_max=v_max)
        want = _array_form(b, x, y, z, zc, max_step, rpm_max, v_max)
        assert np.array_equal(got.pop("cutpt"), want.pop("cutpt"))
        if dialect != "turning":
            got.pop("speeds")
        lowest, lowest_want = got.pop("rapid_lowest"), want.pop("rapid_lowest")
        assert (lowest is None) == (lowest_want is None)
        assert lowest is None or lowest == lowest_want or (math.isnan(lowest)
                                                           and math.isnan(lowest_want))
        assert got == want
        found |= {k for k, v in got.items() if k in ("low", "sideways", "short", "direction",
                                                     "step") and v is not None}
        found |= {f"speed {k}" for k, v in got.get("speeds", {}).items() if v is not None}
    # the faults put in reach the checks (the comparison is not of empty results only)
    assert {"low", "sideways", "step"} <= found
    if dialect == "turning":
        assert {"speed C", "speed X", "speed Z"} <= found
