"""Virtual instruments that look at a height map the way a metrologist's instruments do:
the interference microscope (Mirau / Michelson / Linnik, Koehler illumination).  Mitsuba
(:mod:`render_inspect.render`) traces the geometry; the imaging model here, in plain
numpy/scipy, takes the heights and normals of the surface at ``s x s`` sub-samples per
camera pixel through the 3-D linear (Kirchhoff) transfer function of the objective, the
source spectrum and the camera, and returns phase-shifting (PSI) or coherence-scanning
(CSI) frames: images plus the instrument's settings, no truth (docs/instrument.md).

Each instrument is one module of this package with its ``[render.<name>]`` schema class
and the hooks the pipeline images with, registered with :func:`register_instrument`; the
modules are found and imported here (docs/contributing.md).  The instrument's own
metrological characteristics (transfer function, step response, slope limit, noise) come
from :func:`characterise_instrument`."""

from __future__ import annotations

from ..core.frames import PHASE_CONVENTION, Frames
from ..core.plugins import import_private_modules
from . import _artefacts as artefacts  # calibration surfaces
from ._camera import Camera, expose
from ._focus import autofocus
from ._imaging import interference_intensity, normals_from_heights
from ._modes import csi_frames, psi_frames
from ._interferometer import (
    MAX_AUTO_SUBSAMPLES,
    Interferogram,
    InterferometerConfig,
    disturbances_from_config,
    interferometer_geometry,
    microscope_from_config,
    read_interferogram_exr,
    render_interferogram,
    trace_heights,
    write_interferogram_exr,
)
from ._interferometer_memory import interferometer_memory
from ._characterise import characterise_instrument
from ._interferometer_outputs import (interferogram_summary, interferometer_field,
                                      interferometer_needs, rendered_settings,
                                      write_interferogram_outputs)
from ._microscope import Disturbances, Microscope, recommended_subsamples
from ._objectives import OBJECTIVES, Objective, objective, objective_names, register_objective
from ._registry import (InstrumentType, height_instrument, instrument_types, register_instrument,
                        renderable_instruments)
from ._sources import Source, led, monochromatic, spectrum_table
from ._transfer import (
    TransferFunction,
    acceptance_table,
    axial_step,
    flat_moments,
    linear_itf,
    transfer_function,
    unit_transfer_table,
)

# instruments added as modules of this package register themselves on import
import_private_modules(__name__, __path__, skip=("_registry",))

__all__ = [
    "MAX_AUTO_SUBSAMPLES",
    "OBJECTIVES",
    "PHASE_CONVENTION",
    "Camera",
    "Disturbances",
    "Frames",
    "InstrumentType",
    "Interferogram",
    "InterferometerConfig",
    "Microscope",
    "Objective",
    "Source",
    "TransferFunction",
    "acceptance_table",
    "artefacts",
    "autofocus",
    "axial_step",
    "csi_frames",
    "disturbances_from_config",
    "expose",
    "flat_moments",
    "instrument_types",
    "interference_intensity",
    "interferometer_geometry",
    "interferometer_memory",
    "led",
    "linear_itf",
    "microscope_from_config",
    "monochromatic",
    "normals_from_heights",
    "objective",
    "objective_names",
    "psi_frames",
    "read_interferogram_exr",
    "recommended_subsamples",
    "register_instrument",
    "register_objective",
    "render_interferogram",
    "spectrum_table",
    "trace_heights",
    "transfer_function",
    "unit_transfer_table",
    "write_interferogram_exr",
    "characterise_instrument",
    "height_instrument",
    "renderable_instruments",
    "interferogram_summary",
    "interferometer_field",
    "interferometer_needs",
    "write_interferogram_outputs",
    "rendered_settings",
]
