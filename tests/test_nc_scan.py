"""The compiled reader of the NC writers' own block form against the regular expression
that checked the runs before it: it takes exactly the runs the writers' plain pattern
takes, and reads every number to the bit as Python does."""

from __future__ import annotations

import re

import numpy as np
import pytest

from render_inspect.io._nc_parse import _FEED, _NUM, _uniform
from render_inspect.io._nc_scan import FORM_LONG, FORM_OK, FORM_OTHER, MAX_DIGITS, scan_uniform

WORD_SETS = ("CXZF", "CXZ", "XZ", "Z", "XYZF", "XYZ", "F", "")
#: an F word of the plain form (no exponent)
_PLAIN_FEED = r"\d+(?:\.\d+)?"


def _pattern(words: str, feed: str = _PLAIN_FEED) -> str:
    """The writers' form of a run of blocks carrying ``words`` (as the reader writes it;
    ``feed``: the form of an F word)."""
    blk = r"N\d+ G0[01]" + "".join(f" {w}{feed if w == 'F' else _NUM}" for w in words)
    return rf"(?:{blk}\n)*+"


def _decimal(rng, signed: bool, fraction: str) -> str:
    """A random decimal: up to 15 digits, a sign where allowed (a negative zero too),
    ``fraction``: "always", "maybe" or "never" a fraction."""
    n_int = int(rng.integers(1, 8))
    digits = "".join(rng.choice(list("0123456789"), size=n_int))
    if fraction == "always" or (fraction == "maybe" and rng.random() < 0.5):
        digits += "." + "".join(rng.choice(list("0123456789"), size=int(rng.integers(1, 16 - n_int))))
    return ("-" if signed and rng.random() < 0.4 else "") + digits


def _run(rng, words: str, lines: int) -> str:
    out = []
    for _ in range(lines):
        blk = f"N{int(rng.integers(0, 10 ** 7))} G0{int(rng.integers(0, 2))}"
        for w in words:
            blk += f" {w}" + (_decimal(rng, False, "maybe") if w == "F" else _decimal(rng, True, "always"))
        out.append(blk + "\n")
    return "".join(out)


@pytest.mark.parametrize("words", WORD_SETS)
def test_plain_runs_read_as_python_reads_them(words):
    """Random runs in the writers' form: the compiled reader takes them and gives every
    number as ``float`` reads it (the bits, negative zeros included)."""
    rng = np.random.default_rng(len(words))
    for lines in (0, 1, 2, 50, 500):
        text = _run(rng, words, lines)
        status, vals = scan_uniform(text, words)
        assert status == FORM_OK and vals.shape == (lines, 2 + len(words))
        want = np.array([float(t) for t in re.sub(f"[NG{words}]", " ", text).split()])
        assert vals.ravel().tobytes() == want.tobytes()


def test_negative_zero_and_edge_numbers():
    text = "N1 G00 X-0.000000 Z0.0\nN0012 G01 X123456789012.345 Z-0.5\n"
    status, vals = scan_uniform(text, "XZ")
    assert status == FORM_OK
    assert np.signbit(vals[0, 2]) and vals[0, 2] == 0.0 and not np.signbit(vals[0, 3])
    assert vals[1].tolist() == [12.0, 1.0, 123456789012.345, -0.5]


#: changes of one block that leave the writers' plain form (the general reader's business)
MUTATIONS = [
    ("trailing space", lambda s: s + " "), ("double space", lambda s: s.replace(" ", "  ", 1)),
    ("tab", lambda s: s.replace(" ", "\t", 1)), ("carriage return", lambda s: s + "\r"),
    ("lower case", lambda s: s.lower()), ("G02", lambda s: s.replace(" G01", " G02").replace(" G00", " G02")),
    ("G1", lambda s: s.replace(" G01", " G1").replace(" G00", " G0")),
    ("no N", lambda s: s[1:]), ("N without digits", lambda s: re.sub(r"^N\d+", "N", s)),
    ("plus sign", lambda s: re.sub(r" ([XZ])(\d)", r" \1+\2", s, count=1)),
    ("axis without fraction", lambda s: re.sub(r" ([XZ]-?\d+)\.\d+", r" \1", s, count=1)),
    ("axis with a bare point", lambda s: re.sub(r" ([XZ]-?\d+)\.\d+", r" \1.", s, count=1)),
    ("axis without integer digits", lambda s: re.sub(r" ([XZ]-?)\d+\.", r" \1.", s, count=1)),
    ("F with an exponent", lambda s: re.sub(r" F\S+", " F9.75e+01", s)),
    ("F with a bare point", lambda s: re.sub(r" F(\d+)\S*", r" F\1.", s)),
    ("negative F", lambda s: s.replace(" F", " F-")), ("a word missing", lambda s: re.sub(r" Z\S+", "", s)),
    ("a word twice", lambda s: s + " Z1.0"), ("words swapped", lambda s: re.sub(r" (X\S+) (Z\S+)", r" \2 \1", s)),
    ("a comment", lambda s: s + " ; note"), ("an empty line", lambda s: "\n" + s),
]


@pytest.mark.parametrize("name,change", MUTATIONS, ids=[m[0] for m in MUTATIONS])
def test_other_forms_are_left_to_the_general_reader(name, change):
    """A run with one block out of the plain form is refused by the compiled reader exactly
    when the writers' plain pattern refuses it, and the run reads as before (through the
    pattern and numpy, or not at all)."""
    rng = np.random.default_rng(7)
    words = "XZF"
    for k in range(20):
        lines = _run(rng, words, 8).splitlines()
        lines[k % 8] = change(lines[k % 8])
        text = "\n".join(lines) + "\n"
        status, _ = scan_uniform(text, words)
        plain = re.fullmatch(_pattern(words), text) is not None
        assert (status == FORM_OTHER) == (not plain), (name, text)
        got = _uniform(text, words)
        # the general way: the plain pattern, then the one with F words of any form
        table = str.maketrans({c: " " for c in "NG" + words})
        if plain:
            want = np.fromstring(text.translate(table), sep=" ").reshape(-1, 5)
        elif re.fullmatch(_pattern(words, _FEED), text):
            want = np.fromstring(text.translate(table), sep=" ")
            want = want.reshape(-1, 5) if want.size % 5 == 0 else None
        else:
            want = None
        if want is None:
            assert got is None, (name, text)
        else:
            assert got is not None and got.tobytes() == want.tobytes(), (name, text)


def test_numbers_beyond_15_digits_are_read_by_the_general_way():
    """A number of 16 digits or more is not read by the integer division (beyond 2**53):
    the compiled reader says so and the run is read by ``float``'s rounding."""
    text = "N1 G01 X1.234567890123456 Z0.5\nN2 G01 X0.5 Z0.25\n"
    assert MAX_DIGITS == 15
    assert scan_uniform(text, "XZ")[0] == FORM_LONG
    vals = _uniform(text, "XZ")
    assert vals is not None and vals[0, 2] == float("1.234567890123456")
    assert scan_uniform("N1 G01 X12345678901234.5 Z0.5\n", "XZ")[0] == FORM_OK  # 15 digits
    assert scan_uniform("N1234567890123456 G01 X1.5\n", "X")[0] == FORM_LONG
