"""The compiled writer of a turning program's cutting blocks against Python's formatting:
the same bytes for every value, ties and the values it leaves to Python included."""

from __future__ import annotations

import numpy as np
import pytest

from render_inspect.io._nc_format import format_linear_rows, format_turning_rows


def _python(k0, c, x, z, feed, f_from, decimals) -> bytes:
    """The blocks as the writer wrote them before, one Python format per number."""
    fmt = ("{:.%df}" % decimals).format
    rows = []
    for j in range(c.size):
        text = f"N{k0 + j} G01 C{fmt(float(c[j]))} X{fmt(float(x[j]))} Z{fmt(float(z[j]))}"
        rows.append(text + (" F%.10g" % float(feed[j]) if j >= f_from else ""))
    return ("\n".join(rows) + "\n").encode("ascii") if rows else b""


def _random_values(rng, n: int, decimals: int) -> np.ndarray:
    """Numbers of every size a program holds and beyond: mantissas at random over 18
    decades, both signs, zeros of both signs, ties of the last place written (odd
    multiples of 2**-(decimals + 1): 1/128 for six places) and numbers just beside them."""
    v = rng.random(n) * 10.0 ** rng.integers(-12, 7, size=n)
    v *= np.where(rng.random(n) < 0.5, -1.0, 1.0)
    tie = (2 * rng.integers(0, 10 ** 6, size=n) + 1) / 2.0 ** (decimals + 1)
    pick = rng.random(n)
    v = np.where(pick < 0.1, tie, v)
    v = np.where((pick >= 0.1) & (pick < 0.15), np.nextafter(tie, np.inf), v)
    v = np.where((pick >= 0.15) & (pick < 0.2), np.nextafter(tie, -np.inf), v)
    v = np.where((pick >= 0.2) & (pick < 0.22), 0.0, v)
    v = np.where((pick >= 0.22) & (pick < 0.24), -0.0, v)
    v = np.where((pick >= 0.24) & (pick < 0.26), -rng.random(n) * 1e-9, v)  # '-0.000000'
    return v


def _random_feeds(rng, n: int) -> np.ndarray:
    """Feeds (inverse time, 1/min) over 15 decades, with ties of the tenth digit
    (q + 1/2 for q of ten digits), the ten nines that round up to the next power of ten,
    and neighbours of powers of ten."""
    f = rng.random(n) * 10.0 ** rng.integers(-3, 12, size=n)
    pick = rng.random(n)
    q = rng.integers(10 ** 9, 10 ** 10, size=n).astype(np.float64)
    f = np.where(pick < 0.1, q + 0.5, f)
    f = np.where((pick >= 0.1) & (pick < 0.12), 9999999999.5, f)
    f = np.where((pick >= 0.12) & (pick < 0.14), 9999999999.4, f)
    p10 = 10.0 ** rng.integers(0, 11, size=n)
    f = np.where((pick >= 0.14) & (pick < 0.2), np.nextafter(p10, -np.inf), f)
    f = np.where((pick >= 0.2) & (pick < 0.25), p10, f)
    f = np.where((pick >= 0.25) & (pick < 0.3), p10 * (1 - 5e-11), f)  # rounds up to the power
    return f


@pytest.mark.parametrize("decimals", range(3, 13))
def test_blocks_are_pythons_bytes(decimals):
    """Random blocks at every number of places the writer takes: the compiled writer's
    bytes equal Python's formatting, the block numbers, the first block without F, and
    the values it hands to Python (beyond 2**40 scaled, feeds outside [1, 1e10))."""
    rng = np.random.default_rng(decimals)
    n = 20_000
    c = _random_values(rng, n, decimals) * np.where(rng.random(n) < 0.05, 1e7, 1.0)  # large C
    x, z = _random_values(rng, n, decimals), _random_values(rng, n, decimals)
    feed = _random_feeds(rng, n)
    for k0, f_from in ((1, 1), (16385, 0), (10 ** 12, 0)):
        got = format_turning_rows(k0, c, x, z, feed, f_from, decimals)
        assert got == _python(k0, c, x, z, feed, f_from, decimals)


def test_known_ties_and_edges():
    """Ties go to the even digit as Python writes them; -0.0 and small negatives keep
    their sign; a feed of ten nines and a half rounds up and is written by Python."""
    c = np.array([0.0078125, 0.0234375, -0.0, -1e-9, 1234.5, 5e-7, 2.0 ** 52 / 1e6,
                  np.nextafter(2.0 ** 52 / 1e6, 0.0)])  # (the exact range's end, six places)
    x = np.zeros(c.size)
    z = np.zeros(c.size)
    feed = np.array([1234567890.5, 1234567891.5, 9999999999.5, 1.0, 0.5, 1e10, 97.08643605, 2.5])
    got = format_turning_rows(1, c, x, z, feed, 0, 6).decode().split("\n")
    assert got[0] == "N1 G01 C0.007812 X0.000000 Z0.000000 F1234567890"
    assert got[1] == "N2 G01 C0.023438 X0.000000 Z0.000000 F1234567892"
    assert got[2] == "N3 G01 C-0.000000 X0.000000 Z0.000000 F1e+10"
    assert got[3].startswith("N4 G01 C-0.000000 ") and got[3].endswith(" F1")
    assert got[4].endswith(" F0.5") and got[5].endswith(" F1e+10")
    assert got[6].endswith(" F97.08643605")
    assert "\n".join(got).encode() == _python(1, c, x, z, feed, 0, 6)


def test_no_blocks():
    assert format_turning_rows(1, *(np.zeros(0) for _ in range(4)), 0, 6) == b""


def test_linear_blocks_are_pythons_bytes():
    """An X-Y-Z program's blocks (six places, the feed's text given): Python's bytes, the
    values it hands to Python included."""
    rng = np.random.default_rng(1)
    n = 20_000
    x = _random_values(rng, n, 6) * np.where(rng.random(n) < 0.05, 1e7, 1.0)
    y, z = _random_values(rng, n, 6), _random_values(rng, n, 6)
    for feed in ("500", "0.5", "1e+06"):
        want = "".join(f"N{7 + j} G01 X{xi:.6f} Y{yi:.6f} Z{zi:.6f} F{feed}\n"
                       for j, (xi, yi, zi) in enumerate(zip(x.tolist(), y.tolist(), z.tolist())))
        assert format_linear_rows(7, x, y, z, feed) == want.encode("ascii")
