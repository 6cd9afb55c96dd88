"""``render-inspect`` command line: argparse -> :mod:`render_inspect.pipeline`.

Exit codes: 0 done, 1 an error in the input or the run (one line on stderr naming the
parameter, the allowed range and the value received; anything unexpected is reported
the same way, with a hint how to see the traceback), 2 a usage error (argparse),
130 interrupted (Ctrl-C), 143 terminated (SIGTERM).  After an error or an interruption
the output folder is as it was before the run.  Long steps run in blocks and stop
within about a block (a fraction of a second to a second or two) of the signal
(:mod:`render_inspect.core.cancel`).

Output: progress bars with an ETA on stderr for every step that runs longer than a
second (rich; plain log lines when stderr is not a terminal), messages through the
``render_inspect`` logger (``-v``: more, ``-q``: warnings and errors only), and for
``compare`` and ``demo`` a one-screen summary on stdout with the headline numbers and
the path of ``report.html``.

Each command group is a module of this package, with its parsers (``add_parsers``) and
what runs each of its commands (``RUN``): ``_simulate`` (simulate, toolpath), ``_render``
(render, compare), ``_analyze`` (analyze, measure, characterise), ``_fit`` (fit) and
``_batch`` (sweep, regress, demo).  ``_args`` holds the options they share, ``_progress``
the progress display, ``_summary`` the summaries on stdout and ``_main`` the entry point.
"""

from __future__ import annotations

from ._args import (
    _add_out_args,
    _add_scene_args,
    _add_verbosity,
    _program_formats,
    _Registered,
    _render_kinds,
    log,
    scene_of,
)
from ._main import (
    COMMANDS,
    GROUPS,
    _interrupt_in,
    _on_interrupt,
    _on_terminate,
    _one_line,
    _run,
    _setup_logging,
    _StderrHandler,
    _traceback_hint,
    build_parser,
    main,
)
from ._progress import (
    SHOW_AFTER_S,
    LogReporter,
    RichReporter,
    _NullContext,
    _reporter,
    _RichLogHandler,
    timed_fill,
)
from ._summary import _print_compare_summary, _print_summary

__all__ = ["main", "build_parser", "RichReporter", "LogReporter", "timed_fill", "SHOW_AFTER_S",
           "log"]
