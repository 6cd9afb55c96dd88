"""The command line a run came from, for its provenance.

The ``render-inspect`` program sets it (:func:`running_command`) for the length of one
command, as the user typed it: the program's name, then its arguments with every path as
given (relative paths are relative to the working directory, recorded beside it).  A
report records it (``metrics.json`` ``inputs.command``, the report's provenance table) so
that the run can be repeated as it was made.  A function of the package called from
Python (the API) runs with none set (:func:`command_line` returns None), and its
reports say that the run did not come from the command line.

The setting is a context variable: it belongs to the command running in this thread and
is undone when the command ends, so a script that calls :func:`render_inspect.cli.main`
and then the API does not carry one command's line into another run.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["running_command", "command_line", "working_directory", "PROGRAM"]

#: the program's name, first word of every recorded command line
PROGRAM = "render-inspect"

#: (argv, working directory) of the command now running, None outside one
_COMMAND: ContextVar[tuple[tuple[str, ...], str] | None] = ContextVar(
    "render_inspect_command_line", default=None)


@contextmanager
def running_command(args: Sequence[str]) -> Iterator[None]:
    """Within this block, :func:`command_line` is ``[PROGRAM, *args]`` (``args``: the
    command's arguments as typed, without the program's name) and
    :func:`working_directory` the directory the command runs in."""
    try:
        cwd = os.getcwd()
    except OSError:  # the directory was removed since the program started
        cwd = ""
    token = _COMMAND.set(((PROGRAM, *(str(a) for a in args)), cwd))
    try:
        yield
    finally:
        _COMMAND.reset(token)


def command_line() -> list[str] | None:
    """The command line of the ``render-inspect`` command now running (program name first,
    paths as given), or None when the run was called from Python."""
    now = _COMMAND.get()
    return None if now is None else list(now[0])


def working_directory() -> str | None:
    """The directory the ``render-inspect`` command now running was started in (what its
    relative paths are relative to), or None when the run was called from Python."""
    now = _COMMAND.get()
    return None if now is None else now[1]
