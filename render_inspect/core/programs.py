"""Where the processes find the reader of machine program files (``[process] program``).

The reader lives with the other file formats (:func:`render_inspect.io.read_program`),
which registers it here when :mod:`render_inspect.io` is imported; the processes, which
do not reach into the file layer, call :func:`read_program_file`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable

from .errors import InputError

__all__ = ["register_program_reader", "read_program_file"]

_READER: list = []


def register_program_reader(fn: Callable) -> Callable:
    """Register ``fn(path, **options) -> ImportedProgram`` as the program reader."""
    _READER[:] = [fn]
    return fn


def read_program_file(path: str | Path, **options: Any) -> Any:
    """The machine program ``path`` read by the registered reader (see the module
    docstring)."""
    if not _READER:
        raise InputError("process.program: no program reader is registered (import "
                         "render_inspect.io)")
    return _READER[0](path, **options)
