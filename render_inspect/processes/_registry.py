"""The registry of process kinds (``process.kind`` -> its :class:`Process`), of the scene
sections the process modules own (``[machine]``, ``[rcse]``, ``[artifacts.burrs]``, ...)
and of the rewrites that keep retired scene keys working.

A process module registers its process with :func:`register_process`, the sections it
defines with :func:`register_section` and, when it retires a key, a migration with
:func:`register_migration`; the scene schema (:mod:`render_inspect.scene`) is built from
what is registered, so a new process kind and its sections are one new module.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Annotated, Any, Callable, Union

from pydantic import Discriminator, Tag

from ..core.grid import grid_shape
from ..core.limits import Driver, check_memory, memory_budget
from ..core.plugins import Registry, literal_values
from ._contract import Process, SceneSections, SimulationSection

__all__ = ["register_process", "process_kinds", "process_of", "process_config_union",
           "check_budget", "DEFAULT_KIND", "register_section", "scene_sections",
           "register_migration", "migrate_scene", "register_retired_key", "retired_keys"]

#: the kind a scene without ``process.kind`` gets
DEFAULT_KIND = "sts"

_PROCESSES = Registry("process.kind")
_SECTIONS: dict[str, type] = {}
_MIGRATIONS: list[Callable] = []
_RETIRED: dict[str, tuple[str | None, str]] = {}


def register_process(process: Process) -> Process:
    """Register a process kind under the names of its ``config``'s ``kind`` Literal."""
    if not isinstance(process, Process):
        raise TypeError(f"register_process takes a Process instance, received {process!r}")
    return _PROCESSES.add(literal_values(process.config, "kind"), process)


def process_kinds() -> dict[str, Process]:
    """``process.kind`` name -> :class:`Process`."""
    return _PROCESSES.entries()


def process_of(scene: SceneSections) -> Process:
    """The registered process of ``scene``'s ``[process]`` section."""
    return _PROCESSES.lookup(scene.process.kind)


def _discriminate(value):
    kind = value.get("kind", DEFAULT_KIND) if isinstance(value, dict) else getattr(value, "kind", None)
    entry = _PROCESSES.get(kind) if isinstance(kind, str) else None
    return entry.config.__name__ if entry is not None else None


def process_config_union() -> Any:
    """The pydantic type of a ``[process]`` section: the registered schema classes,
    chosen by ``kind`` (``"sts"`` when the key is missing)."""
    return _PROCESSES.union(_union_of)


def _union_of(configs):
    members = tuple(Annotated[c, Tag(c.__name__)] for c in configs)
    return Annotated[Union[members], Discriminator(
        _discriminate, custom_error_type="invalid_kind",
        custom_error_message=f"kind must be one of {sorted(_PROCESSES)}",
        custom_error_context={"discriminator": "kind"})]


def register_section(path: str, config: type) -> type:
    """Register the scene section ``path`` (``"machine"``, or ``"artifacts.burrs"`` inside
    the ``[artifacts]`` table) with its schema class: every scene then has it, with its
    defaults."""
    parts = path.split(".")
    if not 1 <= len(parts) <= 2 or not all(p.isidentifier() for p in parts):
        raise ValueError(f"section path must be 'name' or 'table.name', received {path!r}")
    _SECTIONS[path] = config
    return config


def scene_sections() -> dict[str, type]:
    """Registered section path -> schema class, in registration order."""
    return dict(_SECTIONS)


def register_migration(fn: Callable[[dict], dict]) -> Callable:
    """Register ``fn(scene_dict) -> scene_dict``: run on every scene before validation, it
    rewrites retired keys into their successors (and warns with
    :class:`~render_inspect.core.deprecation.DeprecatedKeyWarning`)."""
    _MIGRATIONS.append(fn)
    return fn


def register_retired_key(old: str, new: str | None, note: str = "") -> None:
    """Record the retired scene key ``old`` and its successor ``new`` (None: none) for the
    key reference (docs/scene_keys.md)."""
    _RETIRED[old] = (new, note)


def retired_keys() -> dict[str, tuple[str | None, str]]:
    """Retired scene key -> (successor or None, note)."""
    return dict(_RETIRED)


def migrate_scene(data: dict) -> dict:
    """``data`` with every registered migration applied."""
    for fn in _MIGRATIONS:
        data = fn(data)
    return data


def check_budget(simulation: SimulationSection, nbytes: float, *, what: str | None = None,
                 drivers: Iterable[Any] | None = None,
                 hint: str | None = None) -> int:
    """Raise :class:`~render_inspect.core.MemoryBudgetError` when ``nbytes`` exceeds the
    memory budget of the ``[simulation]`` section ``simulation``
    (``simulation.max_memory_gb``, or a share of the memory available:
    :func:`~render_inspect.core.limits.memory_budget`); return ``nbytes``.

    By default the message names the simulation grid and ``simulation.pixel`` (memory
    grows as 1 / pixel^2) and says to shrink ``simulation.region``; ``what``,
    ``drivers`` (:class:`~render_inspect.core.limits.Driver`) and ``hint`` override that.
    """
    sim = simulation
    if what is None:
        ny, nx = grid_shape(sim.region, sim.pixel)
        what = f"the simulation ({ny} x {nx} samples)"
    if drivers is None:
        drivers = [Driver("simulation.pixel", sim.pixel, -2, "mm", limit=(1e-6, 10))]
        hint = hint or "or shrink simulation.region"
    return check_memory(nbytes, what=what, budget=memory_budget(sim.max_memory_gb),
                        drivers=drivers, hint=hint)
