"""What a type checker knows of a scene.

The schema is assembled from the registries when the package is imported (the design
types, the process kinds, the instruments, the sections the process modules register),
which a static type checker cannot follow.  The classes here state the same sections
statically; :class:`~render_inspect.scene.Scene` is, to a type checker, the schema with
these sections, so ``scene.machine.spindle_rpm`` is checked and ``scene.tool.nose_radiuss``
is an error.  At run time nothing here takes part in validation: a scene is the model the
registries assembled.  The test suite checks that these lists and the registries agree,
key for key and type for type.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..core.section import Section
from ..design import DesignSection
from ..instruments import InterferometerConfig
from ..processes import (BurrConfig, MachineConfig, MaterialConfig, ProcessSection, RcseConfig,
                         SimulationSection, ToolSection, VibrationConfig)
from ..render import DiffuseConfig
from ._sections import SimulationConfig, ToolConfig

__all__ = ["DesignSection", "ProcessSection", "RenderSections", "ArtifactsSections",
           "RegisteredSections"]


class RenderSections:
    """The sections of ``[render]``: one per registered instrument, and ``diffuse``."""

    interferometer: InterferometerConfig
    diffuse: DiffuseConfig


class ArtifactsSections:
    """The sections of the ``[artifacts]`` table (registered by the process modules)."""

    burrs: BurrConfig
    vibration: VibrationConfig


if TYPE_CHECKING:
    # what a type checker sees of the sections the schema assembles from the registries
    class RenderConfig(Section, RenderSections):
        """``[render]``: virtual instruments and diffuse-light images."""

    class ArtifactsConfig(Section, ArtifactsSections):
        """``[artifacts]``: process errors added to the ideal cut."""


    def _process_inputs_conform(tool: ToolConfig, simulation: SimulationConfig
                                ) -> tuple[ToolSection, SimulationSection]:
        """(checked, never run) the scene's [tool] and [simulation] are what a process's
        inputs declare (:class:`~render_inspect.processes.Inputs`)."""
        return tool, simulation


class RegisteredSections:
    """The scene's top-level sections registered by the process modules (besides
    ``name``, ``description``, ``design``, ``tool``, ``process``, ``simulation``,
    ``render`` and ``metrology``, which the schema declares itself)."""

    artifacts: ArtifactsConfig
    machine: MachineConfig
    material: MaterialConfig
    rcse: RcseConfig
