"""The contract of a process kind: the typed hooks the pipeline calls, and the data that
flows through them.

A process kind is a subclass of :class:`Process` in one module of this package.  It
declares

* ``config``: its ``[process]`` schema class (a :class:`~render_inspect.core.section.Section`
  whose ``kind`` field is a ``Literal`` of the names it answers to);
* ``inputs``: an :class:`Inputs` dataclass whose fields are the scene sections its hooks
  read (``process``, ``tool`` and ``simulation`` always; a turning process adds
  ``machine``, ``material`` and ``burrs``, a sculpturing process ``vibration`` and
  ``design``), each field typed with the section's schema class (or, for ``[tool]``
  and ``[simulation]``, whose classes belong to the scene, the :class:`ToolSection`
  and :class:`SimulationSection` protocols they satisfy).  The pipeline fills it from
  the scene (:meth:`Process.inputs_of`); the hooks see nothing else of the scene.
  :class:`Process` is generic in it (``class SculptProcess(Process[SculptInputs])``), so
  the hooks' ``cfg`` is typed as the kind's own inputs;

and implements the hooks

``plan(cfg, surface, *, region) -> Plan``
    The machine program and its facts.  ``region`` (mm) limits the program to what can
    reach that window; None plans the whole part.
``cut(cfg, surface, plan) -> Cut``
    The machined and design heights on the simulation grid, and the facts of the cut.
``estimate_memory(cfg, plan=None) -> int``
    Bytes a simulation holds at its peak (before planning, and again with the plan).
``traits(cfg) -> Traits``
    What the pipeline, the metrology and the reports need to know of the process (its
    tool marks, the part's outline, the compensation it applies, ...), so that nothing
    downstream asks which kind it is.

The optional hooks have defaults: ``precheck``, ``program_region``, ``program_header``,
``program_facts``, ``variants`` (the pair ``compare`` puts side by side), the tiled
simulation's ``tile_refusal`` / ``envelope`` / ``tiled_memory`` / ``tiled_facts``, and what the written
program is checked against: ``program_part`` (the part: design heights, outline, stock),
``program_limits`` (the machine's feeds, velocities and travel), ``program_links``
(the clearance plane and plunge feed of the moves between cuts, from the scene's
``process.clearance`` and ``process.plunge_feed_mm_per_min``) and ``program_plan`` (the plan
of a program read back from its file, to simulate it again).
"""

from __future__ import annotations

from collections.abc import Sequence
import dataclasses
from abc import ABC, abstractmethod
from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING, Any, ClassVar, Generic, Protocol, TypeVar, cast

import numpy as np

from ..core.errors import InputError
from ..core.marks import ToolMarks
from ..core.section import Region
from ..core.toolpath import LinearProgram, Links, ToolPath
from ..toolpath import DEFAULT_CLEARANCE, DEFAULT_PLUNGE_FEED, MachineLimits, PartModel, plan_links

if TYPE_CHECKING:
    from ..design import DesignSection, Surface
    from ..machining import Grooves, MaterialResponse

__all__ = ["Process", "Inputs", "Plan", "Cut", "Traits", "Envelope", "Variant", "VariantPair",
           "section", "ToolSection", "SimulationSection", "SceneSections"]


def section(path: str, **kw: Any) -> Any:
    """A field of an :class:`Inputs` subclass filled from the scene section ``path``
    (dotted, e.g. ``"artifacts.burrs"``) instead of the section named like the field."""
    return field(metadata={"section": path}, **kw)


class ToolSection(Protocol):
    """What a process reads of ``[tool]`` (the scene's ``ToolConfig``, which a type
    checker confirms satisfies this): the nose, the angles, the measured edge and the
    wear keys.  Lengths in mm."""

    nose_radius: float
    included_angle_deg: float
    rake_angle_deg: float
    clearance_angle_deg: float
    edge_profile: str | None
    waviness: list[tuple[float, float, float]] | None
    edge_scale: float
    wear: bool
    wear_scale: float
    contact_duty_cycle: float


class SimulationSection(Protocol):
    """What a process reads of ``[simulation]`` (the scene's ``SimulationConfig``): the
    grid (``region`` and ``pixel``, mm; ``shape``), the seed and the memory budget."""

    region: Region
    pixel: float
    seed: int
    max_memory_gb: float | None

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) of the grid."""
        ...

    def model_copy(self, *, update: dict[str, Any] | None = None,
                   deep: bool = False) -> SimulationSection:
        """A copy with some keys replaced (another ``region``)."""
        ...


class _KindSection(Protocol):
    """A ``[process]`` section, as far as the registry reads it: its ``kind``."""

    @property
    def kind(self) -> str:
        ...


class SceneSections(Protocol):
    """What the processes read of a validated scene (the scene's ``Scene``, which a type
    checker confirms satisfies this where the pipeline passes one): ``[design]``,
    ``[tool]``, ``[simulation]`` and the ``kind`` of ``[process]``; :meth:`Inputs.of`
    takes the further sections an :class:`Inputs` subclass declares by name."""

    @property
    def design(self) -> DesignSection:
        ...

    @property
    def tool(self) -> ToolSection:
        ...

    @property
    def simulation(self) -> SimulationSection:
        ...

    @property
    def process(self) -> _KindSection:
        ...


@dataclass(frozen=True)
class Inputs:
    """The scene sections a process's hooks read.

    A process that needs more declares a subclass with one field per further section
    (named like the section, or :func:`section` for a nested one).

    Attributes
    ----------
    name : str
        The scene's name (titles, program headers).
    process : Section
        ``[process]``: the process kind's ``config`` class (a subclass narrows the type).
    tool : ToolSection
        ``[tool]``.
    simulation : SimulationSection
        ``[simulation]`` (grid, seed, memory budget).
    """

    name: str
    # (any kind's [process]; each kind's subclass names its own schema class)
    process: Any
    tool: ToolSection
    simulation: SimulationSection

    @classmethod
    def of(cls, scene: SceneSections) -> "Inputs":
        """The sections of ``scene`` this class declares."""
        values = {}
        for f in fields(cls):
            node: Any = scene
            for part in f.metadata.get("section", f.name).split("."):
                node = getattr(node, part)
            values[f.name] = node
        return cls(**values)

    def replace(self, **sections: Any) -> "Inputs":
        """A copy with some sections replaced (e.g. another ``simulation`` region)."""
        return dataclasses.replace(self, **sections)


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
    plots : dict
        Figures of the program: file name -> figure spec (:mod:`render_inspect.report`).
    """

    program: ToolPath | LinearProgram
    facts: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    data: dict = field(default_factory=dict)
    plots: dict = field(default_factory=dict)


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
        Figures of the cut: file name -> figure spec (:mod:`render_inspect.report`); they
        replace the plan's figures of the same name.
    """

    machined: np.ndarray
    design: np.ndarray
    facts: dict = field(default_factory=dict)
    timing: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    followed: ToolPath | None = None
    plots: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Traits:
    """What the rest of the chain needs to know of a process, stated by the process.

    Attributes
    ----------
    name : str
        The process kind (metrics.json ``process``).
    compensation : str
        The tool-radius compensation applied (metrics.json ``compensation``; ``"none"``
        for processes without one).
    marks : ToolMarks or None
        The periodic marks it leaves (waviness filters, the diffuse renderer's texture,
        the expected roughness); None: no periodic marks.
    axis : (x, y) or None
        The spindle axis of a turned part (mm): sections of the part are radial about it.
    part : dict or None
        The whole part for the macro view (``{"shape": "disc", "center", "radius"}``);
        None: the simulated region is the part.
    saves_program : bool
        ``simulate`` writes the program as ``toolpath.npz`` next to the height map.
    cut_rate : float
        Samples per second the cut runs at (the progress bar's estimate).
    contributions : dict
        What the machined surface owes to parts of the model beyond the commanded
        geometry (the lathe, the material): name -> ``{"label": text, "off": {dotted
        scene key: value}}``, the scene values that turn that part off (``compare``
        splits the deepest cut into them); empty: the commanded geometry is all there is.
    """

    name: str
    compensation: str = "none"
    marks: ToolMarks | None = None
    axis: tuple[float, float] | None = None
    part: dict | None = None
    saves_program: bool = False
    cut_rate: float = 2e6
    contributions: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Envelope:
    """A machined surface that is the envelope of the tool nose along one path and nothing
    else (what the tiled, out-of-core simulation computes tile by tile).

    Attributes
    ----------
    path : ToolPath
        The path the nose follows (after the machine's dynamics).
    nose_radius, half_width : float
        The nose arc, mm.
    meta : dict
        Provenance stored with the height map.
    mechanics : MaterialResponse or None
        The material whose cutting mechanics (minimum chip thickness, elastic recovery,
        side flow) cut the path; None: the geometric envelope.
    grooves : Grooves or None
        The grooves of the material's cutting edge.
    texture : tuple or None
        The part's texture (rms, correlation length, seed), mm, added where the tiles are
        cut with the material's mechanics.
    burrs : dict or None
        The material's burrs added tile by tile: the keyword arguments of
        :func:`~render_inspect.machining.material_burrs` but the grid's (``chip_thickness``,
        ``coefficient``, ``variation``, ``seed``, ``edge_angle_deg``, ``smoothing``,
        ``width``); None: no burrs.
    facts : dict
        Facts of the cut known before the tiles run (the machine, its following error).
    followed : object
        What :meth:`Process.tiled_facts` needs of the path (the followed path), or None.
    plots : dict
        Figures of the cut known before the tiles run (file name -> figure spec).
    edge : EdgeProfile or None
        The measured cutting edge (``toolpath.EdgeProfile``); None: a circular nose.
    h_min_points : array or None
        The minimum chip thickness (mm) at each point of ``path``: the edge worn along it
        (``tool.wear``); None: the material's one value.
    mirror : bool
        The path turns the spindle counter-clockwise (M04): the tiles cut the M03 run of
        the mirror image (the design mirrored, :class:`~render_inspect.processes.MirroredSurface`,
        over the mirrored grid, :func:`~render_inspect.processes.mirrored_region`) and the store's rows are then turned over, so that
        the map is the part's, in its own coordinates (row 0 the smallest y).
    """

    path: ToolPath
    nose_radius: float
    half_width: float
    meta: dict = field(default_factory=dict)
    mechanics: MaterialResponse | None = None
    grooves: Grooves | None = None
    texture: tuple[float, float, int] | None = None
    burrs: dict | None = None
    facts: dict = field(default_factory=dict)
    followed: object = None
    plots: dict = field(default_factory=dict)
    edge: object = None
    h_min_points: object = None
    mirror: bool = False


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


#: the inputs class of a process kind (:attr:`Process.inputs`)
InputsT = TypeVar("InputsT", bound=Inputs)


class Process(ABC, Generic[InputsT]):
    """A process kind (see the module docstring).  Register an instance with
    :func:`~render_inspect.processes.register_process`.

    The class is generic in its inputs: ``class SculptProcess(Process[SculptInputs])``
    with ``inputs = SculptInputs`` types every hook's ``cfg`` as ``SculptInputs``, so a
    type checker sees each key a hook reads."""

    #: the ``[process]`` schema class; its ``kind`` Literal names the kinds
    config: ClassVar[type]
    #: the scene sections the hooks read
    inputs: ClassVar[type[Inputs]] = Inputs

    def inputs_of(self, scene: SceneSections) -> InputsT:
        """The hooks' view of ``scene``: the sections :attr:`inputs` declares."""
        return cast(InputsT, self.inputs.of(scene))

    # ---------------------------------------------------------------- required hooks
    @abstractmethod
    def plan(self, cfg: InputsT, surface: Surface, *,
             region: Sequence[float] | None = None) -> Plan:
        """The machine program (whole part, or what reaches ``region``) and its facts."""

    def plan_window(self, cfg: InputsT, surface: Surface, region: Sequence[float]) -> Plan:
        """The program a simulation of ``region`` cuts, planned at the cost of the region
        (default: :meth:`plan` of the region; a turning process plans only the sectors of
        its revolutions that reach it).  Not a program to write out."""
        return self.plan(cfg, surface, region=region)

    @abstractmethod
    def cut(self, cfg: InputsT, surface: Surface, plan: Plan) -> Cut:
        """The machined and design heights on ``cfg.simulation``'s grid."""

    @abstractmethod
    def estimate_memory(self, cfg: InputsT, plan: Plan | None = None) -> int:
        """Bytes the simulation holds at its peak."""

    def traits(self, cfg: InputsT) -> Traits:
        """What the chain needs to know of this process (default: its name only)."""
        return Traits(name=cfg.process.kind)

    # ---------------------------------------------------------------- optional hooks
    def precheck(self, cfg: InputsT, region: Sequence[float] | None = None) -> None:
        """Check the sizes the process's own keys drive against the memory budget before
        anything is planned (:func:`~render_inspect.processes.check_budget`)."""

    def program_region(self, cfg: InputsT) -> tuple[float, ...] | None:
        """The region the ``toolpath`` command plans (None: the whole part)."""
        return None

    def program_header(self, cfg: InputsT) -> dict:
        """NC header lines of the program."""
        return {}

    def program_facts(self, cfg: InputsT, plan: Plan) -> dict:
        """``toolpath.json`` of the ``toolpath`` command: the plan's facts, with the
        program's point count at least."""
        facts = dict(plan.facts)
        facts.setdefault("toolpath", {}).setdefault("points", int(plan.program.points))
        return facts

    def program_plan(self, cfg: InputsT, surface: Surface,
                     program: ToolPath | LinearProgram) -> Plan:
        """The plan of a program read back from a file (``toolpath.nc``, ...), for
        :meth:`cut` to simulate it again; default: the program and nothing else."""
        return Plan(program)

    def program_part(self, cfg: InputsT, surface: Surface, plan: Plan) -> PartModel | None:
        """The part the written program is checked against (design heights, outline,
        stock, the tool's half width); None: the program is written without links and
        not checked."""
        return None

    def program_limits(self, cfg: InputsT) -> MachineLimits:
        """What the machine allows the program (feeds, axis velocities, spindle speed,
        travel); default: no limits."""
        return MachineLimits(source="the machine")

    def program_links(self, cfg: InputsT, surface: Surface, plan: Plan) -> Links | None:
        """The clearance plane and plunge feed of the moves between the cuts: the part's
        highest point (:meth:`program_part`) plus ``process.clearance``, the feed
        ``process.plunge_feed_mm_per_min``.  None when :meth:`program_part` is None."""
        both = self.program_links_part(cfg, surface, plan)
        return None if both is None else both[0]

    def program_links_part(self, cfg: InputsT, surface: Surface,
                           plan: Plan) -> tuple[Links, PartModel] | None:
        """:meth:`program_links` and the :meth:`program_part` they were set from, made
        once (for a caller that checks the links against the part); None when the program
        has no links.  A process whose program has no links in some case (a program read
        from a file) overrides this, and :meth:`program_links` follows."""
        part = self.program_part(cfg, surface, plan)
        if part is None:
            return None
        p = cfg.process
        return plan_links(part, clearance=getattr(p, "clearance", DEFAULT_CLEARANCE),
                          plunge_feed=getattr(p, "plunge_feed_mm_per_min", DEFAULT_PLUNGE_FEED),
                          program_z=plan.program.z), part

    def variants(self, cfg: InputsT) -> VariantPair | None:
        """The pair ``compare`` puts side by side (None: only ``--vary``)."""
        return None

    def tile_refusal(self, cfg: InputsT) -> str | None:
        """Why the scene cannot be simulated tile by tile (None: it can, through
        :meth:`envelope` and :meth:`tiled_memory`)."""
        return (f"process.kind = {cfg.process.kind!r} has no tiled simulation (its surface "
                f"is not the envelope of one tool path); shrink simulation.region or raise "
                f"simulation.max_memory_gb to simulate it in memory")

    def envelope(self, cfg: InputsT, surface: Surface, plan: Plan) -> Envelope:
        """The path whose nose envelope is the machined surface (tiled simulation).  A
        process without one refuses with its :meth:`tile_refusal`."""
        raise self._no_tiling(cfg, "envelope")

    def tiled_memory(self, cfg: InputsT, plan: Plan | None = None) -> tuple[int, int]:
        """(bytes the process holds besides the tiles, points of its program) of a tiled
        simulation (estimated before planning when ``plan`` is None).  A process without a
        tiled simulation refuses with its :meth:`tile_refusal`."""
        raise self._no_tiling(cfg, "tiled_memory")

    def _no_tiling(self, cfg: InputsT, method: str) -> Exception:
        """The error of a tiled simulation's step the process does not have: the user's
        one line (:meth:`tile_refusal`), or, for a process that says it tiles but lacks
        the step, what the process's author must add."""
        refusal = self.tile_refusal(cfg)
        if refusal is None:
            return TypeError(f"{type(self).__name__}: tile_refusal() allows a tiled "
                             f"simulation, so the process must define {method}()")
        return InputError(refusal)

    def following_memory(self, cfg: InputsT, plan: Plan | None = None) -> int:
        """Bytes a tiled simulation holds at its peak before the tiles start (the machine
        model following the whole path; estimated before planning when ``plan`` is
        None): the estimate is the larger of this and the tiles' phase.  Default 0 (a
        process that follows nothing)."""
        return 0

    def tiled_facts(self, cfg: InputsT, env: Envelope, cut: dict, *, stride: int) -> tuple[dict, dict]:
        """(facts, figures) of a tiled cut from the sums over its tiles (``cut``: see
        :class:`~render_inspect.batch.TiledStats`; its ``pass_theta`` on every
        ``stride``-th row and column; ``residual``: the whole map's ``metrics.json``
        ``residual``, from the tiles; ``residual_row``: a function of a row index giving
        that row of the stored machined - design, mm); default: ``env.facts`` and
        ``env.plots``."""
        return dict(env.facts), dict(env.plots)
