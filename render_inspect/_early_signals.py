"""Signals before the command line's own handlers are in place and after they are gone.

The command line (:mod:`render_inspect.cli`) stops cleanly on Ctrl-C, SIGTERM and SIGHUP
while a command runs.  Before that, while Python imports the package and its libraries
(numpy, numba, the command's modules: a second or more), and after it, while the process
exits, Python's own handling applies: a traceback for Ctrl-C, an exit by the signal
without a word for SIGTERM.  :func:`install` replaces it, for the ``render-inspect``
program only (never for a program that imports the package), with a handler that prints
one line (the command, what stopped it, and that nothing was written yet or that the run
had finished) and exits with the documented code: 130 for SIGINT, 143 for SIGTERM and
SIGHUP.

Nothing is written before the command's handlers are in place (output folders are opened
under them), so the process may end at once; stdout is flushed first.

Only the standard library is imported here, so that this module runs first, and as
little of it as can be before :func:`install` (each module loaded before it is a moment
when Ctrl-C would still give a traceback): ``os`` and ``sys``, loaded with the
interpreter, and ``signal``; ``gc`` once the collector is paused, after the handler.
"""

import os
import signal
import sys

__all__ = ["install", "command", "finished", "is_program", "pause_collector", "resume_collector"]

_STATE = {"prefix": "render-inspect", "finished": False}
_SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP")


def _handler(signum: int, frame: object) -> None:
    what = "interrupted" if signum == signal.SIGINT else "terminated"
    if _STATE["finished"]:
        state = "the run had finished (its output, if any, was written completely)"
    else:
        state = "it was starting up: nothing was written"
    try:
        sys.stdout.flush()
    except Exception:  # (a closed or broken stdout: the line below is what matters)
        pass
    try:
        os.write(2, f"{_STATE['prefix']}: {what}; {state}\n".encode("utf-8", "replace"))
    except OSError:
        pass
    os._exit(130 if signum == signal.SIGINT else 143)


def is_program() -> bool:
    """Whether this process is the ``render-inspect`` program (its console script, or
    ``python -m render_inspect.cli``: while Python locates the module, ``sys.argv[0]`` is
    ``-m``, and then the path of its ``__main__.py``), not a program that imports the
    package."""
    if _multiprocessing_child():
        return False
    first = sys.argv[0] if sys.argv else ""
    if first == "-m":
        # (``python -m render_inspect.cli``, not another module of the package run so)
        orig = list(getattr(sys, "orig_argv", ()))
        if "-m" in orig and orig.index("-m") + 1 < len(orig):
            return orig[orig.index("-m") + 1] in ("render_inspect.cli", "render_inspect.cli.__main__")
        return True
    if os.path.basename(first) == "render-inspect":
        return True
    # (``python -m render_inspect.cli`` once it runs: ``sys.argv[0]`` is then the path of
    # the command line's ``__main__.py``)
    return bool(first) and os.path.realpath(first) == _CLI_MAIN


def _multiprocessing_child() -> bool:
    """Whether this process is a worker that ``multiprocessing`` started by spawning a new
    interpreter or from its fork server (a Dask worker of ``--workers N``): it is handed
    the program's ``sys.argv`` but is not the program."""
    orig = list(getattr(sys, "orig_argv", ()))
    if "--multiprocessing-fork" in orig:
        return True
    return "-c" in orig and orig.index("-c") + 1 < len(orig) \
        and "multiprocessing" in orig[orig.index("-c") + 1]


#: the command line's ``__main__.py`` (``python -m render_inspect.cli`` runs it)
_CLI_MAIN = os.path.realpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "cli",
                                          "__main__.py"))


def pause_collector() -> None:
    """Pause Python's cyclic garbage collector while the program starts (its imports,
    for the program only): they make some hundred thousand objects that live as long as
    the process and almost no garbage (a few hundred objects), and the collector's passes
    over them, young and full, cost tenths of a CPU-second for nothing.
    :func:`resume_collector` turns it back on; a collector that was off is left so."""
    import gc

    if gc.isenabled() and not _STATE.get("collector_paused"):
        gc.disable()
        _STATE["collector_paused"] = True


def resume_collector() -> None:
    """Turn the collector back on if :func:`pause_collector` paused it, the objects made so
    far left out of its passes (``gc.freeze``)."""
    import gc

    if _STATE.get("collector_paused"):
        _STATE["collector_paused"] = False
        gc.freeze()
        gc.enable()


def _command_word() -> str | None:
    # the command named on the command line, before the parser has read it: the first
    # word that is not an option (``render-inspect -v simulate ...``)
    for word in sys.argv[1:]:
        if not word.startswith("-"):
            return word if word.isidentifier() else None
    return None


def install() -> None:
    """Put the one-line handler in place for SIGINT, SIGTERM and SIGHUP (main thread only)."""
    word = _command_word()
    if word and not _STATE["finished"]:
        _STATE["prefix"] = f"render-inspect {word}"
    for name in _SIGNALS:
        try:
            signal.signal(getattr(signal, name), _handler)
        except (ValueError, OSError, AttributeError):  # not the main thread; no such signal
            pass


def command(name: str) -> None:
    """The command being run, for the message (``render-inspect simulate``)."""
    _STATE["prefix"] = f"render-inspect {name}"
    _STATE["finished"] = False


def finished() -> None:
    """The command has returned: a signal now says that the run had finished."""
    _STATE["finished"] = True
