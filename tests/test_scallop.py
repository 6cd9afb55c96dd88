"""Seed 001's residual-height formulas (flat, convex, concave) and the feed inversion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.errors import InputError
from render_inspect.machining import simulate_turning
from render_inspect.toolpath import ToolPath
from render_inspect.toolpath._scallop import (feed_for_scallop, max_feed_for_scallop, plan_feed,
                                              scallop_height)

r, f = 0.506, 0.05   # seed 001: tool 0.506 mm, 0.05 mm per revolution


def _paper(f, R):
    """Seed 001 eqs. 9-11 as printed (R > 0 convex, R < 0 concave, inf flat)."""
    u = (f / 2) ** 2
    if math.isinf(R):
        return r - math.sqrt(r * r - u)
    if R > 0:
        return math.sqrt((R + r) ** 2 - u) - math.sqrt(r * r - u) - R
    Rc = -R
    return Rc - math.sqrt((Rc - r) ** 2 - u) - math.sqrt(r * r - u)


@pytest.mark.parametrize("R", [math.inf, 1000.0, -1000.0, 5.0, -5.0, 0.8])
def test_scallop_height_is_seed001_eqs_9_to_11(R):
    k = 0.0 if math.isinf(R) else 1.0 / R
    assert_allclose(scallop_height(f, r, k), _paper(f, R), rtol=1e-9, atol=1e-15)


@pytest.mark.parametrize("R", [math.inf, 1000.0, -1000.0, 5.0, -5.0])
def test_feed_inversion_round_trips_and_matches_eq_12(R):
    k = 0.0 if math.isinf(R) else 1.0 / R
    H = float(scallop_height(f, r, k))
    assert_allclose(feed_for_scallop(H, r, k), f, rtol=1e-9)
    if not math.isinf(R):
        a = abs(R)
        if R < 0:   # eq. 12 f2, printed for the concave case
            f_eq = math.sqrt(-H * (H - 2 * a) * (H - 2 * r) * (H - 2 * a + 2 * r)) / (H - a)
        else:       # eq. 12 f3, convex
            f_eq = math.sqrt(-H * (H + 2 * a) * (H - 2 * r) * (H + 2 * a + 2 * r)) / (H + a)
        assert_allclose(abs(f_eq), f, rtol=1e-7)
    else:
        assert_allclose(2 * math.sqrt(-H * (H - 2 * r)), f, rtol=1e-9)   # eq. 12 f1


def test_bound_of_seed001_and_the_min_over_curvatures():
    # seed 001's 0.01 mm residual bound on a flat: f = 2 sqrt(H (2 r - H))
    f1 = float(feed_for_scallop(0.01, r, 0.0))
    assert_allclose(f1, 2 * math.sqrt(0.01 * (2 * r - 0.01)), rtol=1e-12)
    # a concave section leaves more scallop per feed, so it limits the feed (eq. 13)
    assert max_feed_for_scallop(0.01, r, [0.0, 1 / 1000, -1 / 1000]) == pytest.approx(
        float(feed_for_scallop(0.01, r, -1 / 1000)))
    assert float(feed_for_scallop(0.01, r, -1 / 1000)) < f1 < float(feed_for_scallop(0.01, r, 1 / 1000))


def test_bad_values_are_named():
    with pytest.raises(InputError, match="concave section needs a radius larger"):
        scallop_height(0.01, 0.5, -4.0)
    with pytest.raises(InputError, match="scallop height must be in"):
        feed_for_scallop(0.6, 0.5)
    with pytest.raises(InputError, match="feed must be in"):
        scallop_height(2.0, 0.5)


class _Sphere:
    """Concave sphere z = R - sqrt(R^2 - r^2) (bowl), with the Surface interface used by
    the planner."""

    def __init__(self, R):
        self.R = R

    def height(self, x, y):
        return self.R - np.sqrt(self.R ** 2 - x * x - y * y)

    def radial_slope(self, rho, theta):
        return rho / np.sqrt(self.R ** 2 - rho * rho)

    def section_curvature(self, x, y, direction):
        return np.full(np.broadcast(x, y).shape, 1.0 / self.R)  # concave: > 0


def test_plan_feed_on_a_bowl_and_the_machined_scallop_meets_the_bound():
    bowl = _Sphere(20.0)
    bound = 50e-6
    plan = plan_feed(bowl, nose_radius=0.5, scallop_bound=bound, r_outer=2.0, spindle_rpm=60.0)
    k = -1 / 20.0
    slope = 2.0 / math.sqrt(400 - 4)
    assert_allclose(plan["feed_per_rev_mm"],
                    float(feed_for_scallop(bound, 0.5, k)) / math.sqrt(1 + slope ** 2), rtol=1e-9)
    assert_allclose(plan["limiting_curvature_per_mm"], k, rtol=1e-12)
    assert plan["feed_mm_per_min"] == pytest.approx(60.0 * plan["feed_per_rev_mm"])
    # cut a flat face with the flat plan: the simulated peak-to-valley is the bound
    flat = plan_feed(type("Flat", (), {"radial_slope": lambda s, a, b: 0.0 * a,
                                       "section_curvature": lambda s, x, y, d: 0.0 * x})(),
                     nose_radius=0.5, scallop_bound=bound, r_outer=1.0)
    fr = flat["feed_per_rev_mm"]
    P = 720
    kk = np.arange(60 * P)
    th = kk * 2 * np.pi / P
    path = ToolPath(th, 1.0 - fr * kk / P, np.zeros(kk.size), th)
    row = simulate_turning(path, nose_radius=0.5, region=(0.7, 0.0, 0.8, 0.0), pixel=2e-5)[0]
    assert_allclose(np.nanmax(row) - np.nanmin(row), bound, rtol=0.01)
