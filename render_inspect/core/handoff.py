"""Figures handed over as soon as they are made.

A caller that draws figures beside the computation (the command line's figure process)
receives them with :func:`receiving`; a step deep in a process that has a figure ready
long before the step ends (the following error, known once the machine has followed the
program, while the part is still to be cut) hands it over with :func:`hand_over`, so
that it is drawn while the rest is computed.  The step keeps the figure among its own
plots too: a caller that receives nothing draws them all at the end, and one that does
draws each once (by its file name).

>>> got = []
>>> with receiving(got.append):
...     hand_over({"a.png": {"kind": "x"}})
>>> got
[{'a.png': {'kind': 'x'}}]
>>> hand_over({"b.png": {}})  # no receiver: nothing happens
"""

from __future__ import annotations

from typing import Any
from collections.abc import Callable, Iterator
import contextlib
import contextvars

__all__ = ["receiving", "hand_over"]

_RECEIVER: contextvars.ContextVar[Callable[[dict[str, Any]], None] | None] = \
    contextvars.ContextVar("render_inspect_figure_receiver", default=None)


@contextlib.contextmanager
def receiving(receiver: Callable[[dict[str, Any]], None] | None) -> Iterator[None]:
    """Within the block, figures handed over in this thread are passed to ``receiver``
    (file name -> figure spec); None receives nothing."""
    token = _RECEIVER.set(receiver)
    try:
        yield
    finally:
        _RECEIVER.reset(token)


def hand_over(plots: dict[str, Any]) -> None:
    """Pass ``plots`` (file name -> figure spec) to the receiver of :func:`receiving`, if
    any."""
    receiver = _RECEIVER.get()
    if receiver is not None and plots:
        receiver(dict(plots))
