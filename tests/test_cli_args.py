"""The options several commands share are defined once (cli/_args.py): ``--set``, and
``--workers`` / ``--scheduler``, each command keeping its own help text."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from render_inspect.cli import build_parser

CLI = Path(__file__).resolve().parents[1] / "render_inspect" / "cli"
SHARED = {"--set", "--workers", "--scheduler", "--out", "--overwrite", "--program", "--quiet", "--verbose"}


def test_shared_options_are_defined_only_in_the_args_module():
    found = []
    for py in sorted(CLI.glob("*.py")):
        if py.name == "_args.py":
            continue
        for node in ast.walk(ast.parse(py.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", "") == "add_argument":
                flags = {a.value for a in node.args if isinstance(a, ast.Constant)}
                if flags & SHARED:
                    found.append((py.name, node.lineno, sorted(flags & SHARED)))
    # only the sweep's and regress's own --out / --overwrite, whose help says what their
    # folder holds, are defined elsewhere
    others = [f for f in found if not (f[0] == "_batch.py" and set(f[2]) <= {"--out", "--overwrite"})]
    assert not others, others


@pytest.mark.parametrize("argv", [
    ["fit", "m.exr", "--scene", "s", "--free", "k", "--out", "o", "--workers", "2", "--scheduler", "a"],
    ["sweep", "f", "--out", "o", "--workers", "2", "--scheduler", "a"],
])
def test_workers_and_scheduler_exclude_each_other_where_they_did(argv, capsys):
    with pytest.raises(SystemExit) as err:
        build_parser().parse_args(argv)
    assert err.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err


def test_set_collects_every_override_in_order():
    for argv in (["simulate", "s", "--out", "o"], ["regress"], ["characterise", "--out", "o"],
                 ["fit", "m.exr", "--scene", "s", "--free", "k", "--out", "o"]):
        args = build_parser().parse_args([*argv, "--set", "a=1", "--set", "b=2"])
        assert args.overrides == ["a=1", "b=2"]
    args = build_parser().parse_args(["simulate", "s", "--out", "o", "--workers", "2", "--scheduler", "x"])
    assert (args.workers, args.scheduler) == (2, "x")  # simulate never made them exclusive
