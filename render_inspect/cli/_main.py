"""The entry point: the parser of every command group, the run with its signal handlers,
and the one line an error or an interruption ends with (see the package docstring)."""

from __future__ import annotations

from collections.abc import Sequence
import argparse
import atexit
import logging
import os
import signal
import sys
import threading
import time
import traceback
from typing import Any, NoReturn

from .. import __version__, _early_signals
from ..core import cancel
from ..core.cancel import Terminated
from ..core.lazy import freeze_after_pauses, quick_cache_loads
from ..core.errors import RenderInspectError
from ..core.invocation import running_command
from ..core.progress import set_reporter
from . import _analyze, _batch, _fit, _render, _simulate
from ._args import _add_verbosity, log
from ._progress import RichReporter, _reporter, _RichLogHandler
from ._summary import (ROW_SUMMARIES, _print_compare_summary, _print_profile_compare_summary,
                       _print_summary)

#: the command groups, in the order ``render-inspect --help`` lists their commands
GROUPS = (_simulate, _render, _analyze, _fit, _batch)
#: command -> what runs it, ``(args, overwrite) -> result``
COMMANDS = {name: run for group in GROUPS for name, run in group.RUN.items()}
#: commands whose process, run as the program (not :func:`main` called from Python), ends
#: as soon as they are done: their files are complete and closed by then, and the
#: interpreter's own teardown of the libraries a render loads (Mitsuba's and numba's
#: compilers, SciPy, the modules' objects) would add about 0.2 CPU-s of nothing to the
#: command (:func:`_exit_at_once`)
EXIT_AT_ONCE = frozenset(name for group in GROUPS for name in getattr(group, "EXIT_AT_ONCE", ()))


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="render-inspect",
        description="Simulate, render and inspect diamond-machined freeform optics before they are cut.")
    ap.add_argument("--version", action="version", version=f"render-inspect {__version__}")
    _add_verbosity(ap, top=True)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in GROUPS:
        group.add_parsers(sub)
    return ap


def _run(args):
    # the pipeline imports numba, scipy and pydantic: each command imports it when it
    # runs, not at the top of its module, so that `render-inspect --help` answers at once
    run = COMMANDS.get(args.command)
    # (the program's start-up paused the collector: it collects again from here)
    _early_signals.resume_collector()
    if _early_signals.is_program():
        freeze_after_pauses()
        # (the program's own process: numba's cached kernels load without its compiler's
        # set-up, which only a compilation needs)
        quick_cache_loads()
    if run is None:
        return None
    return run(args, bool(getattr(args, "overwrite", False)))


def _exit_at_once(code: int) -> NoReturn:
    """End the process with ``code`` without the interpreter's teardown: what is
    registered to run at exit runs first (logging's flush, a coverage run's data ...),
    the standard streams are flushed, then the process ends."""
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # (a closed or broken stream: nothing to keep)
            pass
    os._exit(code)


def _end_stopped(code: int) -> NoReturn:
    """End the program after a stop, once its line is printed: the threads that are not
    daemons are waited for as at any exit (a worker finishing the file it writes), then
    the process ends with ``code`` without the interpreter's teardown
    (:func:`_exit_at_once`).  The teardown stops the daemon threads still at work (the
    figures' library being imported, matplotlib's font list being built, a progress
    display) where they next take the interpreter's lock, which inside native code (a C++
    extension's set-up, a callback from a C library) may abort (SIGABRT) or crash the
    process instead of letting it end with ``code``.  A further stop meanwhile ends the
    process at once, with the same code."""
    def again(signum: int, frame: Any) -> None:
        os._exit(code)

    for name in ("SIGINT", "SIGTERM", "SIGHUP"):  # (no SIGHUP on Windows)
        sig = getattr(signal, name, None)
        if sig is None:
            continue
        try:
            signal.signal(sig, again)
        except (ValueError, OSError):  # (not the main thread)
            pass
    # (what the interpreter's exit does first: join the threads that are not daemons,
    # after telling idle thread pools to end)
    shutdown = getattr(threading, "_shutdown", None)
    if callable(shutdown):
        shutdown()
    _exit_at_once(code)


def _on_interrupt(signum, frame):
    # Ctrl-C: the main thread stops here, and every long computation running in blocks
    # (kernels, tiles, worker threads) at its next check (core.cancel); inside native code
    # that cannot unwind an exception (importing Mitsuba, loading a scene), at the end of
    # that block (cancel.deferred); inside a library's steps of taking or giving back a
    # lock, which would stay held, at the next check
    cancel.request(signum)
    if not cancel.deferring(frame):
        raise KeyboardInterrupt


def _quiet_unraisable(default: Any) -> Any:
    """``sys.unraisablehook`` that leaves out the interruption our own signal handlers
    raise where Python cannot pass it on (inside a ``__del__``, a weakref callback): the
    request is recorded (core.cancel), so the run still ends as interrupted, in one line;
    anything else goes to ``default``."""
    def hook(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, (KeyboardInterrupt, Terminated)):
            return
        default(unraisable)
    return hook


def _on_terminate(signum, frame):
    cancel.request(signum)
    if not cancel.deferring(frame):
        raise Terminated(signum)


def _interrupt_in(err: BaseException) -> KeyboardInterrupt | None:
    """The interruption behind ``err``: Ctrl-C during a compiled (numba) kernel surfaces
    as a SystemError whose cause or context is the KeyboardInterrupt."""
    seen = set()
    e: BaseException | None = err
    while e is not None and id(e) not in seen:
        if isinstance(e, KeyboardInterrupt):
            return e
        seen.add(id(e))
        e = e.__cause__ or e.__context__
    return None


def _asked_to_stop() -> KeyboardInterrupt | None:
    """The interruption a signal asked for (core.cancel), if one did: native code that
    calls back into Python can turn the exception our handler raised there into one of its
    own and drop it (matplotlib's transforms: "Invalid affine transformation matrix"), so
    an error escaping after a stop was asked for is that stop."""
    try:
        cancel.check()
    except KeyboardInterrupt as stop:
        return stop
    return None


def _traceback_hint(parser) -> str:
    opts = getattr(parser, "_option_string_actions", {})
    if "-v" in opts or "--verbose" in opts:
        return "run with -v for the traceback"
    return "set RENDER_INSPECT_TRACEBACK=1 for the traceback"


def _one_line(text: object) -> str:
    return " ".join(str(text).split()) if "\n" not in str(text) else str(text).rstrip()


def _setup_logging(args) -> None:
    level = logging.INFO
    if getattr(args, "quiet", False):
        level = logging.WARNING
    elif getattr(args, "verbose", 0):
        level = logging.DEBUG
    if not any(isinstance(h, _StderrHandler) for h in log.handlers):
        handler = _StderrHandler()
        handler.setFormatter(logging.Formatter("%(message)s"))
        log.addHandler(handler)
    log.setLevel(level)


class _SaidOnce(logging.Filter):
    """Lets a warning through once per command: the same line said before the run (from
    the scene) and again in its results (a measured tool edge's notes) is shown once."""

    def __init__(self) -> None:
        super().__init__()
        self._said: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno < logging.WARNING:
            return True
        text = record.getMessage()
        if text in self._said:
            return False
        self._said.add(text)
        return True


class _StderrHandler(logging.StreamHandler):
    """Log records on the *current* ``sys.stderr``: a handler holding the stream it was
    made with writes into a closed file once ``sys.stderr`` has been replaced (a second
    ``main()`` in one process under a captured or redirected stderr), which logging
    reports as "--- Logging error ---" instead of the message."""

    def __init__(self):
        super().__init__(sys.stderr)

    @property
    def stream(self):
        return sys.stderr

    @stream.setter
    def stream(self, value):  # StreamHandler.__init__ / setStream set it: always stderr
        pass


def main(argv: Sequence[str] | None = None) -> int:
    """The ``render-inspect`` command: run the command line ``argv`` (default: the
    program's arguments); return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    _setup_logging(args)
    show_tb = bool(getattr(args, "verbose", 0)) or os.environ.get("RENDER_INSPECT_TRACEBACK", "") \
        not in ("", "0")
    old_signals: dict[signal.Signals, Any] = {}
    cancel.clear()
    _early_signals.command(args.command)
    prefix = f"render-inspect {args.command}"
    t0 = time.perf_counter()
    reporter = _reporter(args)
    handlers = list(log.handlers)
    if isinstance(reporter, RichReporter):
        rich_handler = _RichLogHandler(reporter._progress.console)
        rich_handler.setFormatter(logging.Formatter("%(message)s"))
        log.handlers = [rich_handler]
    once = _SaidOnce()
    for h in log.handlers:
        h.addFilter(once)
    t_start = time.monotonic()
    try:
        # the handlers are put in place inside this block, so that a signal arriving
        # right after them is reported like any other
        for sig, handler in ((signal.SIGINT, _on_interrupt), (signal.SIGTERM, _on_terminate),
                             (signal.SIGHUP, _on_terminate)):
            try:
                old_signals[sig] = signal.signal(sig, handler)
            except (ValueError, OSError):  # not the main thread: leave the handlers alone
                pass
        if old_signals:
            old_unraisable = sys.unraisablehook
            sys.unraisablehook = _quiet_unraisable(old_unraisable)
        with reporter as rep:
            old = set_reporter(rep)
            try:
                # the command line as typed, for the reports' provenance
                with running_command(sys.argv[1:] if argv is None else argv):
                    result = _run(args)
                # a signal whose exception was swallowed (raised inside a __del__ or a
                # callback that ignores exceptions) still ends the run as an interruption
                cancel.check()
            except BaseException as err:
                if isinstance(err, (SystemExit, GeneratorExit)):
                    raise
                stop = _interrupt_in(err)
                if stop is None:
                    stop = _asked_to_stop()
                if stop is None:
                    raise
                raise stop from None
            finally:
                set_reporter(old)
                for h in log.handlers:
                    h.removeFilter(once)
                log.handlers = handlers
    except RenderInspectError as err:
        if show_tb:
            traceback.print_exc()
        print(f"{prefix}: error: {_one_line(err)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as stop:
        what = "terminated" if isinstance(stop, Terminated) else "interrupted"
        # the folder an interruption arriving after the swap leaves complete (the
        # exception's attribute, or a folder swapped in since this run started; nothing
        # was written when the pipeline was never imported)
        done = getattr(stop, "render_inspect_output_complete", None)
        if done is None and "render_inspect.pipeline" in sys.modules:
            # (the pipeline is imported lazily, see _run; here only when it was)
            from ..pipeline import completed_outputs

            done = next(iter(completed_outputs(since=t_start)), None)
        if args.command == "sweep":
            state = (f"the finished points are kept in {args.out}/results.jsonl: run the same "
                     f"command again to go on")
        elif done:
            state = f"the output folder {done} had been written completely"
        else:
            state = "the output folder was left as it was"
        kept = getattr(stop, "render_inspect_kept", None)  # (fit: its evaluations)
        if kept:
            state += f"; {kept}"
        print(f"{prefix}: {what}; {state}", file=sys.stderr)
        code = 143 if isinstance(stop, Terminated) else 130
        if argv is None:  # the program: ends here (see _end_stopped)
            _end_stopped(code)
        return code
    except MemoryError:
        if show_tb:
            traceback.print_exc()
        print(f"{prefix}: error: ran out of memory; set simulation.max_memory_gb lower than "
              f"the machine's free memory so that render-inspect refuses such runs at the start, "
              f"or reduce the sizes (simulation.region / simulation.pixel, image resolution)",
              file=sys.stderr)
        return 1
    except OSError as err:
        if show_tb:
            traceback.print_exc()
        where = f": {err.filename}" if getattr(err, "filename", None) else ""
        print(f"{prefix}: error: {err.strerror or err}{where} ({_traceback_hint(parser)})",
              file=sys.stderr)
        return 1
    except Exception as err:  # a bug: one line, the traceback on request
        if show_tb:
            traceback.print_exc()
        print(f"{prefix}: internal error: {type(err).__name__}: {_one_line(err)[:300]} "
              f"({_traceback_hint(parser)})", file=sys.stderr)
        return 1
    finally:
        _early_signals.finished()
        for sig, handler in old_signals.items():
            signal.signal(sig, handler)
        if old_signals:
            sys.unraisablehook = old_unraisable
        cancel.clear()
    dt = time.perf_counter() - t0
    if args.command in ("compare", "demo") and isinstance(result, dict) \
            and not getattr(args, "quiet", False):
        if "variants" in result:
            _print_compare_summary(result, args.out, dt)
        elif result.get("kind") == "profile":  # compare --measured PROFILE
            _print_profile_compare_summary(result, args.out, dt)
    elif args.command in ("measure", "analyze") and isinstance(result, dict) \
            and not getattr(args, "quiet", False):
        _print_summary(args.command, result, args.out, dt)
    elif args.command in ROW_SUMMARIES and not getattr(args, "quiet", False):
        _print_summary(args.command, result if isinstance(result, dict) else {}, args.out, dt)
    log.info("%s: done in %.1f s", prefix, dt)
    if argv is None and args.command in EXIT_AT_ONCE:
        _exit_at_once(0)
    return 0
