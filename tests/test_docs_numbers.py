"""The numbers the docs quote from runs are current: every marked span
(``<!-- n:KEY -->TEXT<!-- /n -->``) in README.md and docs/*.md says what
``docs/numbers.json`` holds (fast), and the cheap runs made again give
``docs/numbers.json``'s values (slow).  ``python tools/docs_numbers.py`` makes both."""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _tool():
    spec = importlib.util.spec_from_file_location("docs_numbers", REPO / "tools" / "docs_numbers.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules.setdefault("docs_numbers", mod)
    spec.loader.exec_module(mod)
    return mod


def test_every_marked_number_is_the_runs():
    tool = _tool()
    data = tool.load_numbers()
    assert data["numbers"], "docs/numbers.json holds no number: run tools/docs_numbers.py"
    bad = tool.check(data)
    assert not bad, "\n".join(bad) + "\n(python tools/docs_numbers.py --docs rewrites them)"


def test_every_number_comes_from_a_known_run():
    tool = _tool()
    data = tool.load_numbers()
    quoted = {k for doc in tool.doc_files() for k, _ in tool.spans(doc.read_text())}
    assert quoted, "no doc marks a number"
    # every number comes from a run the script knows, and says which
    for key, n in data["numbers"].items():
        assert n["run"] in tool.RUNS, (key, n["run"])
        assert n["run"] in data["runs"] and data["runs"][n["run"]]["about"]
    assert quoted <= set(data["numbers"])


def test_rewrite_replaces_only_the_marked_text():
    tool = _tool()
    numbers = {"a.b": {"text": "-20.9"}, "blk": {"text": "\n```\nx\n```\n"}}
    text = "min <!-- n:a.b -->-0.03<!-- /n --> nm, 78.6 nm stays\n<!-- n:blk -->\n```\nold\n```\n<!-- /n -->"
    new, unknown = tool.rewrite(text, numbers)
    assert new == "min <!-- n:a.b -->-20.9<!-- /n --> nm, 78.6 nm stays\n<!-- n:blk -->\n```\nx\n```\n<!-- /n -->"
    assert unknown == []
    _, unknown = tool.rewrite("<!-- n:nope -->1<!-- /n -->", numbers)
    assert unknown == ["nope"]
    assert tool.fmt(-20.93) == "-20.9" and tool.fmt(-0.0001, ".2f") == "0.00"
    assert tool.fmt(744.2) == "744" and tool.fmt(12345.6) == "12346"


@pytest.mark.slow
def test_cheap_runs_give_the_numbers_in_the_docs():
    tool = _tool()
    data = tool.load_numbers()
    cheap = [name for name, run in tool.RUNS.items() if run.cheap]
    assert cheap
    for name in cheap:
        got = tool.RUNS[name].make()
        for key, item in got.items():
            value = item if isinstance(item, str) else item[0]
            want = data["numbers"][key]
            if isinstance(value, str):
                assert value == want["text"], key
            else:
                assert math.isclose(value, want["value"], rel_tol=0.005, abs_tol=0.02), \
                    (key, value, want["value"])
