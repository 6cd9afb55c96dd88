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
from ..core.units import MM_TO_NM, NM_TO_MM, UM_TO_MM

__all__ = ["EdgeProfile", "read_edge_file", "edge_of", "NO_EDGE", "TABLE_POINTS",
           "EDGE_UNITS"]

#: the empty edge table: a circular nose (the kernels' circle, bit for bit)
NO_EDGE = np.zeros(0)
#: points of the kernels' height table over the nose's radial width
TABLE_POINTS = 8193
#: length units a column header may name (suffix -> mm per unit)
EDGE_UNITS = {"nm": NM_TO_MM, "um": UM_TO_MM, "mm": 1.0}
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
    """

    angle: np.ndarray
    delta: np.ndarray
    source: str = ""
    fitted_radius: float | None = None

    def deviation(self, theta: np.ndarray | float) -> np.ndarray:
        """delta(theta), mm."""
        return np.interp(np.asarray(theta, dtype=np.float64), self.angle, self.delta)

    @classmethod
    def from_harmonics(cls, harmonics: Sequence[Sequence[float]], *, span_deg: float = 180.0,
                       samples: int = 7201) -> "EdgeProfile":
        """delta(theta) = sum_k a_k cos(2 pi theta / P_k + phi_k) from (a_k nm, P_k degrees,
        phi_k degrees) triples."""
        th = np.linspace(-math.radians(span_deg), math.radians(span_deg), samples)
        d = np.zeros_like(th)
        for a_nm, period_deg, phase_deg in harmonics:
            d += a_nm * NM_TO_MM * np.cos(2 * math.pi * th / math.radians(period_deg) + math.radians(phase_deg))
        text = ", ".join(f"{a:g} nm per {p:g} deg" for a, p, _ in harmonics)
        return cls(th, d, source=f"waviness {text}")

    def scaled(self, factor: float) -> "EdgeProfile":
        """The same edge with the deviation times ``factor``."""
        return EdgeProfile(self.angle, self.delta * float(factor), self.source, self.fitted_radius)

    def within(self, half_angle: float) -> np.ndarray:
        """The deviations (mm) at the samples within +-half_angle (rad) and at its ends."""
        th = np.concatenate([[-half_angle, half_angle],
                             self.angle[np.abs(self.angle) <= half_angle]])
        return self.deviation(th)

    def pv_nm(self, half_angle: float) -> float:
        """Peak-to-valley deviation (nm) over +-half_angle (rad)."""
        d = self.within(half_angle)
        return float((d.max() - d.min()) * MM_TO_NM)

    def height_table(self, nose_radius: float, half_width: float, points: int = TABLE_POINTS) -> np.ndarray:
        """The kernels' table: [d0, 1 / step, lowest entry (<= 0), g_0 .. g_(points-1)] with
        g(d) the height (mm) of the edge above the circular arc Rc - sqrt(Rc^2 - d^2) at the
        radial offset d = d0 + i step, d0 = -half_width .. +half_width."""
        Rc = float(nose_radius)
        hw = min(float(half_width), Rc)
        dmax = float(np.max(np.abs(self.delta))) if self.delta.size else 0.0
        if dmax > MAX_DEVIATION_FRACTION * Rc:
            raise InputError(f"tool edge ({self.source}): |deviation| must be <= "
                             f"{MAX_DEVIATION_FRACTION:g} x tool.nose_radius = "
                             f"{MAX_DEVIATION_FRACTION * Rc * MM_TO_NM:g} nm, received "
                             f"{dmax * MM_TO_NM:.6g} nm")
        # the edge point by point, a little beyond the arc's half-width
        th_max = math.asin(min(hw / Rc, 1.0))
        th_hi = min(th_max * 1.05 + 0.01, math.pi / 2)
        th = np.linspace(-th_hi, th_hi, 4 * points + 1)
        r = Rc + self.deviation(th)
        x = r * np.sin(th)
        if np.any(np.diff(x) <= 0):
            raise InputError(f"tool edge ({self.source}): the edge folds back over the radial "
                             f"offset (its deviation changes faster than the nose turns); a "
                             f"measured edge must be a smooth graph over the angle")
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
               "deviation_rms_nm": float(np.sqrt(np.mean(self.delta ** 2)) * MM_TO_NM)}
        if half_angle is not None:
            out["engaged_pv_nm"] = self.pv_nm(half_angle)
        if self.fitted_radius is not None:
            out["fitted_radius_mm"] = float(self.fitted_radius)
        return out


# ------------------------------------------------------------------ edge files
_HEADER = re.compile(r"^\s*([A-Za-z]+)(?:[_\[\( ]+([A-Za-z]+)[\]\)]?)?\s*$")


def _column(name: str, path: str):
    """(quantity, mm per unit) of a header field ``angle_deg``, ``deviation_nm``,
    ``x_um`` / ``x [um]``..."""
    m = _HEADER.match(name)
    if not m:
        return None, None
    q, u = m.group(1).lower(), (m.group(2) or "").lower()
    u = {"µm": "um", "micron": "um", "microns": "um", "degree": "deg", "degrees": "deg"}.get(u, u)
    return q, u


def _fail(path, line, what) -> InputError:
    where = f"{path}, line {line}" if line else str(path)
    return InputError(f"tool.edge_profile {where}: {what}")


def _parse(text: str, path: str):
    """(quantities, units, rows as (line number, values))."""
    rows: list[tuple[int, list[float]]]
    header, rows = None, []
    for ln, raw in enumerate(text.splitlines(), 1):
        s = raw.split("#", 1)[0].strip()
        if not s:
            continue
        fields = [f for f in re.split(r"[,;\t ]+", s) if f] if "[" not in s and "(" not in s \
            else [f.strip() for f in re.split(r"[,;\t]+", s) if f.strip()]
        if header is None and not rows:
            try:
                [float(f) for f in fields]
            except ValueError:
                header = (ln, fields)
                continue
        if len(fields) != 2:
            raise _fail(path, ln, f"a row must hold 2 numbers, received {len(fields)} ({raw.strip()!r})")
        try:
            vals = [float(f) for f in fields]
        except ValueError:
            raise _fail(path, ln, f"a row must hold 2 numbers, received {raw.strip()!r}") from None
        if not all(math.isfinite(v) for v in vals):
            raise _fail(path, ln, f"values must be finite numbers, received {raw.strip()!r}")
        rows.append((ln, vals))
    if header is None:
        raise _fail(path, 0, "the first line must name the two columns with their units: "
                             "'angle_deg, deviation_nm' (or _um, _mm) for angle against radius "
                             "deviation, or 'x_um, z_um' (or _nm, _mm) for points of the edge")
    ln, names = header
    if len(names) != 2:
        raise _fail(path, ln, f"the header must name 2 columns, received {len(names)} ({' '.join(names)!r})")
    cols = [_column(n, path) for n in names]
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
    separated; ``#`` starts a comment) whose first line names the two columns with units.

    - ``angle_deg, deviation_nm`` (``_um``, ``_mm``): the angle along the edge (degrees,
      0 at the tool axis, positive towards +X) against the deviation of the nose radius
      from its nominal value;
    - ``x_um, z_um`` (``_nm``, ``_mm``): points of the edge in any frame with Z along the
      tool axis (towards the part is -Z, as the tool tip is the edge's lowest point); a
      circle is fitted, and the deviation is each point's distance from its centre less
      its radius, at the angle from the centre.

    Any other layout, a row that is not two finite numbers, fewer than 8 rows, angles that
    do not increase, or (points) a fitted radius more than 5 % from ``nose_radius`` is an
    :class:`InputError` naming the file, line and value."""
    p = Path(path)
    text = _read_text(p)
    hl, names, cols, rows = _parse(text, str(p))
    (q1, u1), (q2, u2) = cols
    if len(rows) < 8:
        raise _fail(p, 0, f"an edge needs at least 8 rows, received {len(rows)}")
    v = np.array([r[1] for r in rows], dtype=np.float64)
    lines = [r[0] for r in rows]
    if q1 in ("angle", "theta") and q2 in ("deviation", "delta", "dr", "radius"):
        if u1 not in ("deg", ""):
            raise _fail(p, hl, f"the angle column must be in degrees ('angle_deg'), received {names[0]!r}")
        if u2 not in EDGE_UNITS:
            raise _fail(p, hl, f"the deviation column must name its unit (one of "
                               f"{', '.join('deviation_' + u for u in EDGE_UNITS)}), received {names[1]!r}")
        ang = np.radians(v[:, 0])
        dev = v[:, 1] * EDGE_UNITS[u2]
        bad = np.flatnonzero(np.diff(ang) <= 0)
        if bad.size:
            k = int(bad[0]) + 1
            raise _fail(p, lines[k], f"angles must increase, received {v[k, 0]:g} deg after "
                                     f"{v[k - 1, 0]:g} deg")
        if np.any(np.abs(ang) > math.pi / 2):
            k = int(np.flatnonzero(np.abs(ang) > math.pi / 2)[0])
            raise _fail(p, lines[k], f"angle must be in [-90, 90] deg, received {v[k, 0]:g}")
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
        dev = np.hypot(x - xc, z - zc) - R
        order = np.argsort(ang, kind="stable")
        ang, dev = ang[order], dev[order]
        if np.any(np.diff(ang) <= 0):
            raise _fail(p, 0, "two points of the edge lie at the same angle from the fitted centre")
        return EdgeProfile(ang, dev, source=p.name, fitted_radius=R)
    raise _fail(p, hl, f"the header must be 'angle_deg, deviation_nm' or 'x_um, z_um' (units nm, um "
                       f"or mm), received {', '.join(names)!r}")


@functools.lru_cache(maxsize=16)
def _cached(path: str, mtime: float, size: int, nose_radius: float | None) -> EdgeProfile:
    return read_edge_file(path, nose_radius=nose_radius)


def edge_of(edge_profile: str | None, waviness: Sequence[Sequence[float]] | None, *,
            nose_radius: float | None = None,
            amplitude_scale: float = 1.0) -> EdgeProfile | None:
    """The edge a ``[tool]`` section describes (``edge_profile`` file, ``waviness``
    harmonics, both summed), or None for a circular nose.  ``amplitude_scale`` multiplies
    the deviation."""
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
            th = np.union1d(edge.angle, wav.angle[np.abs(wav.angle) <= max(abs(edge.angle[0]), abs(edge.angle[-1]))])
            edge = EdgeProfile(th, edge.deviation(th) + wav.deviation(th), f"{edge.source} + {wav.source}",
                               edge.fitted_radius)
    if edge is not None and amplitude_scale != 1.0:
        edge = edge.scaled(amplitude_scale)
    return edge
