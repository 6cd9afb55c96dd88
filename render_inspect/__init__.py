"""render_inspect: see a diamond-machined freeform optic before it is cut.

Pipeline (one direction): scene -> design -> toolpath -> machining -> mesh ->
render -> metrology -> report.  Lengths are millimetres everywhere.
"""

# the command line answers Ctrl-C with one line from its very start (before it imports
# anything else); a program that imports the package keeps Python's own handling
from . import _early_signals

if _early_signals.is_program():
    _early_signals.install()
    # (the process's own settings, before numpy loads: see _process_settings)
    from . import _process_settings

    _process_settings.apply()
    # (the program's imports, until its command runs: see _early_signals.pause_collector)
    _early_signals.pause_collector()

__version__ = "0.1.0"
__all__ = ["__version__"]
