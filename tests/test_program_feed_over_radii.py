"""The feed per revolution a program commands over a stretch of radii
(:func:`render_inspect.processes.feed_over_radii`): a spiral of known steps gives the known
mean spacing and the Hann-weighted one, the published programs give the mean of their own
X steps (read from their text, one revolution to the next), and radii the program does
not reach are refused in one line."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import REALDATA
from render_inspect.core.errors import InputError
from render_inspect.core.toolpath import ToolPath
from render_inspect.io import read_program
from render_inspect.processes import feed_over_radii


def _spiral(feed_inner, feed_outer, r_change, r_max=1.0, per_rev=400):
    """A spiral inwards whose feed per revolution is ``feed_outer`` beyond ``r_change``
    and ``feed_inner`` inside it (mm)."""
    theta, rho, r, th = [], [], r_max, 0.0
    while r > 0:
        f = feed_outer if r > r_change else feed_inner
        theta.append(th)
        rho.append(r)
        th += 2 * math.pi / per_rev
        r -= f / per_rev
    theta, rho = np.array(theta), np.array(rho)
    return ToolPath(theta, rho, np.zeros_like(rho), theta.copy(), {})


def test_known_steps_give_the_mean_spacing_and_the_hann_weighted_one():
    path = _spiral(0.02, 0.04, 0.3)
    # constant step: both weightings give it
    assert feed_over_radii(path, 0.5, 0.8) == pytest.approx(0.04, rel=1e-6)
    assert feed_over_radii(path, 0.5, 0.8, weighting="hann") == pytest.approx(0.04, rel=1e-6)
    # 0.2-0.5 mm: 5 turns at 0.02 and 5 at 0.04 -> 0.3 mm over 10 turns (the step changes
    # at a point of the path: a 400th of a turn)
    assert feed_over_radii(path, 0.2, 0.5) == pytest.approx(0.03, rel=5e-4)
    # under a Hann window over 0.2-0.5 mm the inner third (50 turns per mm) weighs
    # 1/3 - sin(2 pi / 3) / (2 pi) of the whole, the rest 25 turns per mm
    share = 1 / 3 - math.sin(2 * math.pi / 3) / (2 * math.pi)
    hann = 1 / (share * 50 + (1 - share) * 25)
    assert feed_over_radii(path, 0.2, 0.5, weighting="hann") == pytest.approx(hann, rel=2e-3)


def test_radii_the_program_does_not_reach_are_refused():
    path = _spiral(0.02, 0.04, 0.3)
    with pytest.raises(InputError, match=r"reaches radii .*-1 mm, not 0.5-1.2 mm"):
        feed_over_radii(path, 0.5, 1.2)
    with pytest.raises(InputError, match="0 <= r0 < r1"):
        feed_over_radii(path, 0.4, 0.3)
    with pytest.raises(InputError, match="weighting"):
        feed_over_radii(path, 0.2, 0.3, weighting="mean")


def test_published_programs_give_the_mean_of_their_own_steps():
    """Over the radii between two of a program's points at C = 0, n revolutions apart, the
    feed is the mean of its X steps there (the program's text, not the reader)."""
    folder = REALDATA / "turned"
    if not folder.is_dir():
        pytest.skip(f"the published programs are not beside this checkout ({folder})")
    files = sorted(folder.glob("*.nc"))
    assert len(files) == 3, files
    for f in files:
        c, x = [], []
        for word in f.read_text().split():
            if word[0] == "C":
                c.append(float(word[1:]))
            elif word[0] == "X":
                x.append(float(word[1:]))
        c, x = np.asarray(c), np.asarray(x)
        at = np.flatnonzero(c % 360.0 == 0.0)
        at = at[np.r_[True, np.diff(at) > 1]]  # one point a turn (360 then 0.5, or 0)
        xs = x[at]
        path = read_program(f, part_radius=1.1, spindle_rpm=100.0).program
        for k, n in ((3, 5), (len(xs) // 2, 8), (len(xs) - 12, 6)):
            r1, r0 = xs[k], xs[k + n]
            assert feed_over_radii(path, r0, r1) == pytest.approx(
                np.mean(xs[k:k + n] - xs[k + 1:k + n + 1]), rel=1e-9), (f.name, k)


def test_radii_between_two_points_of_the_program():
    """A stretch shorter than the program's spacing of points (two points a turn): the
    feed is still the step there."""
    theta = np.arange(0, 40) * math.pi
    rho = 1.0 - 0.01 * theta / (2 * math.pi)
    path = ToolPath(theta, rho, np.zeros_like(rho), theta.copy(), {})
    assert feed_over_radii(path, 0.9512, 0.9518) == pytest.approx(0.01, rel=1e-9)
