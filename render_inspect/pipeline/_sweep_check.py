"""A sweep refused before anything runs: the points that are not valid scenes (or do not
fit the memory budget), their complaints gathered into one message, one line per key and
what it must be, however many points of a large grid break it; and the points that failed
as they ran, gathered the same way: one line per reason."""

from __future__ import annotations

import re
from collections.abc import Iterable
from pathlib import Path

from ..core.errors import InputError

__all__ = ["check_sweep_tasks", "group_errors", "failure_lines", "SHOW_ERRORS", "SHOW_VALUES"]

#: distinct errors a refused sweep lists
SHOW_ERRORS = 8
#: values received (and point numbers) a refused sweep shows of each error
SHOW_VALUES = 5
#: where an error's words end and the value received begins (the last such place)
_RECEIVED = re.compile(r"^(.*)[;,] received (.*)$", re.S)
#: a number in a message (not the digits of a name such as ``G01`` or ``sts_fig16``)
_NUMBER = re.compile(r"(?<![A-Za-z_\d.])-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?(?![A-Za-z_\d])")


def _skeleton(text: str) -> tuple[str, list[str]]:
    """The message with its numbers taken out (two messages alike but for their numbers
    give the same reason) and the numbers, in order."""
    return _NUMBER.sub("#", text), _NUMBER.findall(text)


def _merged(text: str, numbers: list[list[str]]) -> str:
    """``text`` with each of its numbers that differs between the messages of one reason
    (``numbers``: each message's numbers) written as its range, least .. greatest."""
    spans = iter(zip(*numbers))

    def one(_m: re.Match) -> str:
        vals = next(spans)
        if len(set(vals)) == 1:
            return vals[0]
        lo, hi = min(vals, key=float), max(vals, key=float)
        return lo if float(lo) == float(hi) else f"{lo} .. {hi}"

    return _NUMBER.sub(one, text)


def group_errors(items: Iterable[tuple[int, str]]) -> list[tuple[list[int], str]]:
    """Messages grouped by their reason: ``items`` are (point number, message); messages
    alike but for their numbers (a memory estimate, the values a point set) are one
    reason.  Returns (its point numbers, the message with each number that differs
    between them as its range) for each reason, in the order of their first point."""
    seen: dict[str, tuple[list[int], list[list[str]], str]] = {}
    for index, text in items:
        text = " ".join(ln.strip() for ln in str(text).splitlines() if ln.strip())
        key, numbers = _skeleton(text)
        idx, nums, _ = seen.setdefault(key, ([], [], text))
        idx.append(index)
        nums.append(numbers)
    return [(idx, _merged(first, nums)) for idx, nums, first in seen.values()]


def failure_lines(records: Iterable[dict], total: int) -> list[str]:
    """One line for each reason the failed ``records`` (``index``, ``error``) of a sweep
    of ``total`` points failed: how many points, which (the first few), and the message,
    a number that differs between them given as its range."""
    groups = group_errors((int(r["index"]), str(r.get("error") or "(no message)"))
                          for r in records)
    lines = [f"  {len(idx)} of {total} points ({_first(idx)}): {text}"
             for idx, text in groups[:SHOW_ERRORS]]
    if len(groups) > SHOW_ERRORS:
        lines.append(f"  ... and {len(groups) - SHOW_ERRORS} more")
    return lines


def _error_lines(text: str) -> list[str]:
    """The separate complaints of one error message (a scene's errors are listed one a
    line under a heading naming the scene file; a check of several keys at once, which
    the scene lists at its top level, names its keys in its own words)."""
    lines = [ln.strip() for ln in str(text).splitlines() if ln.strip()]
    if len(lines) > 1 and lines[0].endswith(":"):
        lines = lines[1:]
    return [re.sub(r"^(invalid scene .*?: )?\(top level\): ", "",
                   re.sub(r"^invalid scene .*?: ", "", ln)) for ln in lines] or [str(text)]


def _split_received(line: str) -> tuple[str, str]:
    """(what the key must be, the value received) of one complaint: the words before its
    last ``; received`` or ``, received``, and what follows (empty where it names no
    value)."""
    m = _RECEIVED.match(line)
    return (m.group(1), m.group(2)) if m else (line, "")


def _first(items: list, n: int = SHOW_VALUES) -> str:
    return ", ".join(str(v) for v in items[:n]) + (", ..." if len(items) > n else "")


def check_sweep_tasks(sweep_path: str | Path, tasks: list, invalid: list) -> None:
    """Refuse a sweep with any point that is not a valid scene (or does not fit the
    memory budget) before anything runs: one message with one line per distinct
    complaint (a key and what it must be), how many different values it received and the
    first few of them, and the points it concerns.  Complaints that name no value
    received and are alike but for their numbers (a memory estimate above the budget) are
    one line, each number that differs given as its range."""
    if not invalid:
        return
    total = len(tasks) + len(invalid)
    # complaint -> (its points, its values received: an ordered set)
    seen: dict[str, tuple[list[int], dict[str, None]]] = {}
    plain: dict[str, list[tuple[int, str]]] = {}  # no value received: by their words alone
    for rec in invalid:
        for line in _error_lines(rec["error"]):
            what, value = _split_received(line)
            if not value:
                key = "\0" + _skeleton(what)[0]
                seen.setdefault(key, ([], {}))[0].append(rec["index"])
                plain.setdefault(key, []).append((rec["index"], what))
                continue
            idx, values = seen.setdefault(what, ([], {}))
            idx.append(rec["index"])
            values.setdefault(value, None)
    shown = []
    for what, (idx, found) in list(seen.items())[:SHOW_ERRORS]:
        if what in plain:
            ((_, what),) = group_errors(plain[what])
        got_values = list(found)
        where = (f"point {idx[0]}" if len(idx) == 1 else f"{len(idx)} points: {_first(idx)}")
        got = ("" if not got_values else f"; received {got_values[0]}" if len(got_values) == 1
               else f"; received {len(got_values):,} values: {_first(got_values)}")
        shown.append(f"  {what}{got} [{where}]")
    if len(seen) > SHOW_ERRORS:
        shown.append(f"  ... and {len(seen) - SHOW_ERRORS} more")
    raise InputError(f"sweep file {str(sweep_path)!r}: {len(invalid)} of {total} points are "
                     f"not valid scenes (point numbers count from 0 in the order of the file); "
                     f"nothing was run:\n" + "\n".join(shown))
