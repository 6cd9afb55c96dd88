"""Machining processes, one module per kind: each plans its machine program, cuts the
surface on the simulation grid and states its facts (plan -> cut -> facts).

Kinds: ``sts`` (slow tool servo turning, seed 000), ``fts`` / ``hts`` (fast and hybrid
tool servo turning, seed 002), ``sculpt`` (vibration-assisted sculpturing, seed 003),
``rcse`` (turning along an RCSE path, seed 004).  Each module registers its ``[process]``
schema class and functions with :func:`register_process`; the modules are found and
imported here, so a new process kind is one new file (docs/contributing.md).
"""

from __future__ import annotations

from ..core.plugins import import_private_modules
from ._rcse import RcseProcessConfig, rcse_comparison
from ._registry import (
    DEFAULT_KIND,
    Cut,
    Plan,
    ProcessKind,
    check_budget,
    process_config_union,
    process_kinds,
    process_of,
    register_process,
)
from ._sculpt import SculptProcessConfig, lattice_lines
from ._servo import ServoProcessConfig
from ._sts import StsProcessConfig
from ._turning import (
    TurningProcessConfig,
    compensation_variants,
    plan_spiral,
    toolpath_facts,
)

# variants added as modules of this package register themselves on import
import_private_modules(__name__, __path__, skip=("_registry", "_turning"))

#: the pydantic type of a scene's [process] section
ProcessConfig = process_config_union()

__all__ = ["Plan", "Cut", "ProcessKind", "register_process", "process_kinds", "process_of",
           "process_config_union", "check_budget", "DEFAULT_KIND", "ProcessConfig",
           "TurningProcessConfig", "StsProcessConfig", "ServoProcessConfig",
           "SculptProcessConfig", "RcseProcessConfig", "rcse_comparison", "lattice_lines",
           "compensation_variants", "toolpath_facts", "plan_spiral"]
