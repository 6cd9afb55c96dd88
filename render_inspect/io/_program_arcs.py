"""The arcs of a machine program (G02 / G03) cut as chords (:func:`expand_arcs`): the
rows of the program's arc blocks replaced by points on their circle, within a tolerance,
centre by the offset words from the start point or by ``R``."""

from __future__ import annotations

import math

import numpy as np

from ..core.errors import InputError
from ._program_scan import ScannedProgram

__all__ = ["expand_arcs"]


def _arc_points(p0, p1, centre, clockwise: bool, tol: float):
    """Points (excluding the start, including the end) of the arc from ``p0`` to ``p1``
    about ``centre`` in the plane's (a, b) coordinates; chords within ``tol``."""
    r0 = math.hypot(p0[0] - centre[0], p0[1] - centre[1])
    r1 = math.hypot(p1[0] - centre[0], p1[1] - centre[1])
    a0 = math.atan2(p0[1] - centre[1], p0[0] - centre[0])
    a1 = math.atan2(p1[1] - centre[1], p1[0] - centre[0])
    sweep = a1 - a0
    if clockwise:
        if sweep >= 0:
            sweep -= 2 * math.pi
    elif sweep <= 0:
        sweep += 2 * math.pi
    r = 0.5 * (r0 + r1)
    step = 2 * math.sqrt(max(2 * r * tol - tol * tol, 1e-30)) / max(r, 1e-12)
    n = max(1, int(math.ceil(abs(sweep) / max(step, 1e-9))))
    u = np.arange(1, n + 1) / n
    ang = a0 + sweep * u
    rad = r0 + (r1 - r0) * u
    return centre[0] + rad * np.cos(ang), centre[1] + rad * np.sin(ang), u, r0, r1


def expand_arcs(sp: ScannedProgram, rows: np.ndarray, axes: dict[str, np.ndarray],
                plane_axes: tuple[str, str], offsets: tuple[str, str], tol: float,
                motion: np.ndarray | None = None
                ) -> tuple[np.ndarray | None, dict[str, np.ndarray], np.ndarray | None]:
    """(index of the source row per point, axes per point, arc fraction per point): the
    rows with G02 / G03 replaced by chord points of their arcs in the plane
    ``plane_axes`` = (a, b) (centre offsets ``offsets`` = (ia, ib) from the start, or
    ``R``; G02 clockwise seen with a to the right and b up).  ``motion``: the rows'
    motion, where the caller has it."""
    arcs = np.flatnonzero((sp.motion[rows] if motion is None else motion) >= 2)
    if arcs.size == 0:
        return None, axes, None
    a, b = plane_axes
    ia, ib = offsets
    pieces_idx: list = []
    pieces: dict[str, list] = {k: [] for k in axes}
    pieces_u = []
    last = 0
    for j in arcs.tolist():
        if j == 0:
            continue  # the first point: nothing to move from
        pieces_idx.append(np.arange(last, j))
        for k in axes:
            pieces[k].append(axes[k][last:j])
        pieces_u.append(np.ones(j - last))
        r = rows[j]
        p0 = (axes[a][j - 1], axes[b][j - 1])
        p1 = (axes[a][j], axes[b][j])
        oa, ob, rr = sp.arc[ia][r], sp.arc[ib][r], sp.arc["R"][r]
        line = int(sp.line[r])
        cw = sp.motion[r] == 2
        if not math.isnan(rr):
            d = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
            if d == 0 or abs(rr) < d / 2 - 1e-9:
                raise InputError(f"{sp.path}:{line}: the arc's R {rr:g} mm cannot join points "
                                 f"{d:g} mm apart")
            h = math.sqrt(max(rr * rr - d * d / 4, 0.0))
            mx, my = (p0[0] + p1[0]) / 2, (p0[1] + p1[1]) / 2
            ux, uy = (p1[0] - p0[0]) / d, (p1[1] - p0[1]) / d
            # the centre on the side that makes the arc the short one for R > 0
            side = (-1 if cw else 1) * (1 if rr > 0 else -1)
            centre = (mx - side * uy * h, my + side * ux * h)
        elif not (math.isnan(oa) and math.isnan(ob)):
            centre = (p0[0] + (0.0 if math.isnan(oa) else oa),
                      p0[1] + (0.0 if math.isnan(ob) else ob))
        else:
            raise InputError(f"{sp.path}:{line}: the arc (G0{sp.motion[r]}) has no centre: give "
                             f"{ia} / {ib} or R")
        xa, xb, u, r0, r1 = _arc_points(p0, p1, centre, cw, tol)
        if abs(r0 - r1) > max(1e-3, 1e-3 * r0):  # not a unit conversion
            raise InputError(f"{sp.path}:{line}: the arc's end lies {abs(r0 - r1):.4g} mm off "
                             f"its circle (radius {r0:.6g} mm at the start)")
        pieces_idx.append(np.full(u.size, j))
        for k in axes:
            if k == a:
                pieces[k].append(xa)
            elif k == b:
                pieces[k].append(xb)
            else:  # the other axes move linearly along the arc
                pieces[k].append(axes[k][j - 1] + (axes[k][j] - axes[k][j - 1]) * u)
        pieces_u.append(u)
        last = j + 1
    pieces_idx.append(np.arange(last, rows.size))
    for k in axes:
        pieces[k].append(axes[k][last:])
    pieces_u.append(np.ones(rows.size - last))
    return (np.concatenate(pieces_idx), {k: np.concatenate(v) for k, v in pieces.items()},
            np.concatenate(pieces_u))
