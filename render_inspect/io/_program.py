"""Machine programs written by others, read as the machine runs them
(:func:`read_program`): the tool path a lathe or a raster-cutting machine follows, with
what had to be inferred said in words.

Dialects (docs/programs.md):

* the two this project writes (``; render_inspect generic C-X-Z turning program`` and
  ``... X-Y-Z sculpturing program``), read with their own readers: exact to the written
  places;
* bare point lists, one ``C.. X.. Z..`` (any order) per line, C in degrees and wrapping
  every revolution, no feed or spindle words (the spindle speed comes from the scene);
* lathe G-code: X-Z moves (``G00`` .. ``G03``) while the spindle turns (C follows from
  the spindle speed, ``S`` under ``G97`` or ``G96``), or C-X-Z moves of a slow tool servo,
  with ``G90``/``G91``, ``G93``/``G94``/``G95`` feeds, ``G20``/``G21`` and ``G70``/``G71``
  units, ``U``/``W`` incremental words, comments, ``%``, ``O`` and ``N`` numbers; the
  spindle's M03 / M04 / M05 (:mod:`~render_inspect.io._program_spindle`);
* linear X-Y-Z programs of sculpturing / raster cutting.

Position and angle words without a decimal point are whole mm / inches / degrees, or
least input increments of an increment system (``integers``; see
:mod:`~render_inspect.io._program_integers`).

The words are read by :func:`~render_inspect.io._program_scan.scan_program` (streaming,
vectorised).  Every block it cannot read gets one line naming the file, the line, the
block and the word.
"""

from __future__ import annotations

from collections.abc import Callable
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import SPINDLE_KEY, LinearProgram, ToolPath
from ..core.units import MIN_TO_S, MM_TO_NM, M_TO_MM
from ._nc_dialect import UTF8_BOM, LINEAR_TITLE, TURNING_TITLE, is_own_title
from ._nc_parse import read_nc_lines, read_program_nc_lines
from ._special import not_a_file
from ._program_angles import c_move_times, unwrap_c
from ._program_kernel import feed_times, sample_moves
from ._program_arcs import expand_arcs as _expand_arcs
from ._program_integers import beyond_part_hint, check_integers, integers_facts
from ._program_scan import ScannedProgram, scan_program
from ._program_spindle import (HANDS, MIRROR, c_mode_note, c_way, own_spindle, spindle_of,
                               stopped_sentence)

__all__ = ["ImportedProgram", "read_program", "program_dialect", "RAPID_MM_PER_MIN",
           "ARC_TOLERANCE_MM", "X_MODES", "MAX_PROGRAM_POINTS"]

#: speed of the rapid moves (G00), mm/min: the programs do not say it, and it only sets
#: how long a rapid takes (the spindle turns meanwhile)
RAPID_MM_PER_MIN = 2000.0
#: largest distance of an arc's chords from the arc (G02 / G03 are cut as chords), mm
ARC_TOLERANCE_MM = 1e-6  # not a unit conversion
#: how X is read: as written ("auto": inferred from the part's size)
X_MODES = ("auto", "radius", "diameter")
#: the most points an imported turning path may have once the spindle's turning is
#: sampled (process.points_per_rev per revolution)
MAX_PROGRAM_POINTS = 200_000_000
#: how far back C (deg, as written) must step to be read as a new revolution: a shorter
#: step back is the spindle turning backwards
_WRAP_DEG = 180.0
#: moves whose C step the points per revolution is the median of (evenly spread)
_PPR_SAMPLE = 100_001


@dataclass
class ImportedProgram:
    """A program read from a file.

    Attributes
    ----------
    path : Path
    dialect : str
        ``"render_inspect turning"``, ``"render_inspect linear"``, ``"point list"``,
        ``"lathe G-code"`` (X-Z moves, the spindle turning), ``"C-X-Z G-code"`` or
        ``"linear G-code"``.
    program : ToolPath or LinearProgram
        What the machine follows (arcs as chords, the spindle's turning sampled).
    motion : (n,) int8
        The motion of the block each point ends (0 rapid, 1 linear, 2/3 arc).
    file_line : (n,) int64
        The file line of the block each point belongs to.
    inferred : dict
        What the program does not say and where it came from: name -> one sentence.
    facts : dict
        Counts and modes (blocks, motion blocks, G and M codes, notes; of a turning
        program ``spindle_direction``, ``"M03"`` or ``"M04"``).
    """

    path: Path
    dialect: str
    program: object
    motion: np.ndarray
    file_line: np.ndarray
    inferred: dict = field(default_factory=dict)
    facts: dict = field(default_factory=dict)

    @property
    def kind(self) -> str:
        return "linear" if isinstance(self.program, LinearProgram) else "turning"


def program_dialect(path: str | Path) -> str:
    """The dialect of ``path`` from its first line: ``"render_inspect turning"``,
    ``"render_inspect linear"`` (the title comment ``; ...`` or ``( ... )``, either comment
    style the project writes) or ``"G-code"`` (anything else: point lists and G-code are
    told apart once read).  A UTF-8 byte order mark before it (an editor's, saving the
    file again) does not matter."""
    with Path(path).open("rb") as fh:
        first = fh.readline(400).removeprefix(UTF8_BOM).decode("ascii", "replace").strip()
    style = is_own_title(first)
    if style is not None:
        body = first[2:] if style == "semicolon" else first[1:]
        if body.startswith(TURNING_TITLE):
            return "render_inspect turning"
        if body.startswith(LINEAR_TITLE):
            return "render_inspect linear"
    return "G-code"


def _check_path(path) -> Path:
    path = Path(path)
    why = not_a_file(path)
    if why is not None:
        raise InputError(f"process.program: {str(path)!r} {why}" if why != "not found"
                         else f"process.program: file not found: {str(path)!r}")
    return path


def read_program(path: str | Path, *, kind: str | None = None, spindle_rpm: float = 50.0,
                 feed_mm_per_min: float = 0.5, part_radius: float | None = None,
                 x_mode: str = "auto", points_per_rev: int = 3600,
                 design_height: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                 rapid_mm_per_min: float = RAPID_MM_PER_MIN,
                 spindle_source: str = "process.spindle_rpm",
                 feed_source: str = "process.feed_mm_per_min",
                 integers: str = "whole") -> ImportedProgram:
    """Read the machine program ``path`` (see the module docstring).

    Parameters
    ----------
    kind : {"turning", "linear"}, optional
        What the scene cuts; a program of the other kind is refused.
    spindle_rpm, feed_mm_per_min : float
        The spindle speed and feed where the program does not give them (named in
        ``inferred`` with ``spindle_source`` / ``feed_source``).
    part_radius : float, optional
        The part's radius, mm: whether X is a radius or a diameter is inferred from it.
    x_mode : {"auto", "radius", "diameter"}
    points_per_rev : int
        Points per revolution of the spindle where the program gives no C (an X-Z lathe
        program): the turning is sampled this finely.
    design_height : callable, optional
        ``height(x, y)`` of the design: decides between radius and diameter when the
        part's size allows both.
    integers : {"whole", "IS-A", "IS-B", "IS-C", "IS-D", "IS-E"}
        How position and angle words without a decimal point are read: whole mm, inches
        and degrees, or least input increments of the increment system (IS-B: X2000 is
        2 mm); an F word without one is then refused.  The project's own dialects always
        write decimals and are read as written.  What was read is ``inferred["integers"]``
        (where it matters), a program read whole that writes such words has a warning in
        ``facts["warnings"]``.
    """
    path = _check_path(path)
    if x_mode not in X_MODES:
        raise InputError(f"process.program_x must be one of {list(X_MODES)}, received {x_mode!r}")
    check_integers(integers)
    dialect = program_dialect(path)
    prog: ToolPath | LinearProgram
    if dialect == "render_inspect turning":
        prog, file_line = read_nc_lines(path)
        out = ImportedProgram(path, dialect, prog, np.ones(prog.points, np.int8), file_line,
                              {"x": "X is the radius (the project's own dialect)",
                               "time": "time from the inverse-time F words (G93)",
                               **own_spindle(prog)}, {"points": prog.points})
        out.facts[SPINDLE_KEY] = HANDS[4 if prog.meta.get(SPINDLE_KEY) == "M04" else 3]
    elif dialect == "render_inspect linear":
        prog, file_line = read_program_nc_lines(path)
        out = ImportedProgram(path, dialect, prog, np.ones(prog.points, np.int8), file_line,
                              {"time": "time from the F words (mm/min) along the lines"},
                              {"points": prog.points})
    else:
        sp = scan_program(path, integers=integers)
        if sp.count == 0:
            raise InputError(f"{path}: no motion blocks (no X, Y, Z or C words) found")
        if sp.written["Y"].any():
            if sp.written["C"].any():
                k = int(np.flatnonzero(sp.written["C"])[0])
                raise InputError(f"{path}:{int(sp.line[k])}: a program with both Y and C words; "
                                 f"the reader takes C-X-Z (turning) or X-Y-Z (raster) programs")
            out = _linear(sp, feed_mm_per_min, rapid_mm_per_min, feed_source)
        else:
            out = _turning(sp, spindle_rpm=spindle_rpm, feed=feed_mm_per_min,
                           part_radius=part_radius, x_mode=x_mode, ppr=points_per_rev,
                           design_height=design_height, rapid=rapid_mm_per_min,
                           spindle_source=spindle_source, feed_source=feed_source)
        said, warnings = integers_facts(sp, integers)
        if said is not None:  # (a program that writes every number with its point at the
            out.inferred["integers"] = said     # default reading: nothing to say)
            out.facts["integers"] = integers
        if warnings:
            out.facts["warnings"] = warnings
    if kind is not None and out.kind != kind:
        what = {"turning": "a turning (C-X-Z or X-Z) program",
                "linear": "a linear X-Y-Z program"}
        raise InputError(f"process.program: {path} is {what[out.kind]}, and the scene's "
                         f"process cuts {what[kind].split(' ', 1)[1]}")
    return out


# ---------------------------------------------------------------------------- turning
def _x_mode(sp, x, cut, part_radius, x_mode, design_height, z, x_unit):
    """("radius" or "diameter", the sentence saying why); ``x_unit``: the unit each X was
    written in (:attr:`ScannedProgram.x_unit`)."""
    if x_mode != "auto":
        return x_mode, f"X is the {x_mode}, as process.program_x says"
    far = np.flatnonzero(cut) if cut.any() else np.arange(x.size)
    far = int(far[np.argmax(np.abs(x[far]))])
    big = abs(float(x[far]))
    if part_radius is None:
        return "radius", "X is read as the radius (no part size to infer it from)"
    r = float(part_radius)
    if big > 3 * r:
        raise InputError(f"{sp.path}: the cutting moves reach X = {big:g} mm, beyond the part "
                         f"(radius {r:g} mm) as a radius and as a diameter; check the program "
                         f"or process.workpiece_radius (process.program_x sets how X is read)"
                         + beyond_part_hint(sp, sp.integers, big, 3 * r, int(x_unit[far])))
    if big > 1.5 * r:
        return "diameter", (f"X is the diameter: the cutting moves reach X = {big:g} mm, and "
                            f"the part's radius is {r:g} mm (process.program_x = 'radius' "
                            f"reads it as the radius)")
    if big <= 0.75 * r and design_height is not None and cut.sum() >= 3:
        sel = np.flatnonzero(cut)
        sel = sel[:: max(1, sel.size // 2000)]
        errs = {}
        for mode, scale in (("radius", 1.0), ("diameter", 0.5)):
            dz = z[sel] - design_height(x[sel] * scale, np.zeros(sel.size))
            errs[mode] = float(np.std(dz[np.isfinite(dz)])) if np.isfinite(dz).any() else math.inf
        best = min(errs, key=errs.get)
        return best, (f"X is the {best}: both readings fit the part (largest X {big:g} mm, "
                      f"part radius {r:g} mm), and Z follows the design better so (Z - design "
                      f"varies by {errs[best] * MM_TO_NM:.4g} nm as {best}, "
                      f"{errs['diameter' if best == 'radius' else 'radius'] * MM_TO_NM:.4g} nm "
                      f"otherwise; process.program_x sets it)")
    return "radius", (f"X is the radius: the cutting moves reach X = {big:g} mm, within the "
                      f"part's radius {r:g} mm (process.program_x = 'diameter' reads it as the "
                      f"diameter)")


def _turning(sp: ScannedProgram, *, spindle_rpm, feed, part_radius, x_mode, ppr,
             design_height, rapid, spindle_source, feed_source) -> ImportedProgram:
    path = sp.path
    has_c = bool(sp.written["C"].any())
    known = ~np.isnan(sp.axes["X"]) & ~np.isnan(sp.axes["Z"])
    if has_c:
        known &= ~np.isnan(sp.axes["C"])
    if not known.any():
        need = "X, Z and C" if has_c else "X and Z"
        inc = (" (incremental moves, G91 or U / W, need a start written in absolute, G90, "
               "first)" if 91 in sp.g_codes or sp.words & {"U", "W", "H"} else "")
        raise InputError(f"{path}: no block places the tool: {need} are never all known{inc}")
    first = int(np.argmax(known))
    # the usual program places the tool in every block from the first on: its columns are
    # read through views (``span``), not gathered
    whole = bool(known[first:].all())
    rows = np.arange(first, known.size) if whole else np.flatnonzero(known)
    span = slice(first, None) if whole else rows
    del known
    inferred = {}
    x = sp.axes["X"][span].copy()
    z = sp.axes["Z"][span].copy()
    motion = sp.motion[span]
    cut = motion >= 1
    mode, why = _x_mode(sp, x, cut, part_radius, x_mode, design_height, z, sp.x_unit[span])
    inferred["x"] = why
    if mode == "diameter":
        x *= 0.5
    axes = {"X": x, "Z": z}
    if has_c:
        axes["C"] = sp.axes["C"][span].copy()
    arcs = motion >= 2
    if arcs.any() and np.any(sp.plane[span][arcs] != 18):
        k = int(rows[np.flatnonzero(arcs & (sp.plane[span] != 18))[0]])
        raise InputError(f"{path}:{int(sp.line[k])}: an arc outside the Z-X plane (G17 / G19) "
                         f"in a turning program; select G18")
    del arcs
    # arcs in the Z-X plane (G18): Z to the right, X up; I and K from the start, in radius
    src, axes, frac = _expand_arcs(sp, rows, axes, ("Z", "X"), ("K", "I"), ARC_TOLERANCE_MM,
                                   motion=motion)
    if src is None:
        blk = rows
    else:
        blk = span = rows[src]
        motion = sp.motion[blk]
    x, z = axes["X"], axes["Z"]
    # M03 / M04 / M05: the spindle's direction while the program cuts, the moves it
    # stands in (a program with C words turns C by its words)
    spindle = None if has_c else spindle_of(sp, span, motion)
    stopped = None if spindle is None else spindle.stopped
    fmode = sp.feed_mode[span]
    has_f = bool(np.isfinite(sp.feed).any())
    # without F words the modal feed is NaN throughout (a view: no copy per block)
    fval = sp.feed[span] if has_f else np.broadcast_to(np.float64(math.nan), blk.shape)
    # ---- the spindle
    css = sp.spindle_mode[span] == 96
    if np.isfinite(sp.spindle).any() or css.any():
        s_prog = sp.spindle[span]
        base = np.where(np.isfinite(s_prog) & ~css, s_prog, float(spindle_rpm))
        if css.any():
            clampv = np.where(np.isfinite(sp.clamp_rpm[span]), sp.clamp_rpm[span],
                              float(spindle_rpm))
        else:  # the clamp only acts under constant surface speed
            clampv = np.broadcast_to(np.float64(spindle_rpm), blk.shape)
    else:  # no S anywhere: the scene's speed everywhere (views, no memory)
        s_prog = np.broadcast_to(np.float64(math.nan), blk.shape)
        clampv = base = np.broadcast_to(np.float64(spindle_rpm), blk.shape)
    held = ~css & np.isfinite(sp.held[span]) if np.isfinite(sp.held).any() else None
    if np.isfinite(s_prog).any():
        rpm_words = ~css if held is None else ~css & ~held
        inferred["spindle"] = "spindle speed from the program's S words" + _stated(
            s_prog[rpm_words] if rpm_words.any() else s_prog[:0], "rpm (G97)", ": ")
        if (~np.isfinite(s_prog)).any():
            inferred["spindle"] += (f" ({spindle_source} = {spindle_rpm:g} rpm before the "
                                    f"first S)")
    else:
        inferred["spindle"] = f"spindle speed {spindle_rpm:g} rpm from {spindle_source}"
    if css.any():
        inferred["spindle"] += (" ; constant surface speed (G96" + _stated(s_prog[css], "m/min", ", S ")
                                + ") below the clamp (G50 S, or "
                                f"{spindle_source} where the program sets none)")
    if held is not None and held.any():
        base, why = _held_rpm(held, s_prog, sp.clamp_rpm[span], x, base, float(spindle_rpm))
        inferred["spindle"] += why
    del held
    if stopped is not None:  # M05: the spindle stands in those moves (rapids only)
        base = np.where(stopped, 0.0, base)

    any_css = bool(css.any())

    def spin(r, i):
        """rpm of the moves ``i`` at radius ``r``."""
        if not any_css:
            return base[i]
        v = _css_rpm(s_prog[i], clampv[i], r, css[i], base[i])
        return v if stopped is None else np.where(stopped[i], 0.0, v)

    # ---- time of each move (from the point before)
    length = np.hypot(np.diff(x), np.diff(z))
    down = False
    if has_c:
        # C decreasing: the spindle turning the other way (as M04), read on as -C
        down = c_way(axes["C"], sp, blk, _WRAP_DEG)
        # C wraps every revolution: each step taken modulo 360 where it falls, summed
        dc, c_cum, n_neg, first_neg = unwrap_c(axes["C"])
        if n_neg > dc.size // 2:
            k = int(blk[1:][first_neg])
            raise InputError(f"{path}:{int(sp.line[k])}: C steps back by {_WRAP_DEG:g} deg or "
                             f"more in most of its moves: which way the spindle turns cannot be "
                             f"told from C's wraps; write C in smaller steps")
        del axes["C"]  # C as written: its unwrapped sum is what the path needs
        if n_neg:
            inferred["c"] = (f"C wraps at 360 deg ({n_neg} times): it is read as "
                             f"turning on")
        if down:
            inferred["c"] = (inferred.get("c", "C") + (" ; " if n_neg else " ") +
                             "decreases: the spindle turns the other way (as M04); " + MIRROR)
        note = c_mode_note(sp.m_codes, down)
        if note is not None:
            sp.notes.append(note)
    else:
        dc = None
        if spindle is not None and spindle.said:
            inferred["spindle"] += spindle.said
    fm, fv, mo = fmode[1:], fval[1:], motion[1:]
    # one speed throughout without constant surface speed: a view of the moves' speeds
    rp = spin(0.5 * (x[1:] + x[:-1]), np.arange(1, x.size)) if any_css else base[1:]
    if has_f:
        # G93 / G94 / G95 by the move, the scene's feed before the first F, rapids
        dt, missing, any_rapid = feed_times(length, fm, fv, mo, rp, float(feed), float(rapid))
        if missing:
            inferred["feed"] = f"feed {feed:g} mm/min from {feed_source} before the first F"
        else:
            inferred["feed"] = "feed from the program's F words"
        stated = [_stated(fv[(fm == m) & (mo > 0)], unit, "") for m, unit in (
            (94, "mm/min (G94)"), (95, "mm/rev (G95)"), (93, "per min (inverse time, G93)"))]
        if any(stated):
            inferred["feed"] += ": " + ", ".join(t for t in stated if t) + (
                " (the program's inches converted to mm)" if sp.g_codes & {20, 70} else "")
        if dc is not None:  # (has_c) a move cannot turn C faster than the spindle allows
            dt, _ = c_move_times(dc, length, mo, rp, float(feed), float(rapid), dt)
    elif dc is not None:  # (has_c)
        # C at the spindle speed, moves without C at the scene's feed, rapids; never
        # faster than the spindle turns C
        dt, any_rapid = c_move_times(dc, length, mo, rp, float(feed), float(rapid),
                                     np.empty(0))
        inferred["time"] = (f"no F words: time from C and the spindle speed (C turns at "
                            f"{spindle_rpm:g} rpm from {spindle_source}); moves without C "
                            f"at {feed:g} mm/min from {feed_source}")
    else:
        dt = np.full(length.size, math.nan)
        rapid_mask = mo == 0
        any_rapid = bool(rapid_mask.any())
        dt[~rapid_mask] = length[~rapid_mask] / float(feed) * MIN_TO_S
        inferred["feed"] = f"no F words: feed {feed:g} mm/min from {feed_source}"
        dt[rapid_mask] = length[rapid_mask] / float(rapid) * MIN_TO_S
        del rapid_mask
    if any_rapid:
        inferred["rapid"] = (f"rapids (G00) at {rapid:g} mm/min (the program does not say "
                             f"the machine's rapid rate)")
    endless = np.isinf(dt)
    if endless.any():  # F0 (or G95 with the spindle at S0): the move never ends
        k = int(blk[1:][np.flatnonzero(endless)[0]])
        raise InputError(f"{path}:{int(sp.line[k])}: the move never ends: the feed in force "
                         f"is 0 (F must be > 0, or the spindle speed > 0 under G95)")
    del endless
    if stopped is not None:  # the time the spindle stands, and how it is counted
        inferred["spindle"] += stopped_sentence(stopped[1:], dt, sp.line[blk[1:][stopped[1:]]])
    zero = ~(dt > 0)
    any_zero = bool(zero.any())
    if any_zero:  # points the tool does not leave (a repeated block)
        bad = zero & (length > 0)
        if bad.any():
            k = int(blk[1:][np.flatnonzero(bad)[0]])
            raise InputError(f"{path}:{int(sp.line[k])}: the move takes no time (F or the "
                             f"spindle speed is 0)")
    del length, fm, fv, mo, rp, dc
    if any_zero:
        keep = np.r_[True, ~zero]
        sel = np.flatnonzero(keep)
        x, z, blk, motion, dt_k = x[sel], z[sel], blk[sel], motion[sel], dt[sel[1:] - 1]
        s_prog, css, clampv, base = s_prog[sel], css[sel], clampv[sel], base[sel]
        if stopped is not None:
            stopped = stopped[sel]
        if has_c:
            c_cum = c_cum[sel]
    else:  # every point kept (the usual case): no copies
        dt_k = dt
    del dt, zero
    if has_c:
        t = np.empty(dt_k.size + 1)
        t[0] = 0.0
        np.cumsum(dt_k, out=t[1:])
        theta = np.radians(c_cum)
        del c_cum
        dialect = "point list" if not has_f and not sp.g_codes else "C-X-Z G-code"
    else:
        # the spindle turns while X and Z move: C follows from the time, each move sampled
        # at points_per_rev per revolution
        rp_k = spin(0.5 * (x[1:] + x[:-1]), np.arange(1, x.size)) if any_css else base[1:]
        revs = rp_k * dt_k / MIN_TO_S
        n_sub = np.maximum(1, np.ceil(revs * ppr)).astype(np.int64)
        total = int(n_sub.sum()) + 1
        if total > MAX_PROGRAM_POINTS:
            raise InputError(f"{path}: sampling the spindle's {float(revs.sum()):.4g} revolutions "
                             f"at process.points_per_rev = {ppr} gives {total:,} points (at most "
                             f"{MAX_PROGRAM_POINTS:,}); lower process.points_per_rev")
        if not any_css and n_sub.min() >= 1:
            # one spindle speed a move: every step's point, time and angle in one pass
            x, z, t, theta, blk, motion = sample_moves(x, z, dt_k, n_sub, rp_k, blk, motion,
                                                       total)
        else:
            seg = np.repeat(np.arange(n_sub.size), n_sub)
            u = (np.arange(seg.size) - np.repeat(np.cumsum(n_sub) - n_sub, n_sub) + 1) / n_sub[seg]
            xs = x[seg] + (x[seg + 1] - x[seg]) * u
            zs = z[seg] + (z[seg + 1] - z[seg]) * u
            dts = dt_k[seg] / n_sub[seg]
            # the spindle speed at each step's middle; a feed per revolution (G95) under
            # constant surface speed sets each step's time from it
            xm = xs - 0.5 * (x[seg + 1] - x[seg]) / n_sub[seg]
            rpm_s = spin(xm, seg + 1)
            bk = blk[1:][seg]
            g95 = (sp.feed_mode[bk] == 95) & (motion[1:][seg] > 0) & css[seg + 1]
            if g95.any():
                step = np.hypot(x[seg + 1] - x[seg], z[seg + 1] - z[seg]) / n_sub[seg]
                with np.errstate(divide="ignore"):  # (a standing spindle's rapids: not G95)
                    dts = np.where(g95, step / (sp.feed[bk] * rpm_s) * MIN_TO_S, dts)
            ts = np.cumsum(dts)
            theta = np.r_[0.0, np.cumsum(2 * math.pi * rpm_s / MIN_TO_S * dts)]
            x, z, t = np.r_[x[0], xs], np.r_[z[0], zs], np.r_[0.0, ts]
            blk = np.r_[blk[0], blk[1:][seg]]
            motion = np.r_[motion[0], motion[1:][seg]]
        dialect = "lathe G-code"
        inferred["c"] = (f"C from the spindle's turning, sampled at {ppr} points per "
                         f"revolution (process.points_per_rev)")
    meta = {"source": path.name, "dialect": dialect, "x_mode": mode,
            "sampling": "program", "compensation": "as programmed",
            "points_per_rev": ppr if not has_c else _points_per_rev(theta)}
    hand = 4 if down or (spindle is not None and spindle.direction == 4) else 3
    if hand == 4:  # the path turns on (theta increases), the part's angle is -theta
        meta[SPINDLE_KEY] = "M04"
    prog = ToolPath(theta, x, z, t, meta)
    facts = {"blocks": sp.blocks, "motion_blocks": sp.count, "lines": sp.lines,
             "g_codes": sorted(sp.g_codes), "m_codes": sorted(sp.m_codes), "notes": sp.notes,
             SPINDLE_KEY: HANDS[hand]}
    line = sp.line[span] if blk is rows else sp.line[blk]
    return ImportedProgram(path, dialect, prog, motion.astype(np.int8, copy=False),
                           line.astype(np.int64, copy=False), inferred, facts)


def _stated(v: np.ndarray, unit: str, lead: str = " ") -> str:
    """`` 0.004 .. 0.005 mm/rev``: the least and largest of the values ``v`` as the
    program states them (NaN: none stated; "" where there is none)."""
    v = v[np.isfinite(v)]
    if v.size == 0:
        return ""
    lo, hi = float(v.min()), float(v.max())
    return f"{lead}{lo:.6g} {unit}" if lo == hi else f"{lead}{lo:.6g} .. {hi:.6g} {unit}"


def _points_per_rev(theta: np.ndarray) -> int | None:
    """The program's points per revolution: 360 deg over the median C step of the moves
    that turn C (None where none does)."""
    if theta.size < 2:
        return None
    i = np.unique(np.linspace(0, theta.size - 2, min(theta.size - 1, _PPR_SAMPLE)).astype(np.int64))
    d = theta[i + 1] - theta[i]   # (evenly spread moves: no copy of the path)
    d = d[d > 0]
    return int(round(2 * math.pi / float(np.median(d)))) if d.size else None


def _held_rpm(held, s_prog, clamp, x, base, spindle_rpm):
    """The spindle speed of the moves after G97 without S that follows G96: the speed the
    spindle had at the switch (the surface speed ``s_prog`` at the radius where the tool
    stood, below the clamp), kept until the next S.  Returns (speeds, sentence)."""
    base = np.array(base, dtype=np.float64)
    idx = np.flatnonzero(held)
    starts = idx[np.r_[True, np.diff(idx) > 1]]
    run = np.searchsorted(starts, idx, side="right") - 1
    at = np.maximum(starts - 1, 0)   # the tool's place when G97 came
    cl = np.where(np.isfinite(clamp[starts]), clamp[starts], spindle_rpm)
    rpm = _css_rpm(s_prog[starts], cl, x[at], np.ones(starts.size, bool), cl)
    base[idx] = rpm[run]
    speeds = ", ".join(f"{v:.6g}" for v in rpm[:3]) + (" ..." if rpm.size > 3 else "")
    return base, (f" ; after G97 without S the spindle keeps the speed it had under G96 at "
                  f"the switch ({speeds} rpm)")


def _css_rpm(s, clamp, r, css, rpm):
    """The spindle speed of constant surface speed ``s`` (m/min) at radius ``r`` (mm),
    clamped; ``rpm`` where ``css`` is off."""
    surface = np.where(np.isfinite(s), s, 0.0) * M_TO_MM / (2 * math.pi)
    return np.where(css, np.minimum(clamp, surface / np.maximum(np.abs(r), 1e-9)), rpm)


# ---------------------------------------------------------------------------- linear
def _linear(sp: ScannedProgram, feed, rapid, feed_source) -> ImportedProgram:
    path = sp.path
    known = ~np.isnan(sp.axes["X"]) & ~np.isnan(sp.axes["Y"]) & ~np.isnan(sp.axes["Z"])
    if not known.any():
        raise InputError(f"{path}: no block places the tool: X, Y and Z are never all known")
    rows = np.flatnonzero(known)
    rows = rows[rows >= rows[0]]
    axes = {a: sp.axes[a][rows].copy() for a in "XYZ"}
    plane = int(sp.plane[rows[np.flatnonzero(sp.motion[rows] >= 2)[0]]]) \
        if np.any(sp.motion[rows] >= 2) else 17
    pa = {17: (("X", "Y"), ("I", "J")), 18: (("Z", "X"), ("K", "I")),
          19: (("Y", "Z"), ("J", "K"))}[plane]
    src, axes, _ = _expand_arcs(sp, rows, axes, pa[0], pa[1], ARC_TOLERANCE_MM)
    blk = rows if src is None else rows[src]
    x, y, z = axes["X"], axes["Y"], axes["Z"]
    motion = sp.motion[blk]
    length = np.sqrt(np.diff(x) ** 2 + np.diff(y) ** 2 + np.diff(z) ** 2)
    fm, fv, mo = sp.feed_mode[blk][1:], sp.feed[blk][1:], motion[1:]
    inferred = {}
    fv = np.where(np.isfinite(fv), fv, float(feed))
    if np.isfinite(sp.feed).all():
        inferred["feed"] = "feed from the program's F words"
    else:
        inferred["feed"] = f"feed {feed:g} mm/min from {feed_source} where the program gives no F"
    if np.any((fm == 95) & (mo > 0)):
        k = int(blk[1:][np.flatnonzero((fm == 95) & (mo > 0))[0]])
        raise InputError(f"{path}:{int(sp.line[k])}: feed per revolution (G95 / G99) in an X-Y-Z "
                         f"program (no spindle turns); use G94 or G93")
    dt = np.where(fm == 93, MIN_TO_S / fv, length / fv * MIN_TO_S)
    dt = np.where(mo == 0, length / float(rapid) * MIN_TO_S, dt)
    t = np.r_[0.0, np.cumsum(dt)]
    # a line: a run of feed moves; each rapid starts the next one at its end point
    line = np.r_[0, np.cumsum(mo == 0)].astype(np.int64)
    _, line = np.unique(line, return_inverse=True)
    meta = {"source": path.name, "dialect": "linear G-code", "feed_mm_per_min": float(feed)}
    prog = LinearProgram(x, y, z, t, line.astype(np.int64), meta)
    facts = {"blocks": sp.blocks, "motion_blocks": sp.count, "lines": sp.lines,
             "g_codes": sorted(sp.g_codes), "m_codes": sorted(sp.m_codes), "notes": sp.notes}
    return ImportedProgram(path, "linear G-code", prog, motion.astype(np.int8),
                           sp.line[blk].astype(np.int64), inferred, facts)
