"""Virtual instruments that look at a height map the way a metrologist's instruments do:
the interference microscope (geometry ray-traced by :mod:`render_inspect.render`, the
interference model here).  Each instrument is one module of this package with its
``[render.<name>]`` schema class, registered with :func:`register_instrument`; the
modules are found and imported here (docs/contributing.md)."""

from __future__ import annotations

from ..core.plugins import import_private_modules
from ._interferometer import (
    OBJECTIVES,
    Interferogram,
    InterferometerConfig,
    camera_noise,
    interference_frames,
    interferometer_geometry,
    interferometer_memory,
    read_interferogram_exr,
    render_interferogram,
    trace_heights,
    write_interferogram_exr,
)
from ._registry import InstrumentType, instrument_types, register_instrument

# instruments added as modules of this package register themselves on import
import_private_modules(__name__, __path__, skip=("_registry",))

__all__ = ["OBJECTIVES", "Interferogram", "InterferometerConfig", "camera_noise",
           "interference_frames", "interferometer_geometry", "interferometer_memory",
           "read_interferogram_exr",
           "render_interferogram", "trace_heights", "write_interferogram_exr",
           "InstrumentType", "instrument_types", "register_instrument"]
