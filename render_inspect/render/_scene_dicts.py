"""Mitsuba scene pieces built from plain arrays and numbers (loaded only at the edge).

Conventions: world units are mm, +z is up (the part's height axis), images are returned
with row 0 at the smallest y (the height-map convention), column 0 at the smallest x.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ..core import cancel
from ..core.progress import report
from ..mesh import GridMesh
from ._variant import import_mitsuba, single_thread

__all__ = ["mitsuba_mesh", "ortho_sensor", "perspective_sensor", "load_scene_dict",
           "render_aov_grid", "render_aov_grids", "trace_grids"]


def mitsuba_mesh(gm: GridMesh, *, name: str = "part", bsdf: dict | None = None) -> Any:
    """A ``mi.Mesh`` from a :class:`~render_inspect.mesh.GridMesh` (no file round trip).

    Parameters
    ----------
    gm : GridMesh
        float32 vertices (mm), uint32 faces, optional float32 vertex normals.
    bsdf : dict, optional
        Mitsuba BSDF dict attached to the mesh (default: Mitsuba's diffuse).
    """
    mi, dr, _ = import_mitsuba()
    props = mi.Properties()
    if bsdf is not None:
        with cancel.deferred():  # (Python plugins are built from C++; see mitsuba_variant)
            props["bsdf"] = mi.load_dict(bsdf)
    has_n = gm.normals is not None
    mesh = mi.Mesh(name, gm.n_vertices, gm.n_faces, props, has_vertex_normals=has_n,
                   has_vertex_texcoords=False)
    params = mi.traverse(mesh)
    tf = type(params["vertex_positions"])
    tu = type(params["faces"])
    params["vertex_positions"] = tf(np.ascontiguousarray(gm.vertices, dtype=np.float32).ravel())
    params["faces"] = tu(np.ascontiguousarray(gm.faces, dtype=np.uint32).ravel())
    if has_n:
        params["vertex_normals"] = tf(np.ascontiguousarray(gm.normals, dtype=np.float32).ravel())
    params.update()
    return mesh


def ortho_sensor(*, x0: float, y0: float, width_mm: float, nx: int, ny: int, z_top: float,
                 spp: int = 1, jitter: bool = False) -> dict:
    """Telecentric (orthographic) view straight down onto the window
    ``[x0, x0 + width_mm] x [y0, y0 + width_mm * ny / nx]`` with an ``nx x ny`` film.

    With ``spp=1`` and ``jitter=False`` each film pixel is sampled exactly at its centre.
    """
    mi, _, _ = import_mitsuba()
    hw = width_mm / 2.0
    cx = x0 + hw
    cy = y0 + width_mm * ny / nx / 2.0
    to_world = (mi.ScalarTransform4f().look_at(origin=[cx, cy, z_top], target=[cx, cy, z_top - 1.0],
                                               up=[0, 1, 0])
                @ mi.ScalarTransform4f().scale([hw, hw, 1.0]))
    return {"type": "orthographic", "to_world": to_world,
            "near_clip": 1e-4, "far_clip": 1e6,
            "film": {"type": "hdrfilm", "width": int(nx), "height": int(ny),
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "stratified", "sample_count": int(spp), "jitter": bool(jitter)}}


def perspective_sensor(*, origin: Sequence[float], target: Sequence[float], up: Sequence[float],
                       fov_deg: float, nx: int, ny: int, spp: int) -> dict:
    """Pinhole camera (horizontal field of view ``fov_deg``), box filter, independent sampler."""
    mi, _, _ = import_mitsuba()
    return {"type": "perspective", "fov": float(fov_deg), "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(origin=list(map(float, origin)),
                                                       target=list(map(float, target)),
                                                       up=list(map(float, up))),
            "near_clip": 1e-3, "far_clip": 1e6,
            "film": {"type": "hdrfilm", "width": int(nx), "height": int(ny),
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": int(spp)}}


def load_scene_dict(d: dict) -> Any:
    """``mi.load_dict`` with one Dr.Jit thread, so the BVH (and the image) is repeatable."""
    mi, _, _ = import_mitsuba()
    with single_thread(), cancel.deferred():  # (see mitsuba_mesh)
        return mi.load_dict(d)


def render_aov_grid(gm: GridMesh, *, x0: float, y0: float, width_mm: float, nx: int, ny: int,
                    z_top: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ray-trace the mesh straight down at the centres of an ``ny x nx`` grid of cells
    (cell size ``width_mm / nx``; the grid's lower-left corner at ``(x0, y0)``).

    Returns
    -------
    position : (ny, nx, 3) float32, hit point (mm; zeros where nothing was hit)
    sh_normal : (ny, nx, 3) float32, shading (interpolated vertex) normal, zeros on a miss
    geo_normal : (ny, nx, 3) float32, the hit triangle's normal, zeros on a miss
        Row 0 is the smallest y.
    """
    return render_aov_grids(gm, [dict(x0=x0, y0=y0, width_mm=width_mm, nx=nx, ny=ny)],
                            z_top=z_top)[0]


def render_aov_grids(gm: GridMesh, grids: list[dict], *, z_top: float) -> list[tuple]:
    """:func:`render_aov_grid` for several grids (dicts of ``x0, y0, width_mm, nx, ny``)
    with one scene load (one BVH build), one orthographic sensor per grid."""
    mi, _, _ = import_mitsuba()
    d = {"type": "scene",
         "integrator": {"type": "aov", "aovs": "pp:position,nn:sh_normal,gn:geo_normal"},
         "part": mitsuba_mesh(gm)}
    for k, g in enumerate(grids):
        d[f"sensor_{k}"] = ortho_sensor(z_top=z_top, **g)
    scene = load_scene_dict(d)
    out = []
    for k in range(len(grids)):
        report(k, len(grids))  # (and stop between sensors when a signal asked)
        img = np.array(mi.render(scene, sensor=k, seed=0), dtype=np.float32)
        img = img[::-1]  # film row 0 is the top (largest y)
        out.append((np.ascontiguousarray(img[..., 0:3]), np.ascontiguousarray(img[..., 3:6]),
                    np.ascontiguousarray(img[..., 6:9])))
    return out


def _aligned(shape: tuple[int, int]) -> np.ndarray:
    """An empty float32 array of ``shape`` in a 64-byte aligned buffer.  Dr.Jit reads a
    NumPy array in place and writes its alignment into the traced program (an aligned or
    an unaligned vector load): arrays that NumPy placed at other addresses would otherwise
    make other programs, each compiled anew, where one compiled program serves every
    call."""
    n = shape[0] * shape[1]
    buf = np.empty(n + 16, dtype=np.float32)
    start = (-buf.ctypes.data % 64) // 4
    return buf[start:start + n].reshape(shape)


def trace_grids(gm: GridMesh, grids: list[dict], *, z_top: float,
                shift: Sequence[float] = (0.0, 0.0),
                full_normals: bool = False, workers: int = 1) -> list[tuple]:
    """Ray-trace the mesh straight down near the cell centres of several grids (one BVH
    build) and return the height at the centres.

    Each ray is cast at ``centre + shift`` (mm); the hit height is carried back to the
    centre along the hit triangle's plane (its geometric normal ``n``):
    ``z = p_z + (n_x shift_x + n_y shift_y) / n_z``.  A small odd shift keeps rays off
    mesh edges and vertices, where a ray may slip between two triangles.

    On the JIT variants (``llvm_ad_rgb``, ``cuda_ad_rgb``) rays are built from arrays and
    intersected with ``Scene.ray_intersect`` (about 3x faster than the AOV film);
    ``scalar_rgb`` renders the ``aov`` integrator through orthographic sensors.

    Parameters
    ----------
    gm : GridMesh
    grids : list of dict
        ``x0, y0`` (lower-left corner, mm), ``width_mm``, ``nx``, ``ny``.
    z_top : float
        Height the rays start from (mm, mesh coordinates; above the mesh).
    shift : (float, float)
        Ray offset from the cell centres, mm.
    full_normals : bool
        Return the whole shading normal instead of its z component.
    workers : int
        Threads that copy the normals' components side by side, over blocks of rows
        (the same array for any number).

    Returns
    -------
    list of (z, nz)
        ``z`` (ny, nx) float32, mesh height at the cell centres (NaN on a miss);
        ``nz`` (ny, nx) float32, z component of the shading normal (0 on a miss), or with
        ``full_normals`` the unit shading normal (ny, nx, 3) float32 ((0, 0, 0) on a
        miss).  Row 0 is the smallest y.
    """
    mi, dr, variant = import_mitsuba()
    dx, dy = float(shift[0]), float(shift[1])
    if variant.startswith("scalar"):
        shifted = [dict(g, x0=float(g["x0"]) + dx, y0=float(g["y0"]) + dy) for g in grids]
        out = []
        for pos, nrm, gn in render_aov_grids(gm, shifted, z_top=z_top):
            hit = (np.einsum("...i,...i->...", gn, gn) > 0.25) & (gn[..., 2] > 1e-6)
            gz = np.where(hit, gn[..., 2], np.float32(1.0))
            z = pos[..., 2] + (gn[..., 0] * np.float32(dx) + gn[..., 1] * np.float32(dy)) / gz
            n_out = (np.where(hit[..., None], nrm, np.float32(0.0)) if full_normals
                     else np.where(hit, nrm[..., 2], np.float32(0.0)))
            out.append((np.where(hit, z, np.float32(np.nan)).astype(np.float32),
                        np.ascontiguousarray(n_out, dtype=np.float32)))
        return out
    scene = load_scene_dict({"type": "scene", "part": mitsuba_mesh(gm)})
    # the numbers that change from call to call (the rays' start height, the shift) enter
    # the traced program as values it reads, not as constants written into it: the
    # program is then the same for every mesh and compiled once per process, not once per
    # call (the same float32 numbers either way, the same heights bit for bit)
    z_start, sx, sy = (dr.opaque(mi.Float, v) for v in (float(z_top), dx, dy))
    out = []
    for g in grids:
        nx, ny = int(g["nx"]), int(g["ny"])
        cell = float(g["width_mm"]) / nx
        xs = (float(g["x0"]) + dx + (np.arange(nx) + 0.5) * cell).astype(np.float32)
        ys = (float(g["y0"]) + dy + (np.arange(ny) + 0.5) * cell).astype(np.float32)
        ox, oy = _aligned((ny, nx)), _aligned((ny, nx))
        ox[:] = xs               # (np.tile(xs, ny))
        oy[:] = ys[:, None]      # (np.repeat(ys, nx))
        o = mi.Point3f(mi.Float(ox.ravel()), mi.Float(oy.ravel()), z_start)
        ray = mi.Ray3f(o, mi.Vector3f(0.0, 0.0, -1.0))
        si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=True)
        hit = si.is_valid() & (si.n.z > 1e-6)
        z = si.p.z + (si.n.x * sx + si.n.y * sy) / dr.select(hit, si.n.z, 1.0)
        z = dr.select(hit, z, dr.nan)
        if full_normals:
            comps = [dr.select(hit, c, 0.0) for c in (si.sh_frame.n.x, si.sh_frame.n.y,
                                                       si.sh_frame.n.z)]
            dr.eval(z, *comps)
            n_out = np.empty((ny, nx, 3), dtype=np.float32)  # (filled in place: no stack)
            planes = [np.asarray(c, dtype=np.float32).reshape(ny, nx) for c in comps]

            def fill(r: slice, n_out: np.ndarray = n_out, planes: list = planes) -> None:
                for i, c in enumerate(planes):
                    n_out[r, :, i] = c[r]

            _by_row_blocks(fill, ny, workers)
        else:
            nz = dr.select(hit, si.sh_frame.n.z, 0.0)
            dr.eval(z, nz)
            n_out = np.array(nz, dtype=np.float32).reshape(ny, nx)
        # (the heights read where Dr.Jit holds them, float32 already: NumPy's view, no copy)
        out.append((np.asarray(z, dtype=np.float32).reshape(ny, nx), n_out))
    return out


def _by_row_blocks(fn: Callable[[slice], object], rows: int, workers: int) -> None:
    """``fn(block)`` for ``rows`` rows split into ``workers`` blocks of whole rows, each
    block in a thread of its own (NumPy's copies and element-wise passes let go of the
    interpreter); all the rows at once in the calling thread with one worker."""
    n = max(1, min(int(workers), rows))
    if n == 1:
        fn(slice(0, rows))
        return
    edges = [rows * i // n for i in range(n + 1)]
    with ThreadPoolExecutor(max_workers=n) as pool:
        for f in [pool.submit(fn, slice(a, b)) for a, b in zip(edges[:-1], edges[1:])]:
            f.result()
