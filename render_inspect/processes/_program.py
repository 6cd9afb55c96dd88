"""The user's own machine program in place of the planned one (``[process] program``).

The program replaces what the process would plan; the scene still gives the design (the
reference of the residual), the tool, the machine, the material, the instrument and the
region.  :func:`imported_path` reads a turning program
(:func:`~render_inspect.io.read_program`) with the scene's spindle speed, feed and part
size for what the program does not say, and keeps the part of it that can reach the
simulated region; :func:`program_checks` measures what a CAM user checks (feed per
revolution against the radius, chordal error against the design, axis rates) and lists
the moves through the part or below the design as findings.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import ToolPath
from ..core.units import MM_TO_NM, MM_TO_UM, MIN_TO_S
from ..core.programs import read_program_file
from ..core.toolpath import LinearProgram, part_angle
from ..toolpath import BLOCK_RATE_KEY, Tool, block_rate, region_radii

if TYPE_CHECKING:
    from ._contract import Plan

log = logging.getLogger("render_inspect")

__all__ = ["imported_path", "imported_linear", "program_checks", "feed_per_rev_table", "fit_paraboloid", "findings_summary",
           "feed_per_rev", "feed_over_radii", "FINDING_TOLERANCE_MM", "feed_per_rev_figure", "cut_name"]

#: what a program read from a file can change where its blocks come too fast
FILE_ADVICE = "write the program with fewer, longer blocks or at a lower feed"
#: how far below the design a point of an imported program must lie to be a finding, mm
#: (the programs' 6 written places round to 0.5 nm; fitted designs are good to a few nm)
FINDING_TOLERANCE_MM = 1e-5
#: radial bands of the feed-per-revolution table
_BANDS = 20
#: points whose design height the checks evaluate at most (evenly spread)
_CHECK_POINTS = 2_000_000
#: examples of each kind of finding listed
_EXAMPLES = 5


def program_path(cfg: Any) -> str | None:
    """The scene's ``process.program`` (None: the process plans its own)."""
    return getattr(cfg.process, "program", None)


def cut_name(scene: Any) -> str:
    """What the outputs' titles and headings call a cut: the scene's name, and where the
    path cut is a machine program read from a file (``process.program``, ``--program``)
    the program's file name too: ``"sts_sinusoidal_grid, program part.nc"``.  ``scene``:
    a scene or a process's inputs (anything with ``name`` and ``process``)."""
    program = getattr(getattr(scene, "process", None), "program", None)
    return f"{scene.name}, program {Path(str(program)).name}" if program else str(scene.name)


def imported_path(cfg: Any, surface: Any, *, region: Sequence[float] | None = None) -> ToolPath:
    """The turning program of ``process.program`` as the lathe runs it
    (:func:`~render_inspect.io.read_program` with the scene's ``process.spindle_rpm``,
    ``process.feed_mm_per_min``, ``process.workpiece_radius``, ``process.program_x``,
    ``process.program_integers`` and ``process.points_per_rev``), cut to the points that
    can reach ``region``; its ``meta["program"]`` holds the dialect and what was inferred
    (and the reader's warnings, said once), ``meta["feed_per_rev_mm"]`` the program's
    median feed per revolution at the radii ``region`` spans (over the whole program
    without a region)."""
    p = cfg.process
    imp = read_program_file(p.program, kind="turning", spindle_rpm=float(p.spindle_rpm),
                       feed_mm_per_min=float(p.feed_mm_per_min),
                       part_radius=float(p.workpiece_radius), x_mode=p.program_x,
                       points_per_rev=int(p.points_per_rev), design_height=surface.height,
                       integers=p.program_integers)
    _warn(imp)
    path = imp.program
    meta = dict(path.meta)
    meta["program"] = {"file": Path(imp.path).name, "dialect": imp.dialect,
                       "inferred": dict(imp.inferred), **imp.facts}
    r, f = feed_per_rev(path)
    if f.size:
        meta["feed_per_rev_mm"] = float(np.median(f))
        if region is not None:
            # the feed that cut the region (the scallop, the burrs' smoothing): the median
            # at the radii the region spans (a program may change its feed with the radius)
            r_in, r_out = region_radii(tuple(region), 0.0)
            sel = (np.abs(r) >= r_in) & (np.abs(r) <= r_out) & (f > 0)
            if sel.any():
                meta["feed_per_rev_mm"] = float(np.median(f[sel]))
                meta["program"]["feed_per_rev_region_um"] = meta["feed_per_rev_mm"] * MM_TO_UM
    meta["time_s"] = float(path.t[-1] - path.t[0]) if path.points else 0.0
    lines, motion = imp.file_line, imp.motion
    if region is not None and path.points > 2:
        keep = _reaching(path, region, Tool.from_config(cfg.tool).half_width)
        if keep is not None:
            path = ToolPath(path.theta[keep], path.rho[keep], path.z[keep], path.t[keep], meta)
            lines, motion = lines[keep], motion[keep]
            meta["program"]["points_kept_for_region"] = int(path.points)
    out = ToolPath(path.theta, path.rho, path.z, path.t, meta)
    # the file line and motion (0 rapid, 1 linear, 2/3 arc) of the block of each point
    out.program_lines = lines  # type: ignore[attr-defined]  # (read back with getattr)
    out.program_motion = motion  # type: ignore[attr-defined]
    return out


def _warn(imp: Any) -> None:
    """The reader's warnings (numbers without a decimal point read as whole units): said
    once per command (a command that reads the program again says the same line)."""
    for text in imp.facts.get("warnings", ()):
        log.warning("warning: %s", text)


def _reaching(path: ToolPath, region, half_width: float):
    """A slice of the points that can reach ``region`` (radii within the nose's half
    width and one revolution's feed of it), or None when all are needed or they are not
    one run."""
    fpr = feed_per_rev(path)[1]
    step = float(np.max(fpr)) if fpr.size else 0.0
    r_in, r_out = region_radii(region, half_width + 2 * max(step, 0.0))
    inside = (np.abs(path.rho) >= r_in) & (np.abs(path.rho) <= r_out)
    idx = np.flatnonzero(inside)
    if idx.size == 0 or idx.size == path.points:
        return None
    lo, hi = int(idx[0]), int(idx[-1])
    if hi - lo + 1 != idx.size:
        return None  # the program leaves the band and comes back: keep it whole
    return slice(max(lo - 1, 0), min(hi + 2, path.points))


def imported_linear(cfg: Any) -> tuple[LinearProgram, Any]:
    """The X-Y-Z program of ``process.program`` (feed from ``process.feed_mm_per_min``
    where it gives none)."""
    p = cfg.process
    imp = read_program_file(p.program, kind="linear", feed_mm_per_min=float(p.feed_mm_per_min),
                       feed_source="process.feed_mm_per_min", integers=p.program_integers)
    _warn(imp)
    prog = imp.program
    prog.meta["program"] = {"file": Path(imp.path).name, "dialect": imp.dialect,
                            "inferred": dict(imp.inferred), **imp.facts}
    return prog, imp


# ---------------------------------------------------------------------------- checks
def feed_per_rev(path: ToolPath) -> tuple[np.ndarray, np.ndarray]:
    """(radius, feed per revolution) at every point one revolution before the end: how
    far the radius moves in the revolution that starts at the point, mm (positive
    inwards)."""
    theta, rho = np.asarray(path.theta), np.asarray(path.rho)
    if theta.size < 2:
        return np.zeros(0), np.zeros(0)
    ok = theta + 2 * math.pi <= theta[-1] + 1e-9
    r_next = np.interp(theta[ok] + 2 * math.pi, theta, rho)
    return rho[ok], rho[ok] - r_next


def feed_over_radii(path: ToolPath, r0: float, r1: float, *, weighting: str = "plain") -> float:
    """The feed per revolution (mm) a program commands over the radii ``r0 < r1`` (mm),
    from its spindle angle and radius words (the path's ``theta`` and ``rho``).

    ``weighting="plain"``: the radial distance over the revolutions the spindle turns
    between the two radii, every radius alike: the mean spacing of the marks the program
    leaves there (their count over the stretch's length).  ``weighting="hann"``: the
    marks' local frequency (revolutions per mm of radius) averaged under a Hann window
    over the radii, inverted: what a period read from a Hann-windowed spectrum of the
    stretch sees, its centre counting more than its ends.  The two agree where the step
    is constant.  Radii the path does not reach, or a path that turns back in radius
    between them, are refused."""
    if weighting not in ("plain", "hann"):
        raise InputError(f"weighting must be 'plain' or 'hann', got {weighting!r}")
    theta, rho = np.asarray(path.theta, np.float64), np.asarray(path.rho, np.float64)
    if not (0.0 <= r0 < r1):
        raise InputError(f"radii must satisfy 0 <= r0 < r1 (mm), got {r0:g} and {r1:g}")
    if rho.size < 2 or r0 < rho.min() or r1 > rho.max():
        lo, hi = (float(rho.min()), float(rho.max())) if rho.size else (0.0, 0.0)
        raise InputError(f"the program reaches radii {lo:.4g}-{hi:.4g} mm, not "
                         f"{r0:.4g}-{r1:.4g} mm")
    inside = np.flatnonzero((rho >= r0) & (rho <= r1))
    if inside.size == 0:  # the radii lie between two neighbouring points of the program
        inside = np.flatnonzero(np.diff(np.sign(rho - r0)) != 0)[:1]
    # the points that hold the radii and one either side (the interpolation's ends)
    a, b = max(int(inside[0]) - 1, 0), min(int(inside[-1]) + 2, rho.size)
    d = np.diff(rho[a:b])
    if not (np.all(d <= 0) or np.all(d >= 0)):
        raise InputError(f"the program turns back in radius between {r0:.4g} and "
                         f"{r1:.4g} mm: its feed per revolution there is not one number")
    # revolutions turned since the program's start, as a function of the radius
    order = np.argsort(rho[a:b], kind="stable")
    rr, turns = rho[a:b][order], theta[a:b][order] / (2 * math.pi)
    if weighting == "plain":
        na, nb = np.interp([r0, r1], rr, turns)
        return float((r1 - r0) / abs(nb - na))
    r = np.linspace(r0, r1, 2001)
    w = np.hanning(r.size)
    return float(np.sum(w) / np.sum(w * np.abs(np.gradient(np.interp(r, rr, turns), r))))


def feed_per_rev_table(path: ToolPath, bands: int = _BANDS) -> list[dict]:
    """Feed per revolution in radial bands: ``r_from_mm``, ``r_to_mm``, ``points``,
    ``mean_um``, ``min_um``, ``max_um``."""
    r, f = feed_per_rev(path)
    if r.size == 0:
        return []
    edges = np.linspace(float(r.min()), float(r.max()), bands + 1)
    which = np.clip(np.searchsorted(edges, r, side="right") - 1, 0, bands - 1)
    out = []
    for k in range(bands):
        sel = which == k
        if not sel.any():
            continue
        fk = f[sel]
        out.append({"r_from_mm": float(edges[k]), "r_to_mm": float(edges[k + 1]),
                    "points": int(sel.sum()), "mean_um": float(fk.mean() * MM_TO_UM),
                    "min_um": float(fk.min() * MM_TO_UM), "max_um": float(fk.max() * MM_TO_UM)})
    return out


def feed_per_rev_figure(path: ToolPath, name: str) -> dict:
    """The figure spec (``feed_per_rev.png``) of the feed per revolution against the
    radius."""
    r, f = feed_per_rev(path)
    step = max(1, r.size // 20000)
    return {"kind": "feed_per_rev", "radius_mm": r[::step], "feed_um": f[::step] * MM_TO_UM,
            "title": f"{name}: feed per revolution against the radius"}


def _sample(n: int) -> np.ndarray:
    return np.arange(n) if n <= _CHECK_POINTS else np.linspace(0, n - 1, _CHECK_POINTS).astype(np.int64)


def program_checks(cfg: Any, surface: Any, path: ToolPath) -> dict:
    """What a CAM user checks of an imported turning program: ``feed_per_rev`` (table by
    radius; median, least and largest), ``chordal_error_max_nm`` (the chords' midpoints
    against the design, beyond the end points' own offsets), ``c_rate_max_rpm``, and
    ``findings``: points of cutting moves below the design (more than
    :data:`FINDING_TOLERANCE_MM`) and rapid moves (G00) through the part (ending below the
    design plus ``process.depth_of_cut`` inside the part's radius, other than a rise
    straight up), each with counts, the worst
    and the first file lines."""
    p = cfg.process
    theta, rho, z, t = (np.asarray(a, np.float64) for a in (path.theta, path.rho, path.z, path.t))
    lines = getattr(path, "program_lines", None)
    motion = getattr(path, "program_motion", None)
    if lines is None:
        lines = np.full(rho.size, -1, np.int64)
    if motion is None:
        motion = np.ones(rho.size, np.int8)
    out: dict[str, Any] = {}
    table = feed_per_rev_table(path)
    _, f = feed_per_rev(path)
    if f.size:
        out["feed_per_rev"] = {"median_um": float(np.median(f) * MM_TO_UM),
                               "min_um": float(f.min() * MM_TO_UM),
                               "max_um": float(f.max() * MM_TO_UM), "by_radius": table}
    if t.size > 1:
        dt = np.diff(t)
        ok = dt > 0
        rate = np.diff(theta)[ok] / dt[ok] * MIN_TO_S / (2 * math.pi)
        out["c_rate_max_rpm"] = float(rate.max()) if rate.size else 0.0
        out["c_rate_min_rpm"] = float(rate.min()) if rate.size else 0.0
    idx = _sample(rho.size)
    # where each point lies on the part (its angle the part's own: -theta for M04); the
    # C rate above is the spindle's speed
    theta = part_angle(path)
    x, y = rho[idx] * np.cos(theta[idx]), rho[idx] * np.sin(theta[idx])
    design = surface.height(x, y)
    off = z[idx] - design
    inside = np.abs(rho[idx]) <= float(p.workpiece_radius)
    # chords: midpoints of consecutive sampled points that are consecutive program points
    if idx.size > 1:
        cons = np.flatnonzero(np.diff(idx) == 1)
        if cons.size:
            i0 = idx[cons]
            tm, rm, zm = (0.5 * (a[i0] + a[i0 + 1]) for a in (theta, rho, z))
            dm = surface.height(rm * np.cos(tm), rm * np.sin(tm))
            e = (zm - dm) - 0.5 * (off[cons] + off[cons + 1])
            e = e[np.isfinite(e) & (motion[i0 + 1] > 0)]
            if e.size:
                out["chordal_error_max_nm"] = float(np.max(np.abs(e)) * MM_TO_NM)
    findings = []
    cutting = motion[idx] > 0
    below = inside & cutting & np.isfinite(off) & (off < -FINDING_TOLERANCE_MM)
    findings += _finding("below_design", "cutting moves end below the design", below, -off,
                         idx, lines, rho, theta)
    stock = float(getattr(p, "depth_of_cut", 0.0))
    # a rapid that only rises (a retract straight up from the cut) leaves the part
    prev = np.maximum(idx - 1, 0)
    rising = (z[idx] > z[prev]) & (np.abs(rho[idx] - rho[prev]) <= 1e-9)
    through = inside & ~cutting & ~rising & np.isfinite(off) & (off < stock)
    findings += _finding("rapid_through_part", "rapid moves (G00) end inside the part", through,
                         stock - off, idx, lines, rho, theta)
    out["findings"] = findings
    out["findings_count"] = int(sum(f["points"] for f in findings))
    return out


def _finding(kind: str, what: str, mask, depth, idx, lines, rho, theta) -> list[dict]:
    if not mask.any():
        return []
    sel = np.flatnonzero(mask)
    worst = int(sel[np.argmax(depth[sel])])
    first = sel[:_EXAMPLES]
    return [{"kind": kind, "what": what, "points": int(sel.size),
             "worst_nm": float(depth[worst] * MM_TO_NM),
             "worst_line": int(lines[idx[worst]]),
             "worst_radius_mm": float(rho[idx[worst]]),
             "worst_c_deg": float(math.degrees(theta[idx[worst]]) % 360.0),
             "first_lines": [int(lines[idx[k]]) for k in first]}]


def findings_summary(checks: dict) -> str:
    """One line: the findings of :func:`program_checks` (or that there are none)."""
    fs = checks.get("findings") or []
    if not fs:
        return "no move of the program ends below the design or inside the part"
    return "; ".join(f"{f['points']:,} points: {f['what']} (deepest {f['worst_nm']:.4g} nm at "
                     f"line {f['worst_line']}, radius {f['worst_radius_mm']:.4g} mm)" for f in fs)


def fit_paraboloid(paths: Sequence[ToolPath], *, nose_radius: float = 0.0) -> dict:
    """The paraboloid ``z = offset - r^2 / (2 R)`` (``design.type = "paraboloid"`` with
    ``radius_x = radius_y = R``) that fits the Z of turning programs best (least squares
    over every point of ``paths``, ToolPaths).  With ``nose_radius`` > 0 the programs' Z is
    taken as the tip of a Z-compensated nose, ``z = design + Rc (sqrt(1 + slope^2) - 1)``
    (solved by fixed-point iteration); 0 takes Z as the design itself.

    Returns ``radius_mm``, ``offset_mm``, ``rms_nm`` and ``max_nm`` (the residual of the
    fit) and ``points``."""
    r = np.concatenate([np.asarray(p.rho, np.float64) for p in paths])
    z = np.concatenate([np.asarray(p.z, np.float64) for p in paths])
    if r.size < 3:
        raise InputError(f"a paraboloid needs at least 3 program points, received {r.size}")
    a = np.c_[np.ones_like(r), r * r]
    comp = np.zeros_like(r)
    coef: Any = None  # (the least-squares coefficients: the loop runs at least once)
    for _ in range(20 if nose_radius > 0 else 1):
        coef, *_ = np.linalg.lstsq(a, z - comp, rcond=None)
        new = nose_radius * (np.sqrt(1 + (2 * coef[1] * r) ** 2) - 1) if nose_radius > 0 else comp
        if np.max(np.abs(new - comp)) < 1e-12:
            break
        comp = new
    res = z - comp - a @ coef
    if coef[1] == 0:
        raise InputError("the programs' Z does not change with the radius: no paraboloid fits")
    return {"radius_mm": float(-1.0 / (2.0 * coef[1])), "offset_mm": float(coef[0]),
            "rms_nm": float(np.sqrt(np.mean(res ** 2)) * MM_TO_NM),
            "max_nm": float(np.max(np.abs(res)) * MM_TO_NM), "points": int(r.size)}


def imported_sculpt_plan(process: Any, cfg: Any, surface: Any) -> Plan:
    """The plan of the X-Y-Z program of ``process.program`` for the sculpturing cut: its
    lines (runs of feed moves; each rapid starts the next) must each keep X constant and
    move along Y (the cut sweeps the edge along Y); of consecutive points over the same
    (X, Y) (a vertical plunge or retract) the lowest is kept."""
    prog, imp = imported_linear(cfg)
    x, y, z, line = (np.asarray(a) for a in (prog.x, prog.y, prog.z, prog.line))
    lines_of = imp.file_line
    keep = np.ones(x.size, bool)
    same = (np.diff(x) == 0) & (np.diff(y) == 0) & (np.diff(line) == 0)
    # of a run of points over one (X, Y), keep the lowest
    n = x.size
    starts = np.flatnonzero(np.r_[True, ~same])
    ends = np.r_[starts[1:], n]
    for a, b in zip(starts.tolist(), ends.tolist()):
        if b - a > 1:
            keep[a:b] = False
            keep[a + int(np.argmin(z[a:b]))] = True
    x, y, z, line, t, lines_of = x[keep], y[keep], z[keep], line[keep], prog.t[keep], lines_of[keep]
    for k in np.unique(line):
        sel = np.flatnonzero(line == k)
        if sel.size < 2:
            continue
        if np.ptp(x[sel]) > 1e-9:
            j = sel[np.flatnonzero(np.abs(x[sel] - x[sel[0]]) > 1e-9)[0]]
            raise InputError(f"{imp.path}:{int(lines_of[j])}: the sculpturing cut takes lines "
                             f"along Y at constant X; this line moves X from {x[sel[0]]:g} to "
                             f"{x[j]:g} mm")
        dy = np.diff(y[sel])
        if not (np.all(dy > 0) or np.all(dy < 0)):
            j = sel[1:][np.flatnonzero(dy == 0)[0]] if np.any(dy == 0) else sel[-1]
            raise InputError(f"{imp.path}:{int(lines_of[j])}: a sculpturing line must move Y "
                             f"one way (it turns back or stands still here)")
        if dy[0] < 0:  # the cut takes each line with Y increasing
            y[sel], z[sel] = y[sel][::-1], z[sel][::-1]
    _, line = np.unique(line, return_inverse=True)
    prog2 = LinearProgram(x, y, z, t, line.astype(np.int64), dict(prog.meta))
    plan = process.program_plan(cfg, surface, prog2)
    # the program's own blocks, timed from its F words (an arc one block), as a turning
    # program read from a file
    rate = block_rate(prog.t, lines=imp.file_line, limit=getattr(cfg.process, BLOCK_RATE_KEY, None),
                      advice=FILE_ADVICE)
    plan.facts["toolpath"] = {"points": int(prog2.points), "lines": int(prog2.lines),
                              "kind": "sculpt", "cut_time_s": float(plan.data.get("cut_time_s", 0.0)),
                              "block_rate": rate}
    plan.facts["program"] = dict(prog.meta.get("program", {}))
    return plan
