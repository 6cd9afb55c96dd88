"""Sweep files: a base scene and the scene keys to vary, expanded into points.

A sweep file is TOML::

    name = "fig15_small"
    scene = "sts_sinusoidal_grid"        # a shipped scene, or a path relative to this file

    [set]                                 # every point (dotted scene keys)
    "simulation.region" = [-0.15, -0.15, 0.15, 0.15]

    [grid]                                # every combination of these lists
    "tool.nose_radius" = [0.1, 0.5, 1.0]
    "process.feed_mm_per_min" = [0.2, 1.0]

    [zip]                                 # lists of one length, varied together
    "process.spindle_rpm" = [50, 100]

    [[points]]                            # single points (tables of dotted keys)
    "tool.nose_radius" = 0.25

    [[study]]                             # more sub-sweeps with their own set/grid/zip/points
    name = "b"
    set = { "tool.nose_radius" = 0.5 }
    grid = { "process.spindle_rpm" = [50, 100, 150] }

    [morris]                              # a Morris screening design (batch._morris)
    trajectories = 10
    [[morris.factor]]
    key = "material.edge_radius_nm"
    low = 10.0
    high = 100.0

    [run]                                 # what each point runs
    render = "none"                       # "none", "all", "diffuse" or an instrument ("interferometer")
    measure = false                       # measure the interferogram frames (needs the interferometer)
    compare = false                       # compensated vs uncompensated, per point
    files = "metrics"                     # "metrics" | "all"

    [select]                              # the point to machine (batch._select)
    minimize = "machining.time_min"
    [select.at_most]
    "residual.Sq_nm" = 2.0

    [[plot]]
    kind = "curves"                       # metric against one key, a curve per value of another
    x = "tool.nose_radius"
    series = "process.feed_mm_per_min"
    y = "residual.Sq_nm"

A point's overrides are the file's ``set``, then its study's ``set``, then the values of
its grid / zip / single point, applied to the base scene exactly as ``--set`` would.
"""

from __future__ import annotations

from collections.abc import Sequence
import difflib
import hashlib
import itertools
import json
import math
import re
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, ValidationError, ValidationInfo, field_validator, model_validator

from ..core.messages import validation_line
from ..core.errors import InputError
from ..core.section import Section
from ._morris import MORRIS_STUDY, MorrisConfig
from ._select import SelectConfig

__all__ = ["SweepFile", "Study", "RunConfig", "PlotConfig", "SweepPoint", "read_sweep",
           "expand_points", "sweep_keys", "fixed_keys", "count_points", "toml_value",
           "point_id", "dotted_get", "MAX_POINTS", "check_file_name"]

#: the most points one sweep file may have (checked before its grids are expanded;
#: split a larger study into several sweep files)
MAX_POINTS = 10_000
#: names that become file names (``[[plot]] name``, ``[[study]] name``): letters, digits,
#: '.', '_' and '-', starting with a letter or digit, at most 100 characters
_FILE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]{0,99}$")


def check_file_name(value: str, what: str) -> str:
    """``value`` when it is a safe file name (see :data:`_FILE_NAME`), else a ValueError
    naming ``what``: a name may not hold a folder (``/``, ``..``) or start with '.'."""
    if not isinstance(value, str) or not _FILE_NAME.match(value) or ".." in value:
        raise ValueError(f"{what} must be a file name of letters, digits, '.', '_' and '-' "
                         f"(starting with a letter or digit, at most 100 characters, no "
                         f"folders)")
    return value

def _check_keys(keys, where: str, sections=None) -> None:
    """Dotted scene keys; with ``sections`` (the scene's top-level sections, passed by the
    caller that knows the scene schema) also their first part."""
    for k in keys:
        parts = str(k).split(".")
        if len(parts) < 2 or not all(parts) or (sections is not None and parts[0] not in sections):
            allowed = f" (section one of {', '.join(sections)})" if sections is not None else ""
            raise ValueError(f"{where} key must be a dotted scene key such as "
                             f"'tool.nose_radius'{allowed}, received {k!r}")


def _sections(info: ValidationInfo):
    return (info.context or {}).get("sections")


def _check_study(set_, grid, zip_, points, sections=None) -> None:
    _check_keys(set_, "set", sections)
    _check_keys(grid, "grid", sections)
    _check_keys(zip_, "zip", sections)
    for p in points:
        _check_keys(p, "points", sections)
    for k, v in grid.items():
        if not v:
            raise ValueError(f"grid must give at least one value for {k!r}, received []")
    lens = {k: len(v) for k, v in zip_.items()}
    if len(set(lens.values())) > 1:
        raise ValueError(f"zip lists must all have the same length, received lengths {lens}")
    if any(n == 0 for n in lens.values()):
        raise ValueError(f"zip lists must not be empty, received lengths {lens}")
    both = set(grid) & set(zip_)
    if both:
        raise ValueError(f"zip keys must not also be grid keys, received {sorted(both)} in both")


def _no_empty_tables(data: Any, info: ValidationInfo, where: str) -> Any:
    """Refuse a ``[grid]`` or ``[zip]`` written in a sweep file without a key (it would
    run the base scene alone, not the sweep that was meant); a sweep of the base scene
    alone has no such table.  Only a file's tables are checked (``info.context`` set)."""
    if info.context is not None and isinstance(data, dict):
        for table in ("grid", "zip"):
            if table in data and data[table] == {}:
                raise ValueError(f"an empty {table} table{where}: give at least one dotted "
                                 f"scene key with its list of values (a sweep of the base scene "
                                 f"alone has no [{table}])")
    return data


class Study(Section):
    """One sub-sweep: ``set`` (fixed keys), ``grid`` (every combination), ``zip`` (lists
    varied together) and ``points`` (single points)."""
    name: str = ""
    set: dict[str, Any] = Field(default_factory=dict)
    grid: dict[str, list[Any]] = Field(default_factory=dict)
    zip: dict[str, list[Any]] = Field(default_factory=dict)
    points: list[dict[str, Any]] = Field(default_factory=list)

    @field_validator("name")
    @classmethod
    def _name(cls, v):
        return v if v == "" else check_file_name(v, "study name")

    @model_validator(mode="before")
    @classmethod
    def _empty(cls, data: Any, info: ValidationInfo):
        return _no_empty_tables(data, info, " in [[study]]")

    @model_validator(mode="after")
    def _lists(self, info: ValidationInfo):
        _check_study(self.set, self.grid, self.zip, self.points, _sections(info))
        return self

    def count(self) -> int:
        """The number of combinations (:meth:`combinations`), without making them."""
        n = 0
        if self.grid or self.zip:
            nz = len(next(iter(self.zip.values()))) if self.zip else 1
            n = math.prod(len(v) for v in self.grid.values()) * nz
        n += len(self.points)
        return n or 1

    def combinations(self) -> list[dict]:
        """The study's points as dicts of dotted key -> value (without ``set``); a study
        where nothing varies is one point (its ``set`` on the base scene)."""
        combos = []
        if self.grid or self.zip:
            gkeys = list(self.grid)
            zkeys = list(self.zip)
            nz = len(next(iter(self.zip.values()))) if zkeys else 1
            for values in itertools.product(*(self.grid[k] for k in gkeys)):
                for i in range(nz):
                    c = dict(zip(gkeys, values))
                    c.update({k: self.zip[k][i] for k in zkeys})
                    combos.append(c)
        combos.extend(dict(p) for p in self.points)
        return combos or [{}]


class RunConfig(Section):
    """``[run]``: what each point runs besides ``simulate``.  ``render`` takes what
    ``render --kind`` takes (a registered instrument, ``diffuse`` or ``all``) or ``none``:
    the names come from the validation context (``render_kinds``, and ``frames_kind``, the
    instrument ``measure`` reads the frames of), which :func:`read_sweep` is given."""
    render: str = Field("none", description="none, all, diffuse or a registered instrument")
    measure: bool = Field(False, description="measure the interferogram frames (needs the interferometer)")
    compare: bool = Field(False, description="compensated vs uncompensated for each point")
    files: Literal["metrics", "all"] = Field(
        "metrics", description="metrics: metrics.json, scene.json, residual.png; all: also "
                               "heightmap.exr, toolpath.npz and the previews")

    @field_validator("render")
    @classmethod
    def _render(cls, v, info: ValidationInfo):
        kinds = (info.context or {}).get("render_kinds")
        if kinds is not None and v not in ("none", *kinds):
            names = [repr(k) for k in ("none", *kinds)]
            raise ValueError(f"must be one of {', '.join(names[:-1])} or {names[-1]}; "
                             f"received {v!r}")
        return v

    @model_validator(mode="after")
    def _measure(self, info: ValidationInfo):
        frames = (info.context or {}).get("frames_kind")
        if self.measure and (self.render not in (frames, "all") if frames is not None
                             else self.render in ("none", "diffuse")):
            raise ValueError(f"measure = true needs render = {frames or 'the frames instrument'!r}"
                             f" or 'all', received render = {self.render!r}")
        return self


class PlotConfig(Section):
    """``[[plot]]``: ``curves`` (``y`` against ``x``, one curve per value of ``series``) or
    ``heatmap`` (``value`` over the ``x`` - ``y`` plane)."""
    kind: Literal["curves", "heatmap"]
    x: str
    y: str = Field("residual.Sq_nm", description="curves: a metric; heatmap: a second key")
    series: str | None = None
    value: str = Field("residual.Sq_nm", description="heatmap: the metric")
    study: str | None = Field(None, description="only the points of this study")
    title: str = ""
    log: bool = Field(False, description="logarithmic metric axis / colour scale")
    name: str | None = Field(None, description="file name (without .png): letters, digits, "
                                               "'.', '_' and '-'")

    @field_validator("name")
    @classmethod
    def _name(cls, v):
        return v if v is None else check_file_name(v, "plot name")


class SweepFile(Section):
    """A sweep file (see the module docstring)."""
    name: str = ""
    description: str = ""
    scene: str
    set: dict[str, Any] = Field(default_factory=dict)
    grid: dict[str, list[Any]] = Field(default_factory=dict)
    zip: dict[str, list[Any]] = Field(default_factory=dict)
    points: list[dict[str, Any]] = Field(default_factory=list)
    study: list[Study] = Field(default_factory=list)
    morris: MorrisConfig | None = Field(None, description="a Morris elementary-effects design, "
                                                          "run as the study 'morris'")
    run: RunConfig = Field(default_factory=RunConfig)
    plot: list[PlotConfig] = Field(default_factory=list)
    select: SelectConfig | None = Field(None, description="the point to machine: bounds on "
                                                          "metrics and the metric to minimise")

    @model_validator(mode="before")
    @classmethod
    def _empty(cls, data: Any, info: ValidationInfo):
        return _no_empty_tables(data, info, "")

    @model_validator(mode="after")
    def _top(self, info: ValidationInfo):
        _check_study(self.set, self.grid, self.zip, self.points, _sections(info))
        if self.morris is not None:
            _check_keys([f.key for f in self.morris.factor], "morris.factor", _sections(info))
        names = [s.name for s in self.study] + ([MORRIS_STUDY] if self.morris else [])
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"study names must be unique, received {dup} more than once")
        return self

    def studies(self) -> list[Study]:
        """The top-level grid/zip/points as a study named "" (when given) plus the
        ``[[study]]`` tables and the ``[morris]`` design (the study ``morris``); a single
        point (the base scene with ``set``) when nothing varies."""
        out = []
        if self.grid or self.zip or self.points or not (self.study or self.morris):
            out.append(Study(name="", grid=self.grid, zip=self.zip, points=self.points))
        out.extend(self.study)
        if self.morris is not None:
            pts = [p for traj in self.morris.design() for p in traj]
            out.append(Study(name=MORRIS_STUDY, points=pts))
        return out


@dataclass
class SweepPoint:
    """One point of a sweep before it is run.

    Attributes
    ----------
    overrides : dict
        Dotted scene key -> value, in the order applied.
    studies : list of str
        The studies that contain the point (a point shared by several studies runs once).
    index : int
        Position in the sweep (first appearance).
    """
    overrides: dict
    studies: list = field(default_factory=list)
    index: int = 0


def _did_you_mean(loc: Sequence[Any]) -> str:
    """``; did you mean 'grid'?`` for an unknown key of the sweep file (``loc``: where
    it is) whose table has a key spelled like it."""
    model: Any = SweepFile
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        f = getattr(model, "model_fields", {}).get(part)
        ann = getattr(f, "annotation", None)
        nested = [a for a in (*getattr(ann, "__args__", ()), ann)
                  if isinstance(a, type) and issubclass(a, Section)]
        nested += [a for arg in getattr(ann, "__args__", ()) for a in getattr(arg, "__args__", ())
                   if isinstance(a, type) and issubclass(a, Section)]
        if not nested:
            return ""
        model = nested[0]
    close = difflib.get_close_matches(str(loc[-1]), list(getattr(model, "model_fields", {})),
                                      n=2, cutoff=0.6)
    return ("; did you mean " + " or ".join(repr(c) for c in close) + "?") if close else ""


def _format_error(err: ValidationError, source: str) -> InputError:
    # (messages) every error in the scene's words: the key, what it accepts, the value
    lines = []
    for e in err.errors():
        key, text = validation_line(e, key=".".join(str(p) for p in e["loc"]))
        if e.get("type") == "extra_forbidden":
            text += _did_you_mean(e["loc"])
        lines.append(f"{key or '(top level)'}: {text}")
    if len(lines) == 1:
        return InputError(f"invalid sweep file {source}: {lines[0]}")
    return InputError(f"invalid sweep file {source} ({len(lines)} errors):\n"
                      + "\n".join(f"  {line}" for line in lines))


def read_sweep(path: str | Path, *, sections: Sequence[str] | None = None,
               render_kinds: Sequence[str] | None = None,
               frames_kind: str | None = None) -> SweepFile:
    """Read and validate a sweep file (TOML).

    Parameters
    ----------
    path : path
        The sweep file.
    sections : sequence of str, optional
        The scene's top-level sections: keys must start with one of them (without it, only
        their dotted form is checked; the scene checks the rest when the points resolve).
    render_kinds : sequence of str, optional
        What ``[run] render`` may name besides ``"none"`` (what ``render --kind`` takes:
        the registered instruments, ``"diffuse"``, ``"all"``); without it any name passes
        here and the render checks it when the points run.
    frames_kind : str, optional
        The instrument whose frames ``[run] measure`` measures (``render`` must name it or
        ``"all"``).

    Raises
    ------
    InputError
        Missing file, bad TOML, unknown keys or bad values (naming the key and the value).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"sweep file not found: {str(path)!r}; give a .toml sweep file "
                         f"(shipped ones are in render_inspect/scenes/sweeps/)")
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as err:
        raise InputError(f"sweep file {str(path)!r} is not valid TOML: {err}") from None
    except UnicodeDecodeError as err:  # a binary file given as the sweep
        raise InputError(f"sweep file {str(path)!r} is not UTF-8 text (byte {err.start}): a "
                         f"sweep file is a TOML text") from None
    except RecursionError:
        raise InputError(f"sweep file {str(path)!r} nests tables/arrays too deeply") from None
    try:
        spec = SweepFile.model_validate(data, context={"sections": sections,
                                                       "render_kinds": render_kinds,
                                                       "frames_kind": frames_kind})
    except ValidationError as err:
        raise _format_error(err, str(path)) from None
    if not spec.name:
        spec.name = path.stem
    n = count_points(spec)
    if n > MAX_POINTS:
        sizes = "; ".join(_shape_text(st) for st in spec.studies())
        raise InputError(f"sweep file {str(path)!r} has {n:,} points ({sizes}), more than the "
                         f"{MAX_POINTS:,} one sweep may have; split it into several sweep files")
    return spec


def _shape_text(st: Study) -> str:
    parts = []
    if st.grid:
        parts.append("grid " + " x ".join(str(len(v)) for v in st.grid.values()))
    if st.zip:
        parts.append(f"zip of {len(next(iter(st.zip.values())))}")
    text = " x ".join(parts)
    if st.points:
        text += (" + " if text else "") + f"{len(st.points)} single points"
    return (f"study {st.name!r}: " if st.name else "") + (text or "1 point")


def count_points(spec: SweepFile) -> int:
    """The points of a sweep before expansion (an upper bound: points shared by studies
    count once each)."""
    return sum(st.count() for st in spec.studies())


def expand_points(spec: SweepFile) -> list[SweepPoint]:
    """All points of a sweep, each once (identical override sets from several studies are
    merged; their ``studies`` lists them all)."""
    seen: dict[str, SweepPoint] = {}
    for st in spec.studies():
        for combo in st.combinations():
            ov = {**spec.set, **st.set, **combo}
            key = json.dumps(ov, sort_keys=True, default=str)
            if key in seen:
                if st.name not in seen[key].studies:
                    seen[key].studies.append(st.name)
            else:
                seen[key] = SweepPoint(ov, [st.name], len(seen))
    return list(seen.values())


def sweep_keys(spec: SweepFile) -> list[str]:
    """The keys that vary across the sweep (study ``set`` keys included), in the order
    they first appear: the ``params`` of every result."""
    keys: list[str] = []
    for st in spec.studies():
        for k in [*st.set, *st.grid, *st.zip, *(k for p in st.points for k in p)]:
            if k not in keys:
                keys.append(k)
    return keys


def fixed_keys(spec: SweepFile) -> list[str]:
    """The keys the file's top-level ``set`` fixes for every point (those that do not
    also vary), in file order."""
    varied = set(sweep_keys(spec))
    return [k for k in spec.set if k not in varied]


def toml_value(value: object) -> str:
    """``value`` as TOML value text (what ``--set KEY=VALUE`` takes)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise InputError(f"sweep value must be a number, string, boolean, list or table, "
                     f"received {value!r}")


def point_id(payload: dict) -> str:
    """A point's identity: the first 16 hex digits of the SHA-256 of ``payload`` as
    canonical JSON (keys sorted, no spaces)."""
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


def dotted_get(data: dict, key: str, default: Any = None) -> Any:
    """``data["a"]["b"]`` for ``key = "a.b"`` (``default`` when a part is missing)."""
    node = data
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return default
        node = node[part]
    return node
