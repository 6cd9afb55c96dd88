"""The measured cutting edge of a round-nosed diamond: a nose whose radius varies along the
edge, r(theta) = Rc + delta(theta).

theta is the angle along the edge from the tool axis (0 at the tip, the lowest point of
the nose), positive towards +X of the tool (away from the spindle axis on a turning
path).  A point of the edge sits at (x, z) = (r sin theta, Rc - r cos theta) from the
programmed tool tip: the nominal nose centre stays Rc above the tip, so the edge's
deviation at the tip, delta(0), moves the cutting point itself.

A tool tracing a surface of slope angle theta touches it where the edge's normal is the
surface's, at theta on the edge, so a deviation delta(theta) moves the cut surface by
-delta(theta) along its normal (-delta / cos(theta) in Z): the form error tool-edge
waviness imprints (Gong, Ehmann et al. on waviness-compensated diamond turning; see
docs/references.md).

The edge comes from a file that a tool-edge measurement exports (:func:`read_edge_file`)
or from harmonics (:func:`EdgeProfile.from_harmonics`).  The kernels read it as a table
of the nose's height over the radial offset from the tool axis
(:meth:`EdgeProfile.height_table`): the circular arc's height Rc - sqrt(Rc^2 - d^2) plus
the tabulated difference, linearly interpolated.
"""

from __future__ import annotations

from collections.abc import Sequence
import functools
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.errors import InputError
from ..core.units import MM_TO_NM, MM_TO_UM, NM_TO_MM, UM_TO_MM

__all__ = ["EdgeProfile", "read_edge_file", "edge_of", "edge_notes", "NO_EDGE", "TABLE_POINTS",
           "EDGE_UNITS", "MIN_WAVINESS_PERIOD_DEG"]

#: the empty edge table: a circular nose (the kernels' circle, bit for bit)
NO_EDGE = np.zeros(0)
#: points of the kernels' height table over the nose's radial width
TABLE_POINTS = 8193
#: length units a column header may name (suffix -> mm per unit)
EDGE_UNITS = {"nm": NM_TO_MM, "um": UM_TO_MM, "mm": 1.0}
#: angle units a column header may name (suffix -> rad per unit)
ANGLE_UNITS = {"deg": math.pi / 180.0, "rad": 1.0}
#: shortest waviness period (deg): the kernels' table (:data:`TABLE_POINTS` over at most
#: the nose's diameter) keeps at least 35 points in it, the harmonics' samples 64
MIN_WAVINESS_PERIOD_DEG = 0.5
#: the harmonics' sampling (deg) where every period is 64 samples long or more
_HARMONIC_STEP_DEG = 0.05
#: angle (rad) by which the cut may pass the measured part of the edge unremarked
_COVER_TOLERANCE = math.radians(0.01)
#: largest |deviation| an edge may have, as a fraction of the nose radius (the kernels'
#: table assumes the edge stays a graph over the radial offset)
MAX_DEVIATION_FRACTION = 0.01
#: largest edge file read (a measured edge is a few thousand lines)
MAX_EDGE_BYTES = 16 * 1024 * 1024


@dataclass(frozen=True)
class EdgeProfile:
    """A measured (or modelled) cutting edge: the deviation ``delta`` (mm) of the nose
    radius at the angles ``angle`` (rad, increasing) along the edge.  Between the samples
    the deviation is linear; beyond them it keeps the end values.

    Attributes
    ----------
    angle : (n,) float64, rad
    delta : (n,) float64, mm
    source : str
        Where the edge comes from (a file, or the harmonics), for the outputs.
    fitted_radius : float or None
        mm: the radius of the circle fitted to an (x, z) edge file.
    measured : (float, float) or None
        rad: the angles the measurement covers (beyond them the deviation is held at its
        end values); None: the whole edge (the harmonics, or the table itself).
    """

    angle: np.ndarray
    delta: np.ndarray
    source: str = ""
    fitted_radius: float | None = None
    measured: tuple[float, float] | None = None

    @property
    def covers(self) -> tuple[float, float]:
        """The angles (rad) the edge was measured over: the table's, or the file's
        within a sum with harmonics."""
        if self.measured is not None:
            return self.measured
        return float(self.angle[0]), float(self.angle[-1])

    def deviation(self, theta: np.ndarray | float) -> np.ndarray:
        """delta(theta), mm."""
        return np.interp(np.asarray(theta, dtype=np.float64), self.angle, self.delta)

    @classmethod
    def from_harmonics(cls, harmonics: Sequence[Sequence[float]], *, span_deg: float = 180.0,
                       samples: int = 7201) -> "EdgeProfile":
        """delta(theta) = sum_k a_k cos(2 pi theta / P_k + phi_k) from (a_k nm, P_k degrees,
        phi_k degrees) triples, sampled 64 times per period at least (every 0.05 deg for
        periods of 3.2 deg or more)."""
        for k, (_, period_deg, _) in enumerate(harmonics):
            if not period_deg >= MIN_WAVINESS_PERIOD_DEG:
                raise InputError(f"tool.waviness[{k}] period must be >= {MIN_WAVINESS_PERIOD_DEG:g} deg "
                                 f"(the cut resolves the edge no finer), received {period_deg:g}")
        p_min = min((float(h[1]) for h in harmonics), default=360.0)
        if p_min / 64 < _HARMONIC_STEP_DEG:
            samples = max(samples, int(math.ceil(2 * span_deg / (p_min / 64))) + 1)
        th = np.linspace(-math.radians(span_deg), math.radians(span_deg), samples)
        d = np.zeros_like(th)
        for a_nm, period_deg, phase_deg in harmonics:
            d += a_nm * NM_TO_MM * np.cos(2 * math.pi * th / math.radians(period_deg) + math.radians(phase_deg))
        text = ", ".join(f"{a:g} nm per {p:g} deg" for a, p, _ in harmonics)
        return cls(th, d, source=f"waviness {text}")

    def scaled(self, factor: float) -> "EdgeProfile":
        """The same edge with the deviation times ``factor``."""
        return EdgeProfile(self.angle, self.delta * float(factor), self.source, self.fitted_radius,
                           self.measured)

    def within(self, half_angle: float) -> np.ndarray:
        """The deviations (mm) at the samples within +-half_angle (rad) and at its ends."""
        th = np.concatenate([[-half_angle, half_angle],
                             self.angle[np.abs(self.angle) <= half_angle]])
        return self.deviation(th)

    def pv_nm(self, half_angle: float) -> float:
        """Peak-to-valley deviation (nm) over +-half_angle (rad)."""
        d = self.within(half_angle)
        return float((d.max() - d.min()) * MM_TO_NM)

    def check(self, nose_radius: float, half_width: float, *, what: str | None = None,
              points: int = TABLE_POINTS) -> None:
        """Refuse, in one line (:class:`InputError`), an edge the cut cannot take with a nose
        of ``nose_radius`` (mm) over the radial half-width ``half_width`` (mm): a largest
        |deviation| beyond :data:`MAX_DEVIATION_FRACTION` of the nose radius, or an edge that
        folds back over the radial offset.  ``what`` names the edge in the message (the
        scene keys it comes from); by default its source.  Called before a run, and again by
        :meth:`height_table` (of ``points`` points)."""
        Rc = float(nose_radius)
        hw = min(float(half_width), Rc)
        what = what or f"tool edge ({self.source})"
        if self.delta.size:
            k = int(np.argmax(np.abs(self.delta)))
            dmax = abs(float(self.delta[k]))
            if dmax > MAX_DEVIATION_FRACTION * Rc:
                raise InputError(f"{what}: |deviation| must be <= {MAX_DEVIATION_FRACTION * Rc * MM_TO_NM:g} nm "
                                 f"({MAX_DEVIATION_FRACTION * 100:g} % of tool.nose_radius = {Rc:g} mm: the "
                                 f"cut takes the edge as a graph over the radial offset), received "
                                 f"{dmax * MM_TO_NM:.6g} nm (the largest, at "
                                 f"{math.degrees(float(self.angle[k])):.4g} deg)")
        # the edge point by point, a little beyond the arc's half-width
        th_max = math.asin(min(hw / Rc, 1.0))
        th_hi = min(th_max * 1.05 + 0.01, math.pi / 2)
        th = np.linspace(-th_hi, th_hi, 4 * points + 1)
        x = (Rc + self.deviation(th)) * np.sin(th)
        fold = np.flatnonzero(np.diff(x) <= 0)
        if fold.size:
            raise InputError(f"{what}: the edge folds back over the radial offset at "
                             f"{math.degrees(float(th[int(fold[0])])):.4g} deg (its deviation changes "
                             f"faster than the nose turns); a measured edge must be a smooth graph "
                             f"over the angle within the nose arc (+-{math.degrees(th_hi):.4g} deg)")

    def height_table(self, nose_radius: float, half_width: float, points: int = TABLE_POINTS) -> np.ndarray:
        """The kernels' table: [d0, 1 / step, lowest entry (<= 0), g_0 .. g_(points-1)] with
        g(d) the height (mm) of the edge above the circular arc Rc - sqrt(Rc^2 - d^2) at the
        radial offset d = d0 + i step, d0 = -half_width .. +half_width."""
        Rc = float(nose_radius)
        hw = min(float(half_width), Rc)
        self.check(Rc, hw, points=points)
        # the angle of the edge point at each offset d: (Rc + delta(t)) sin t = d, by fixed
        # point from the circle's angle (a contraction: |delta'| tan t << Rc)
        d = np.linspace(-hw, hw, points)
        t = np.arcsin(np.clip(d / Rc, -1.0, 1.0))
        for _ in range(8):
            t = np.arcsin(np.clip(d / (Rc + self.deviation(t)), -1.0, 1.0))
        # its height above the circle's point at d: Rc cos(t0) - r cos(t)
        g = np.sqrt(np.maximum(Rc * Rc - d * d, 0.0)) - (Rc + self.deviation(t)) * np.cos(t)
        step = (2 * hw) / (points - 1)
        return np.concatenate([[-hw, 1.0 / step, min(float(g.min()), 0.0)], g])

    def to_dict(self, half_angle: float | None = None) -> dict:
        """The edge for ``metrics.json``."""
        out = {"source": self.source, "samples": int(self.angle.size),
               "angle_range_deg": [math.degrees(float(self.angle[0])), math.degrees(float(self.angle[-1]))],
               "deviation_pv_nm": float((self.delta.max() - self.delta.min()) * MM_TO_NM),
               "deviation_rms_nm": float(np.sqrt(np.mean(self.delta ** 2)) * MM_TO_NM),
               "measured_range_deg": [math.degrees(a) for a in self.covers]}
        if half_angle is not None:
            out["engaged_pv_nm"] = self.pv_nm(half_angle)
        if self.fitted_radius is not None:
            out["fitted_radius_mm"] = float(self.fitted_radius)
        return out


# ------------------------------------------------------------------ edge files
_HEADER = re.compile(r"^\s*([A-Za-z]+)(?:\s*[_\[\(/ ]+\s*([A-Za-z\u00b5\u03bc]+)\s*[\]\)]?)?\s*$")
#: other spellings of the units a header may name
_UNIT_SPELLINGS = {"\u00b5m": "um", "\u03bcm": "um", "micron": "um", "microns": "um",
                   "degree": "deg", "degrees": "deg", "radian": "rad", "radians": "rad"}
#: column names of the angle layout: the angle, the deviation of the radius, the radius
_ANGLE, _DEVIATION, _RADIUS = ("angle", "theta"), ("deviation", "delta", "dr", "dev"), ("radius",)


def _column(name: str):
    """(quantity, unit) of a header field ``angle_deg``, ``deviation_nm``, ``x_um`` /
    ``x [um]`` / ``deviation (µm)``..."""
    m = _HEADER.match(name)
    if not m:
        return None, None
    q, u = m.group(1).lower(), (m.group(2) or "").lower()
    return q, _UNIT_SPELLINGS.get(u, u)


def _fail(path, line, what) -> InputError:
    where = f"{path}, line {line}" if line else str(path)
    return InputError(f"tool.edge_profile {where}: {what}")


def _numbers(s: str) -> list[str]:
    """The fields of a data row: split at commas, semicolons, tabs and spaces; a row
    with semicolons is split at them alone, and its decimal commas read as points."""
    if ";" in s:
        f = [x.strip() for x in s.split(";") if x.strip()]
        return [x.replace(",", ".") if x.count(",") == 1 and "." not in x else x for x in f]
    return [f for f in re.split(r"[,\t ]+", s) if f]


def _names(s: str) -> list[str]:
    """The fields of a header: split at semicolons, commas or tabs where it has them
    (a name may then hold a space, 'angle (deg)'), else at spaces."""
    for sep in (r";", r"[,\t]"):
        if re.search(sep, s):
            return [f.strip() for f in re.split(sep, s) if f.strip()]
    return s.split()


def _parse(text: str, path: str):
    """(header line, names, (quantity, unit) per name, rows as (line number, values))."""
    rows: list[tuple[int, list[float]]]
    header, rows = None, []
    for ln, raw in enumerate(text.splitlines(), 1):
        s = raw.split("#", 1)[0].strip()
        if not s:
            continue
        fields = _numbers(s)
        try:
            vals = [float(f) for f in fields]
        except ValueError:
            vals = None
        if vals is None and header is None and not rows:
            header = (ln, _names(s))
            continue
        if vals is None and not rows and header is not None:
            raise _fail(path, ln, f"line {header[0]} ({' '.join(header[1])!r}) and this line "
                                  f"({raw.strip()!r}) are both text: the first line that is not a "
                                  f"comment must name the two columns; start any other line with '#'")
        if len(fields) != 2:
            hint = " (decimal commas? separate the columns with ';')" if "," in s and len(fields) == 4 else ""
            raise _fail(path, ln, f"a row must hold 2 numbers, received {len(fields)} ({raw.strip()!r}){hint}")
        if vals is None:
            raise _fail(path, ln, f"a row must hold 2 numbers, received {raw.strip()!r}")
        if not all(math.isfinite(v) for v in vals):
            raise _fail(path, ln, f"values must be finite numbers, received {raw.strip()!r}")
        rows.append((ln, vals))
    if header is None:
        raise _fail(path, 0, "the first line must name the two columns with their units: "
                             "'angle_deg, deviation_nm' (or _um, _mm; angle_rad) for angle against "
                             "radius deviation, or 'x_um, z_um' (or _nm, _mm) for points of the edge")
    ln, names = header
    if len(names) != 2:
        raise _fail(path, ln, f"the header must name 2 columns, received {len(names)} ({' '.join(names)!r})")
    cols = [_column(n) for n in names]
    return ln, names, cols, rows


def _read_text(path: Path) -> str:
    try:
        size = path.stat().st_size
        if size > MAX_EDGE_BYTES:
            raise _fail(path, 0, f"the file must be at most {MAX_EDGE_BYTES // (1024 * 1024)} MiB, "
                                 f"received {size} bytes")
        raw = path.read_bytes()
    except OSError as err:
        raise InputError(f"tool.edge_profile {str(path)!r} cannot be read "
                         f"({err.strerror or err})") from None
    if b"\x00" in raw:
        raise _fail(path, 0, "it is a binary file, not a text table of the edge")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise _fail(path, raw[:err.start].count(b"\n") + 1, "the file is not UTF-8 text") from None


def _fit_circle(x, z):
    """Least-squares circle (xc, zc, R) through the points (Kasa's algebraic fit)."""
    A = np.column_stack([x, z, np.ones_like(x)])
    b = x * x + z * z
    sol, *_ = np.linalg.lstsq(A, b, rcond=None)
    xc, zc = sol[0] / 2, sol[1] / 2
    R = math.sqrt(max(sol[2] + xc * xc + zc * zc, 0.0))
    return xc, zc, R


def read_edge_file(path: str | Path, *, nose_radius: float | None = None) -> EdgeProfile:
    """Read a tool-edge measurement: a text table (comma, semicolon, tab or space
    separated, decimal commas where semicolons separate; ``#`` starts a comment) whose
    first line names the two columns with units, in either order.

    - ``angle_deg, deviation_nm`` (``angle_rad``; ``_um``, ``_mm``): the angle along the
      edge (0 at the tool axis, positive towards +X) against the deviation of the nose
      radius from its nominal value (positive: the edge stands out of the circle);
      ``angle_deg, radius_um``: against the nose radius itself, whose deviation is taken
      from ``nose_radius``; the rows in increasing or decreasing angle;
    - ``x_um, z_um`` (``_nm``, ``_mm``): points of the edge in any frame with Z along the
      tool axis (towards the part is -Z, as the tool tip is the edge's lowest point); a
      circle is fitted, and the deviation is each point's distance from its centre less
      its radius, at the angle from the centre.

    Any other layout, a row that is not two finite numbers, fewer than 8 rows, angles that
    repeat or turn back, an angle beyond 90 deg from the tool axis (points: seen from the
    fitted centre), or a fitted radius (a radius column's median) more than 5 % from
    ``nose_radius`` is an :class:`InputError` naming the file, line and value."""
    p = Path(path)
    text = _read_text(p)
    hl, names, cols, rows = _parse(text, str(p))
    if len(rows) < 8:
        raise _fail(p, 0, f"an edge needs at least 8 rows, received {len(rows)}")
    v = np.array([r[1] for r in rows], dtype=np.float64)
    lines = [r[0] for r in rows]
    qs = [c[0] for c in cols]
    if (qs[1] in _ANGLE and qs[0] in _DEVIATION + _RADIUS) or qs == ["z", "x"]:
        v, names, cols = v[:, ::-1], names[::-1], cols[::-1]  # the columns in the other order
    (q1, u1), (q2, u2) = cols
    if q1 in _ANGLE and q2 in _DEVIATION + _RADIUS:
        if u1 not in ANGLE_UNITS:
            raise _fail(p, hl, f"the angle column must name its unit, 'angle_deg' or 'angle_rad', "
                               f"received {names[0]!r}")
        if u2 not in EDGE_UNITS:
            raise _fail(p, hl, f"the {q2} column must name its unit (one of "
                               f"{', '.join(q2 + '_' + u for u in EDGE_UNITS)}), received {names[1]!r}")
        ang = np.radians(v[:, 0]) if u1 == "deg" else v[:, 0] * ANGLE_UNITS[u1]
        dev = v[:, 1] * EDGE_UNITS[u2]
        if q2 in _RADIUS:
            dev = _deviation_of_radius(p, hl, names[1], dev, nose_radius)
        if ang.size > 1 and np.all(np.diff(ang) < 0):  # a table from +X to -X
            ang, dev, v, lines = ang[::-1].copy(), dev[::-1].copy(), v[::-1], lines[::-1]
        bad = np.flatnonzero(np.diff(ang) <= 0)
        if bad.size:
            k = int(bad[0]) + 1
            raise _fail(p, lines[k], f"angles must increase (or all decrease), received {v[k, 0]:g} {u1} "
                                     f"after {v[k - 1, 0]:g} {u1}")
        if np.any(np.abs(ang) > math.pi / 2):
            k = int(np.flatnonzero(np.abs(ang) > math.pi / 2)[0])
            span = "[-90, 90] deg" if u1 == "deg" else f"[-{math.pi / 2:.6g}, {math.pi / 2:.6g}] rad"
            raise _fail(p, lines[k], f"angle must be in {span} (0 at the tool axis; a table measured "
                                     f"from one end of the edge: subtract half the included angle), "
                                     f"received {v[k, 0]:g}")
        return EdgeProfile(ang, dev, source=p.name)
    if q1 == "x" and q2 == "z":
        if u1 not in EDGE_UNITS or u2 not in EDGE_UNITS:
            raise _fail(p, hl, f"the x and z columns must name their units (x_um, z_um; nm, um or "
                               f"mm), received {' '.join(names)!r}")
        x = v[:, 0] * EDGE_UNITS[u1]
        z = v[:, 1] * EDGE_UNITS[u2]
        xc, zc, R = _fit_circle(x, z)
        if not (R > 0 and math.isfinite(R)):
            raise _fail(p, 0, "no circle fits the points: they must trace the round nose")
        if nose_radius is not None and abs(R - nose_radius) > 0.05 * nose_radius:
            raise _fail(p, 0, f"the circle fitted to the points has radius {R:.6g} mm: tool.nose_radius "
                              f"must be within 5 % of it, received {nose_radius:g} mm")
        # the tip is the lowest point: the centre lies above the points
        ang = np.arctan2(x - xc, zc - z)
        far = np.flatnonzero(np.abs(ang) > math.pi / 2)
        if far.size:
            k = int(far[0])
            raise _fail(p, lines[k], f"the point ({v[k, 0]:g} {u1}, {v[k, 1]:g} {u2}) lies "
                                     f"{math.degrees(ang[k]):.4g} deg from the tool axis seen from the "
                                     f"fitted centre: the points must lie below the centre, within "
                                     f"[-90, 90] deg (the tip the lowest point; where the file's z "
                                     f"points towards the part, negate it)")
        dev = np.hypot(x - xc, z - zc) - R
        order = np.argsort(ang, kind="stable")
        ang, dev = ang[order], dev[order]
        if np.any(np.diff(ang) <= 0):
            raise _fail(p, 0, "two points of the edge lie at the same angle from the fitted centre")
        return EdgeProfile(ang, dev, source=p.name, fitted_radius=R)
    raise _fail(p, hl, f"the header must be 'angle_deg, deviation_nm', 'angle_deg, radius_um' or "
                       f"'x_um, z_um' (units nm, um or mm; angle_rad), received {', '.join(names)!r}")


def _deviation_of_radius(p: Path, hl: int, name: str, radius: np.ndarray,
                         nose_radius: float | None) -> np.ndarray:
    """The deviation (mm) of a column of the nose radius itself from ``nose_radius``."""
    if nose_radius is None:
        raise _fail(p, hl, f"the column {name!r} holds the nose radius itself: its deviation is "
                           f"taken from tool.nose_radius, which is not given")
    med = float(np.median(radius))
    if abs(med - nose_radius) > 0.05 * nose_radius:
        raise _fail(p, hl, f"the column {name!r} holds the nose radius itself (the deviation is "
                           f"radius - tool.nose_radius): its median must lie within 5 % of "
                           f"tool.nose_radius = {nose_radius:g} mm, received {med:.6g} mm (a "
                           f"column of the deviation is named 'deviation_nm')")
    return radius - float(nose_radius)


def edge_notes(edge: EdgeProfile, nose_radius: float, used: tuple[float, float],
               used_by: str) -> list[str]:
    """One line for each thing the cut takes from beyond the measured edge: angles of
    ``used`` (rad, what ``used_by`` names) outside the measurement, where the deviation is
    held at its end values; a circle fitted to an (x, z) file whose radius differs from
    ``nose_radius`` by more than the file's deviation (the cut keeps ``nose_radius``)."""
    out = []
    a0, a1 = edge.covers
    lo, hi = float(used[0]), float(used[1])
    ends = []
    if lo < a0 - _COVER_TOLERANCE:
        ends.append(f"{float(edge.deviation(a0)) * MM_TO_NM:.4g} nm from {math.degrees(a0):.4g} deg down")
    if hi > a1 + _COVER_TOLERANCE:
        ends.append(f"{float(edge.deviation(a1)) * MM_TO_NM:.4g} nm from {math.degrees(a1):.4g} deg up")
    if ends:
        out.append(f"tool edge ({edge.source}) is measured from {math.degrees(a0):.4g} to "
                   f"{math.degrees(a1):.4g} deg, but {used_by} spans {math.degrees(lo):.4g} to "
                   f"{math.degrees(hi):.4g} deg: beyond the measurement the deviation is held at "
                   f"its end values ({'; '.join(ends)})")
    R = edge.fitted_radius
    if R is not None and abs(R - nose_radius) > max(float(np.ptp(edge.delta)), 0.0):
        out.append(f"the circle fitted to tool.edge_profile ({edge.source}) has radius {R:.7g} mm, "
                   f"{abs(R - nose_radius) * MM_TO_UM:.4g} um from tool.nose_radius = {nose_radius:g} mm: "
                   f"the cut keeps tool.nose_radius with the file's deviation from its fitted circle "
                   f"(set tool.nose_radius = {R:.7g} to cut with the measured radius)")
    return out


@functools.lru_cache(maxsize=16)
def _cached(path: str, mtime: float, size: int, nose_radius: float | None) -> EdgeProfile:
    return read_edge_file(path, nose_radius=nose_radius)


def edge_of(edge_profile: str | None, waviness: Sequence[Sequence[float]] | None, *,
            nose_radius: float | None = None,
            amplitude_scale: float = 1.0, half_width: float | None = None) -> EdgeProfile | None:
    """The edge a ``[tool]`` section describes (``edge_profile`` file, ``waviness``
    harmonics, both summed), or None for a circular nose.  ``amplitude_scale`` multiplies
    the deviation.  With ``nose_radius`` and ``half_width`` (the nose arc's radial
    half-width, mm) the edge is checked as the cut will take it (:meth:`EdgeProfile.check`):
    one that is not is refused here, in one line naming the scene keys it comes from."""
    edge = None
    if edge_profile:
        p = os.fspath(edge_profile)
        try:
            st = os.stat(p)
        except OSError as err:
            raise InputError(f"tool.edge_profile {p!r} cannot be read ({err.strerror or err})") from None
        edge = _cached(p, st.st_mtime, st.st_size, nose_radius)
    if waviness:
        wav = EdgeProfile.from_harmonics(waviness)
        if edge is None:
            edge = wav
        else:
            # the harmonics over the whole edge, the file's deviation held beyond its ends
            th = np.union1d(edge.angle, wav.angle)
            edge = EdgeProfile(th, edge.deviation(th) + wav.deviation(th), f"{edge.source} + {wav.source}",
                               edge.fitted_radius, edge.covers)
    if edge is not None and amplitude_scale != 1.0:
        edge = edge.scaled(amplitude_scale)
    if edge is not None and nose_radius is not None and half_width is not None:
        keys = [f"tool.edge_profile {os.fspath(edge_profile)}"] if edge_profile else []
        keys += ["tool.waviness"] if waviness else []
        scale = f" x tool.edge_scale = {amplitude_scale:g}" if amplitude_scale != 1.0 else ""
        edge.check(nose_radius, half_width, what=" + ".join(keys) + scale)
    return edge
