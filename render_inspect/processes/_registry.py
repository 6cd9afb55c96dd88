"""The registry of process kinds: ``process.kind`` -> how that process plans its program
and cuts the surface.

A process kind is one module of this package: its ``[process]`` schema class (a
:class:`~render_inspect.core.Section` whose ``kind`` field is a ``Literal`` of names) and
three functions, registered with :func:`register_process`:

``plan(scene, surface, *, region) -> Plan``
    The machine program (a :class:`~render_inspect.core.ToolPath` or
    :class:`~render_inspect.core.LinearProgram`) and its facts.  ``region`` (mm) limits
    the program to what can reach that window; None plans the whole part.
``cut(scene, surface, plan) -> Cut``
    The machined and design heights on the scene's simulation grid, and the facts of the
    cut (servo, burrs, vibration, ...).
``estimate_memory(scene, plan=None) -> int``
    Bytes a simulation of the scene holds at its peak (before planning, and again with the
    plan's real size).

Optional: ``program_region(scene)`` (the region the ``toolpath`` command plans; None = the
whole part), ``program_header(scene)`` (NC header lines), ``variants(scene)`` (the pair
``compare`` puts side by side: a :class:`VariantPair`, the comparison that means something
for this process, e.g. compensation on/off for turning, vibration on/off for sculpturing),
``precheck(scene, region)`` (checks the sizes the process's own keys drive, such as the
points of the program, against the memory budget before anything is planned, and names
those keys when they do not fit),
``envelope_path(scene, surface, plan) -> (ToolPath, meta)`` (turning processes whose
machined surface is the nose envelope of one path and nothing else: the tiled,
out-of-core simulation computes it tile by tile).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Callable, Union

import numpy as np
from pydantic import Discriminator, Tag

from ..core.errors import SceneError
from ..core.grid import grid_shape
from ..core.limits import Driver, check_memory, memory_budget
from ..core.plugins import literal_values

__all__ = ["Plan", "Cut", "ProcessKind", "register_process", "process_kinds", "process_of",
           "process_config_union", "check_budget", "DEFAULT_KIND", "Variant", "VariantPair"]

#: the kind a scene without ``process.kind`` gets
DEFAULT_KIND = "sts"


@dataclass
class Plan:
    """What a process plans before cutting.

    Attributes
    ----------
    program : ToolPath or LinearProgram
        The commanded machine program.
    facts : dict
        metrics.json entries (``toolpath`` facts, ...).
    timing : dict
        Seconds per step.
    data : dict
        Values the cut needs that are not part of the program (process-private).
    """

    program: object
    facts: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict)


@dataclass
class Cut:
    """The machined surface a process cuts on the simulation grid.

    Attributes
    ----------
    machined, design : (ny, nx) float64, mm
    facts : dict
        metrics.json entries of the cut (``servo``, ``burrs``, ``vibration``, ...).
    timing : dict
        Seconds per step.
    meta : dict
        Provenance stored with the height map.
    followed : ToolPath, optional
        The path the tool really followed (servo dynamics), when it differs from the plan.
    plots : dict
        Extra figures: file name -> callable(png_path).
    """

    machined: np.ndarray
    design: np.ndarray
    facts: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    followed: object = None
    plots: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Variant:
    """One column of ``compare``: the scene with some keys set to other values.

    Attributes
    ----------
    name : str
        Folder and ``metrics.json`` key of the variant (``"compensated"``,
        ``"vibration_off"``, ...): letters, digits, ``_``, ``-`` and ``.``.
    label : str
        What the variant is, for people ("Z compensation", "no vibration").
    values : dict
        Dotted scene key -> value (Python; ``None`` allowed) applied to the scene;
        empty means the scene as given.
    """

    name: str
    label: str
    values: dict = field(default_factory=dict)


@dataclass(frozen=True)
class VariantPair:
    """The two variants ``compare`` puts side by side, and why.

    Attributes
    ----------
    a, b : Variant
        Left and right column; the report shows ``a - b``.
    key : str
        The scene key (or keys, comma separated) that differ between them.
    about : str
        One sentence for the report: what the difference shows.
    """

    a: Variant
    b: Variant
    key: str
    about: str = ""

    @property
    def variants(self) -> tuple[Variant, Variant]:
        return (self.a, self.b)


def _whole_part(scene):
    return None


@dataclass(frozen=True)
class ProcessKind:
    """One registered process: its ``kind`` names, schema class and functions."""

    names: tuple[str, ...]
    config: type
    plan: Callable
    cut: Callable
    estimate_memory: Callable
    program_region: Callable = _whole_part
    program_header: Callable = lambda scene: {}
    variants: Callable | None = None
    precheck: Callable = lambda scene, region=None: None
    envelope_path: Callable | None = None


_PROCESSES: dict[str, ProcessKind] = {}
_UNION = None


def register_process(config, *, plan: Callable, cut: Callable, estimate_memory: Callable,
                     program_region: Callable | None = None,
                     program_header: Callable | None = None,
                     variants: Callable | None = None,
                     precheck: Callable | None = None,
                     envelope_path: Callable | None = None) -> ProcessKind:
    """Register a process kind (see the module docstring)."""
    kwargs = {}
    if precheck is not None:
        kwargs["precheck"] = precheck
    if program_region is not None:
        kwargs["program_region"] = program_region
    if program_header is not None:
        kwargs["program_header"] = program_header
    entry = ProcessKind(literal_values(config, "kind"), config, plan, cut, estimate_memory,
                        variants=variants, envelope_path=envelope_path, **kwargs)
    for name in entry.names:
        _PROCESSES[name] = entry
    global _UNION
    _UNION = None
    return entry


def process_kinds() -> dict[str, ProcessKind]:
    """``process.kind`` name -> :class:`ProcessKind`."""
    return dict(_PROCESSES)


def process_of(scene) -> ProcessKind:
    """The registered process of ``scene.process.kind``."""
    kind = scene.process.kind
    entry = _PROCESSES.get(kind)
    if entry is None:
        raise SceneError(f"process.kind must be one of {sorted(_PROCESSES)}, received {kind!r}")
    return entry


def _discriminate(value):
    kind = value.get("kind", DEFAULT_KIND) if isinstance(value, dict) else getattr(value, "kind", None)
    entry = _PROCESSES.get(kind) if isinstance(kind, str) else None
    return entry.config.__name__ if entry is not None else None


def process_config_union():
    """The pydantic type of a ``[process]`` section: the registered schema classes,
    chosen by ``kind`` (``"sts"`` when the key is missing)."""
    global _UNION
    if _UNION is None:
        configs = []
        for entry in _PROCESSES.values():
            if entry.config not in configs:
                configs.append(entry.config)
        members = tuple(Annotated[c, Tag(c.__name__)] for c in configs)
        _UNION = Annotated[Union[members], Discriminator(
            _discriminate, custom_error_type="invalid_kind",
            custom_error_message=f"kind must be one of {sorted(_PROCESSES)}",
            custom_error_context={"discriminator": "kind"})]
    return _UNION


def check_budget(scene, nbytes, *, what: str | None = None, drivers=None,
                 hint: str | None = None) -> int:
    """Raise :class:`~render_inspect.core.MemoryBudgetError` when ``nbytes`` exceeds the
    scene's memory budget (``simulation.max_memory_gb``, or a share of the memory
    available: :func:`~render_inspect.core.limits.memory_budget`); return ``nbytes``.

    By default the message names the simulation grid and ``simulation.pixel`` (memory
    grows as 1 / pixel^2) and says to shrink ``simulation.region``; ``what``,
    ``drivers`` (:class:`~render_inspect.core.limits.Driver`) and ``hint`` override that.
    """
    sim = scene.simulation
    if what is None:
        ny, nx = grid_shape(sim.region, sim.pixel)
        what = f"the simulation ({ny} x {nx} samples)"
    if drivers is None:
        drivers = [Driver("simulation.pixel", sim.pixel, -2, "mm", limit=(1e-6, 10))]
        hint = hint or "or shrink simulation.region"
    return check_memory(nbytes, what=what, budget=memory_budget(sim.max_memory_gb),
                        drivers=drivers, hint=hint)
