"""A sweep refused before anything runs: the points that are not valid scenes (or do not
fit the memory budget), their complaints gathered into one message, one line per key and
what it must be, however many points of a large grid break it."""

from __future__ import annotations

import re
from pathlib import Path

from ..core.errors import InputError

__all__ = ["check_sweep_tasks", "SHOW_ERRORS", "SHOW_VALUES"]

#: distinct errors a refused sweep lists
SHOW_ERRORS = 8
#: values received (and point numbers) a refused sweep shows of each error
SHOW_VALUES = 5
#: where an error's words end and the value received begins (the last such place)
_RECEIVED = re.compile(r"^(.*)[;,] received (.*)$", re.S)


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
    first few of them, and the points it concerns."""
    if not invalid:
        return
    total = len(tasks) + len(invalid)
    # complaint -> (its points, its values received: an ordered set)
    seen: dict[str, tuple[list[int], dict[str, None]]] = {}
    for rec in invalid:
        for line in _error_lines(rec["error"]):
            what, value = _split_received(line)
            idx, values = seen.setdefault(what, ([], {}))
            idx.append(rec["index"])
            if value:
                values.setdefault(value, None)
    shown = []
    for what, (idx, found) in list(seen.items())[:SHOW_ERRORS]:
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
