"""render_inspect: see a diamond-machined freeform optic before it is cut.

Pipeline (one direction): scene -> design -> toolpath -> machining -> mesh ->
render -> metrology -> report.  Lengths are millimetres everywhere.
"""

__version__ = "0.1.0"
__all__ = ["__version__"]
