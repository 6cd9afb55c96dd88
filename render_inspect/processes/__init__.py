"""Machining processes, one module per kind: each plans its machine program, cuts the
surface on the simulation grid and states its facts (plan -> cut -> facts), through the
typed contract of :class:`Process` (docs/contributing.md).

Kinds: ``sts`` (slow tool servo turning, Li et al. 2018), ``fts`` / ``hts`` (fast and
hybrid tool servo turning, Kong et al. 2020), ``sculpt`` (vibration-assisted
sculpturing, Zhang et al., Applied Sciences), ``rcse`` (turning along an RCSE path, the
RCSE study, Optica 2024).  Each module registers its process with
:func:`register_process` and the scene sections it defines with
:func:`register_section`; the modules are found and imported here, so a new process kind
is one new file.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Union

from ..core.plugins import import_private_modules
from ._contract import (Cut, Envelope, Inputs, Plan, Process, SceneSections, SimulationSection, ToolSection, Traits,
                        Variant, VariantPair, section)
from ._machine import MachineConfig, MaterialConfig, ProcessScene, machine_of, material_of
from ._mechanics import BurrConfig, TurningInputs, map_figure_stride, turn
from ._rcse import RcseConfig, RcseProcessConfig, rcse_comparison
from ._registry import (
    DEFAULT_KIND,
    check_budget,
    migrate_scene,
    process_config_union,
    process_kinds,
    process_of,
    register_migration,
    register_process,
    register_retired_key,
    register_section,
    retired_keys,
    scene_sections,
)
from ._sculpt import SculptProcessConfig, VibrationConfig, lattice_lines
from ._settings import (RANDOM_PART_KEYS, machine_settings, material_settings, preset_settings,
                        random_parts)
from ._servo import ServoProcessConfig
from ._spindle import MirroredSurface, mirrored_region
from ._program import (cut_name, feed_over_radii, feed_per_rev, feed_per_rev_table, findings_summary, fit_paraboloid,
                       program_checks)
from ._sts import StsProcessConfig
from ._turning import (
    TiledTurningProcess,
    TurningProcess,
    TurningProcessConfig,
    compensation_variants,
    plan_spiral,
    toolpath_facts,
)

# process kinds added as modules of this package register themselves on import
import_private_modules(__name__, __path__,
                       skip=("_contract", "_registry", "_turning", "_mechanics", "_machine"))

#: the schema classes of the process kinds, as a type checker knows a ``[process]`` section
#: (the registry's, listed: a process kind added to the registry is added here too)
ProcessSection = Union[StsProcessConfig, ServoProcessConfig, SculptProcessConfig, RcseProcessConfig]

if TYPE_CHECKING:
    ProcessConfig = ProcessSection
else:
    #: the pydantic type of a scene's [process] section
    ProcessConfig = process_config_union()

__all__ = ["Process", "Inputs", "Plan", "Cut", "Traits", "Envelope", "Variant", "VariantPair",
           "section", "ToolSection", "SimulationSection", "SceneSections", "ProcessScene", "register_process", "process_kinds", "process_of", "process_config_union",
           "check_budget", "DEFAULT_KIND", "ProcessConfig", "ProcessSection", "register_section", "scene_sections",
           "register_migration", "migrate_scene", "register_retired_key", "retired_keys",
           "TurningProcessConfig", "TurningProcess",
           "TiledTurningProcess", "TurningInputs", "StsProcessConfig", "ServoProcessConfig",
           "SculptProcessConfig", "RcseProcessConfig", "RcseConfig", "MachineConfig",
           "MaterialConfig", "BurrConfig", "VibrationConfig", "machine_of", "material_of",
           "turn", "map_figure_stride", "rcse_comparison", "lattice_lines", "compensation_variants",
           "toolpath_facts", "plan_spiral", "machine_settings", "material_settings",
           "preset_settings", "random_parts", "RANDOM_PART_KEYS", "fit_paraboloid",
           "program_checks", "feed_over_radii", "feed_per_rev", "feed_per_rev_table", "findings_summary",
           "cut_name", "MirroredSurface", "mirrored_region"]
