"""A turned disc as a solid: its face sampled on polar rings from a height map, a 45 degree
chamfer, the cylindrical side wall and the bottom.

A square grid clipped to a circle leaves a staircase of cells along the rim and no side
to the part; a real turned part has a round edge, usually chamfered, and a side wall that
catches the light.  Here the face is sampled on ``rings`` concentric rings of ``sectors``
points (bilinear interpolation of the height map; the normals from its gradient, so the
shading is smooth), out to ``radius - chamfer``; the chamfer (true scale, 45 degrees)
and the wall are flat-shaded rings of their own.  The face's centre is one vertex with a
fan of triangles: no seam and no staircase at the spindle axis.
"""

from __future__ import annotations

from collections.abc import Sequence
import math

import numpy as np
from ..core.lazy import lazy_module

from .. import __version__
from ..core.errors import InputError, MemoryBudgetError, check_positive
from ..core.units import MIB_TO_BYTES
from ._grid import DEFAULT_MEMORY_BUDGET_BYTES, GridMesh

#: SciPy, imported on first use (render_inspect.core.lazy)
ndimage = lazy_module("scipy.ndimage")

__all__ = ["disc_mesh"]


def _filled(z: np.ndarray) -> np.ndarray:
    """``z`` with every NaN replaced by its nearest finite neighbour (so interpolation
    near the rim never reads a hole)."""
    bad = ~np.isfinite(z)
    if not bad.any():
        return z
    if bad.all():
        raise InputError("the height map has no finite height: nothing to mesh")
    idx = ndimage.distance_transform_edt(bad, return_distances=False, return_indices=True)
    return z[tuple(idx)]


def _ring_faces(inner: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """Triangles between two closed rings of equal length, counter-clockwise seen from
    the side the rings' order implies (inner -> outer, increasing angle: +z)."""
    i1, o1 = np.roll(inner, -1), np.roll(outer, -1)
    return np.concatenate([np.stack([inner, outer, o1], 1), np.stack([inner, o1, i1], 1)])


def disc_mesh(z: np.ndarray, *, pixel: float, origin: Sequence[float], center: Sequence[float],
              radius: float, exaggeration: float = 1.0,
              z_offset: float | None = None, rings: int = 256, sectors: int = 1024,
              chamfer: float = 0.0, wall: float = 0.0, normals: bool = True,
              memory_budget: int | None = None, channel: str = "") -> GridMesh:
    """The mesh of a turned disc: face, chamfer, side wall and bottom.

    Parameters
    ----------
    z : (ny, nx) array
        Heights, mm, row 0 = smallest y; NaN outside the part (filled from the nearest
        height for the interpolation).
    pixel, origin
        The grid of ``z``, mm.
    center, radius
        The disc (the part's outline), mm.
    exaggeration, z_offset
        Vertex z of the face = ``exaggeration * (h - z_offset)`` (z_offset: default the
        mean height); the chamfer and the wall are drawn at true scale below the face's
        rim.
    rings, sectors : int
        Concentric rings of the face and points per ring.
    chamfer : float
        Width (and depth) of the 45 degree chamfer at the rim, mm (0: a sharp edge).
    wall : float
        Height of the side wall below the lowest point of the face, mm (0: no wall and
        no bottom: the face alone).
    memory_budget : int, optional
        Bytes the arrays may take.

    Returns
    -------
    GridMesh
        Metadata as :func:`~render_inspect.mesh.grid_mesh`'s, with ``shape = "disc"``,
        ``center_mm``, ``radius_mm``, ``rings``, ``sectors``, ``chamfer_mm``, ``wall_mm``.
    """
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 2:
        raise InputError(f"z must be a 2-D height grid with at least 2 x 2 values, got shape {z.shape}")
    for name, v in (("pixel", pixel), ("radius", radius), ("exaggeration", exaggeration)):
        check_positive(name, v)
    rings, sectors = int(rings), int(sectors)
    if rings < 1 or sectors < 8:
        raise InputError(f"disc mesh needs rings >= 1 and sectors >= 8, got {rings}, {sectors}")
    if not 0 <= chamfer < radius or wall < 0:
        raise InputError(f"chamfer must be in [0, radius) and wall >= 0, got {chamfer}, {wall}")
    n_v = 1 + rings * sectors + (5 * sectors + 1 if wall > 0 else 2 * sectors)
    n_f = sectors * (2 * rings - 1) + (8 * sectors if wall > 0 else 2 * sectors)
    need = n_v * (12 + (12 if normals else 0)) + n_f * 12
    budget = DEFAULT_MEMORY_BUDGET_BYTES if memory_budget is None else int(memory_budget)
    if need > budget:
        raise MemoryBudgetError(f"a disc mesh of {rings} x {sectors} points needs "
                                f"{need / MIB_TO_BYTES:.0f} MiB, over the memory budget of "
                                f"{budget / MIB_TO_BYTES:.0f} MiB: lower the resolution")
    finite = np.isfinite(z)
    if not finite.any():
        raise InputError("z has no finite height: nothing to mesh")
    if z_offset is None:
        z_offset = float(np.mean(z[finite]))
    ze = (_filled(z) - z_offset) * exaggeration
    gy, gx = np.gradient(ze, pixel)
    cx, cy = float(center[0]), float(center[1])
    r_top = radius - chamfer
    phi = 2 * math.pi * np.arange(sectors) / sectors
    cos, sin = np.cos(phi), np.sin(phi)
    r = r_top * np.arange(1, rings + 1) / rings
    xs = np.concatenate([[cx], (cx + r[:, None] * cos[None, :]).ravel()])
    ys = np.concatenate([[cy], (cy + r[:, None] * sin[None, :]).ravel()])
    coords = np.stack([(ys - origin[1]) / pixel, (xs - origin[0]) / pixel])
    zs, nx_, ny_ = (ndimage.map_coordinates(a, coords, order=1, mode="nearest")
                    for a in (ze, gx, gy))
    face_v = np.stack([xs, ys, zs], 1)
    inv = 1.0 / np.sqrt(1.0 + nx_ ** 2 + ny_ ** 2)
    face_n = np.stack([-nx_ * inv, -ny_ * inv, inv], 1)
    def ring(k: int) -> np.ndarray:  # vertex indices of ring k >= 1
        return 1 + (k - 1) * sectors + np.arange(sectors)

    faces = [np.stack([np.zeros(sectors, np.int64), ring(1), np.roll(ring(1), -1)], 1)]
    for k in range(1, rings):
        faces.append(_ring_faces(ring(k), ring(k + 1)))
    verts, nrms = [face_v], [face_n]
    n0 = face_v.shape[0]
    z_rim = zs[ring(rings)]
    s = math.sqrt(0.5)
    if wall > 0 or chamfer > 0:
        # the chamfer: from the face's rim out to the radius, 45 degrees down
        top = np.stack([cx + r_top * cos, cy + r_top * sin, z_rim], 1)
        bot = np.stack([cx + radius * cos, cy + radius * sin, z_rim - chamfer], 1)
        cn = np.stack([s * cos, s * sin, np.full(sectors, s)], 1)
        verts += [top, bot]
        nrms += [cn, cn]
        t_i, b_i = n0 + np.arange(sectors), n0 + sectors + np.arange(sectors)
        if chamfer > 0:
            faces.append(_ring_faces(t_i, b_i))
        n0 += 2 * sectors
        if wall > 0:
            z_bottom = float(np.min(zs) - chamfer - wall)
            w_top = bot.copy()
            w_bot = np.stack([cx + radius * cos, cy + radius * sin, np.full(sectors, z_bottom)], 1)
            wn = np.stack([cos, sin, np.zeros(sectors)], 1)
            base = np.concatenate([w_bot, [[cx, cy, z_bottom]]])
            down = np.zeros((sectors + 1, 3))
            down[:, 2] = -1.0
            verts += [w_top, w_bot, base]
            nrms += [wn, wn, down]
            wt, wb = n0 + np.arange(sectors), n0 + sectors + np.arange(sectors)
            faces.append(_ring_faces(wt, wb))
            bb = n0 + 2 * sectors + np.arange(sectors)
            c = n0 + 3 * sectors
            faces.append(np.stack([np.full(sectors, c), np.roll(bb, -1), bb], 1))  # faces down
    vertices = np.concatenate(verts).astype(np.float32)
    nrm = np.concatenate(nrms).astype(np.float32) if normals else None
    faces = np.concatenate(faces).astype(np.uint32)
    meta = {"vertical_exaggeration": float(exaggeration), "z_offset_mm": float(z_offset),
            "pixel_mm": float(2 * math.pi * radius / sectors), "grid_pixel_mm": float(pixel),
            "origin_mm": [float(origin[0]), float(origin[1])], "grid_shape": list(z.shape),
            "stride": 1, "skirt": bool(wall > 0), "channel": channel, "shape": "disc",
            "center_mm": [cx, cy], "radius_mm": float(radius), "rings": rings,
            "sectors": sectors, "chamfer_mm": float(chamfer), "wall_mm": float(wall),
            "units": "mm", "software_version": __version__}
    return GridMesh(vertices, faces, nrm, meta)
