"""Virtual instruments that look at a height map the way a metrologist's instruments do:
the interference microscope (geometry ray-traced by :mod:`render_inspect.render`, the
interference model here).  Each instrument is one module of this package with its
``[render.<name>]`` schema class, registered with :func:`register_instrument`; the
modules are found and imported here (docs/contributing.md)."""

from __future__ import annotations

import importlib
import pkgutil

from ._interferometer import (
    OBJECTIVES,
    Interferogram,
    InterferometerConfig,
    camera_noise,
    interference_frames,
    interferometer_geometry,
    read_interferogram_exr,
    render_interferogram,
    trace_heights,
    write_interferogram_exr,
)
from ._registry import InstrumentType, instrument_types, register_instrument

for _m in sorted(m.name for m in pkgutil.iter_modules(__path__)):
    if _m.startswith("_") and _m != "_registry":
        importlib.import_module(f"{__name__}.{_m}")

__all__ = ["OBJECTIVES", "Interferogram", "InterferometerConfig", "camera_noise",
           "interference_frames", "interferometer_geometry", "read_interferogram_exr",
           "render_interferogram", "trace_heights", "write_interferogram_exr",
           "InstrumentType", "instrument_types", "register_instrument"]
