"""Height map -> triangle mesh, built directly from arrays (float32 vertices, uint32 faces).

A grid of ``ny x nx`` heights gives ``ny * nx`` vertices and ``2 (ny - 1)(nx - 1)``
triangles (two per cell, counter-clockwise seen from +z, so normals point up).  Vertex
``k = i * nx + j`` sits at ``x = x0 + j * pixel``, ``y = y0 + i * pixel`` (row 0 = smallest
y) and ``z = exaggeration * (h - z_offset)`` (mm).  Cells with a NaN corner are left out.

Memory: 12 bytes per vertex + 24 bytes per triangle (+12 per vertex for normals): a
4000 x 4000 map is 192 MB of positions, 768 MB of faces and 192 MB of normals.
"""

from __future__ import annotations

from collections.abc import Sequence
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np

from .. import __version__
from ..core.errors import InputError, MemoryBudgetError, check_positive
from ..core.limits import address_space_limit, address_space_room
from ..core.units import GIB_TO_BYTES, MIB_TO_BYTES, MM_TO_M
from ..io import atomic_write_bytes
from ..core.heightmap import HeightMap

if TYPE_CHECKING:
    import trimesh

__all__ = ["GridMesh", "grid_mesh", "heightmap_mesh", "heightmap_to_trimesh", "export_mesh",
           "gltf_from_project", "decimation_stride", "MESH_FORMATS", "DEFAULT_MEMORY_BUDGET_BYTES"]

#: The largest mesh (vertices + faces + normals, bytes) built without an explicit budget.
DEFAULT_MEMORY_BUDGET_BYTES = 6 * GIB_TO_BYTES

#: Export formats, keyed by file extension (trimesh's exporters).
MESH_FORMATS = {".ply": "ply", ".obj": "obj", ".glb": "glb", ".stl": "stl"}


@dataclass
class GridMesh:
    """A triangle mesh as plain arrays.

    Attributes
    ----------
    vertices : (n, 3) float32, mm (z already exaggerated and offset)
    faces : (m, 3) uint32, counter-clockwise seen from +z
    normals : (n, 3) float32 or None, unit vertex normals of the (exaggerated) surface
    metadata : dict, provenance: ``vertical_exaggeration``, ``z_offset_mm``,
        ``pixel_mm`` (grid spacing of the vertices), ``origin_mm``, ``grid_shape``,
        ``stride``, ``skirt``, ``channel``, ``software_version``
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray | None = None
    metadata: dict = field(default_factory=dict)

    @property
    def n_vertices(self) -> int:
        return int(self.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @property
    def nbytes(self) -> int:
        return int(self.vertices.nbytes + self.faces.nbytes
                   + (self.normals.nbytes if self.normals is not None else 0))

    def to_trimesh(self) -> trimesh.Trimesh:
        """Return a :class:`trimesh.Trimesh` (float64 vertices) carrying ``metadata``."""
        import trimesh

        kw: dict[str, Any] = {}
        if self.normals is not None and not self.metadata.get("skirt"):
            kw["vertex_normals"] = self.normals.astype(np.float64)
        mesh = trimesh.Trimesh(vertices=self.vertices.astype(np.float64),
                               faces=self.faces.astype(np.int64), process=False, **kw)
        mesh.metadata.update(self.metadata)
        return mesh


def decimation_stride(shape: tuple[int, ...], max_cells: int) -> int:
    """Smallest integer stride so that the longer side has at most ``max_cells`` cells."""
    check_positive("max_cells", max_cells)
    n = max(int(shape[0]), int(shape[1])) - 1
    return max(1, math.ceil(n / int(max_cells)))


def _grid_faces(ny: int, nx: int, keep: np.ndarray | None) -> np.ndarray:
    """uint32 faces of an ny x nx vertex grid; ``keep`` (ny-1, nx-1) bool selects cells."""
    idx = np.arange(ny * nx, dtype=np.uint32).reshape(ny, nx)
    v00 = idx[:-1, :-1]
    v01 = idx[:-1, 1:]
    v10 = idx[1:, :-1]
    v11 = idx[1:, 1:]
    f = np.empty((ny - 1, nx - 1, 2, 3), dtype=np.uint32)
    f[..., 0, 0] = v00
    f[..., 0, 1] = v01
    f[..., 0, 2] = v11
    f[..., 1, 0] = v00
    f[..., 1, 1] = v11
    f[..., 1, 2] = v10
    if keep is not None:
        f = f[keep]
    return f.reshape(-1, 3)


def _grid_normals(z: np.ndarray, pixel: float) -> np.ndarray:
    """Unit normals (-dz/dx, -dz/dy, 1)/norm from central differences (float32)."""
    zf = np.where(np.isfinite(z), z, np.nan)
    if min(z.shape) >= 2:
        gy, gx = np.gradient(zf, pixel)
    else:
        gy = gx = np.zeros_like(zf)
    gx = np.nan_to_num(gx)
    gy = np.nan_to_num(gy)
    n = np.empty(z.shape + (3,), dtype=np.float32)
    inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
    n[..., 0] = -gx * inv
    n[..., 1] = -gy * inv
    n[..., 2] = inv
    return n.reshape(-1, 3)


def grid_mesh(z: np.ndarray, *, pixel: float, origin: Sequence[float] = (0.0, 0.0),
              exaggeration: float = 1.0,
              z_offset: float | None = None, stride: int = 1, normals: bool = True,
              skirt: bool = False, base_depth: float | None = None,
              memory_budget: int | None = None, channel: str = "") -> GridMesh:
    """Triangle mesh of a height grid.

    Parameters
    ----------
    z : (ny, nx) array_like
        Heights, mm; row 0 is the smallest y.  NaN cells are left out (or, with ``skirt``,
        set to the base so the solid stays closed).
    pixel : float
        Grid spacing, mm (> 0).
    origin : (float, float)
        x, y of ``z[0, 0]``, mm.
    exaggeration : float
        Vertical exaggeration (> 0): vertex z = exaggeration * (h - z_offset).
    z_offset : float, optional
        Height subtracted before exaggerating, mm; default the mean of the finite heights.
    stride : int
        Decimation: keep every ``stride``-th row and column (and the last one).
    normals : bool
        Compute smooth vertex normals from the (exaggerated) grid.
    skirt : bool
        Add vertical walls down to a flat base and close the bottom (a watertight solid).
    base_depth : float, optional
        Depth of the base below the lowest (exaggerated) vertex, mm; default 5 % of the
        larger lateral size.
    memory_budget : int, optional
        Bytes the arrays may take (default :data:`DEFAULT_MEMORY_BUDGET_BYTES`).

    Returns
    -------
    GridMesh
    """
    z = np.asarray(z, dtype=np.float64)
    if z.ndim != 2 or min(z.shape) < 2:
        raise InputError(f"z must be a 2-D height grid with at least 2 x 2 values, got shape {z.shape}")
    check_positive("pixel", pixel)
    check_positive("exaggeration", exaggeration)
    if int(stride) != stride or stride < 1:
        raise InputError(f"stride must be an integer >= 1, got {stride!r}")
    stride = int(stride)
    if stride > 1:
        rows = np.unique(np.r_[np.arange(0, z.shape[0], stride), z.shape[0] - 1])
        cols = np.unique(np.r_[np.arange(0, z.shape[1], stride), z.shape[1] - 1])
        z = z[np.ix_(rows, cols)]
        # non-uniform last step: the grid stays regular only in its interior; we keep
        # the exact last row/column positions below.
    else:
        rows = np.arange(z.shape[0])
        cols = np.arange(z.shape[1])
    ny, nx = z.shape
    budget = DEFAULT_MEMORY_BUDGET_BYTES if memory_budget is None else int(memory_budget)
    need = ny * nx * (12 + (12 if normals else 0)) + (ny - 1) * (nx - 1) * 24
    if need > budget:
        raise MemoryBudgetError(_mesh_refusal(ny, nx, need, budget, memory_budget, stride))
    finite = np.isfinite(z)
    if not finite.any():
        raise InputError("z has no finite height: nothing to mesh")
    if z_offset is None:
        z_offset = float(np.mean(z[finite]))
    ze = (z - z_offset) * exaggeration
    base_z = None
    if skirt:
        if base_depth is None:
            base_depth = 0.05 * max(rows[-1], cols[-1]) * pixel
        check_positive("base_depth", base_depth)
        base_z = float(np.min(ze[finite]) - base_depth)
        ze = np.where(finite, ze, base_z)
        keep = None
    else:
        fill = float(np.min(ze[finite]))
        keep = finite[:-1, :-1] & finite[1:, :-1] & finite[:-1, 1:] & finite[1:, 1:]
        if keep.all():
            keep = None
        ze = np.where(finite, ze, fill)
    xs = origin[0] + cols * pixel
    ys = origin[1] + rows * pixel
    v = np.empty((ny, nx, 3), dtype=np.float32)
    v[..., 0] = xs[None, :]
    v[..., 1] = ys[:, None]
    v[..., 2] = ze
    vertices = v.reshape(-1, 3)
    faces = _grid_faces(ny, nx, keep)
    nrm = None
    if normals:
        if stride == 1:
            nrm = _grid_normals(ze, pixel)
        else:
            gy, gx = np.gradient(ze, ys, xs)
            inv = 1.0 / np.sqrt(1.0 + gx * gx + gy * gy)
            nrm = np.stack([-gx * inv, -gy * inv, inv], axis=-1).astype(np.float32).reshape(-1, 3)
    if skirt:
        vertices, faces, nrm = _add_skirt(vertices, faces, nrm, ny, nx, base_z)
    meta = {"vertical_exaggeration": float(exaggeration), "z_offset_mm": float(z_offset),
            "pixel_mm": float(pixel * stride), "grid_pixel_mm": float(pixel),
            "origin_mm": [float(origin[0]), float(origin[1])], "grid_shape": [int(ny), int(nx)],
            "stride": stride, "skirt": bool(skirt), "channel": channel,
            "units": "mm", "software_version": __version__}
    if skirt:
        meta["base_z_mm"] = base_z
    return GridMesh(vertices, faces, nrm, meta)


def _mesh_refusal(ny, nx, need, budget, given, stride) -> str:
    """The mesh refusal, naming where its budget comes from (the default, the scene's
    budget, or what the address-space limit leaves) and the fix that fits."""
    text = (f"a {ny} x {nx} mesh needs {need / MIB_TO_BYTES:.0f} MiB, over the memory budget "
            f"of {budget / MIB_TO_BYTES:.0f} MiB")
    if given is None:
        source = f"the mesh default, {DEFAULT_MEMORY_BUDGET_BYTES / MIB_TO_BYTES:.0f} MiB"
    else:
        source = "simulation.max_memory_gb, or 80 % of the free memory when it is not set"
    room, limit = address_space_room(), address_space_limit()
    if room is not None and limit is not None and room <= need:
        return (f"{text} (from {source}, capped by the address-space limit (ulimit -v) of "
                f"{limit / MIB_TO_BYTES:.0f} MiB, which leaves {room / MIB_TO_BYTES:.0f} MiB): "
                f"raise the limit (ulimit -v unlimited), or raise stride (got {stride}) or crop "
                f"a window")
    return f"{text} (from {source}): raise stride (got {stride}) or crop a window"


def _add_skirt(vertices, faces, nrm, ny, nx, base_z):
    """Walls from the grid border down to ``base_z`` and a bottom fan (watertight)."""
    idx = np.arange(ny * nx, dtype=np.int64).reshape(ny, nx)
    # border loop, counter-clockwise seen from +z: bottom row (y min) left->right, right
    # column up, top row right->left, left column down
    loop = np.concatenate([idx[0, :-1], idx[:-1, -1], idx[-1, :0:-1], idx[:0:-1, 0]])
    nb = loop.size
    top = vertices[loop]
    base = top.copy()
    base[:, 2] = base_z
    n0 = vertices.shape[0]
    centre = np.array([[vertices[:, 0].min() / 2 + vertices[:, 0].max() / 2,
                        vertices[:, 1].min() / 2 + vertices[:, 1].max() / 2, base_z]],
                      dtype=np.float32)
    new_v = np.concatenate([vertices, base.astype(np.float32), centre])
    b = n0 + np.arange(nb)
    t = loop
    t1 = np.roll(t, -1)
    b1 = np.roll(b, -1)
    # outward-facing walls: the loop runs counter-clockwise, so (t, b, b1) and (t, b1, t1)
    walls = np.concatenate([np.stack([t, b, b1], 1), np.stack([t, b1, t1], 1)])
    c = n0 + nb
    bottom = np.stack([np.full(nb, c), b1, b], 1)  # faces down
    new_f = np.concatenate([faces.astype(np.int64), walls, bottom]).astype(np.uint32)
    if nrm is not None:
        down = np.zeros((nb + 1, 3), np.float32)
        down[:, 2] = -1
        nrm = np.concatenate([nrm, down])
    return new_v, new_f, nrm


def heightmap_mesh(heightmap: HeightMap, *, channel: str = "machined", exaggeration: float = 1.0,
                   window: Sequence[float] | None = None, margin: int = 1,
                   z_offset: float | None = None,
                   stride: int = 1, max_cells: int | None = None, normals: bool = True,
                   skirt: bool = False, base_depth: float | None = None,
                   memory_budget: int | None = None) -> GridMesh:
    """Mesh one channel of a :class:`~render_inspect.machining.HeightMap`.

    Parameters
    ----------
    heightmap : HeightMap
    channel : {"machined", "design", "residual"}
    exaggeration : float
        Vertical exaggeration (> 0), recorded in ``metadata["vertical_exaggeration"]``.
    window : (x0, y0, x1, y1), optional
        Mesh only the pixels inside this window (mm) plus ``margin`` pixels around it.
    stride, max_cells : int, optional
        Decimation: an explicit stride, or the stride that keeps the longer side at most
        ``max_cells`` cells (detail finer than the image's pixels cannot be seen).
    Others as :func:`grid_mesh`.
    """
    if channel not in ("machined", "design", "residual"):
        raise InputError(f"channel must be one of 'machined', 'design', 'residual', got {channel!r}")
    z = getattr(heightmap, channel)
    i0, j0 = 0, 0
    if window is not None:
        i0, i1, j0, j1 = window_indices(heightmap, window, margin=margin)
        z = z[i0:i1, j0:j1]
    if max_cells is not None:
        stride = max(int(stride), decimation_stride(z.shape, max_cells))
    origin = (heightmap.origin[0] + j0 * heightmap.pixel, heightmap.origin[1] + i0 * heightmap.pixel)
    gm = grid_mesh(z, pixel=heightmap.pixel, origin=origin, exaggeration=exaggeration,
                   z_offset=z_offset, stride=stride, normals=normals, skirt=skirt,
                   base_depth=base_depth, memory_budget=memory_budget, channel=channel)
    gm.metadata["window_mm"] = None if window is None else [float(w) for w in window]
    return gm


def window_indices(heightmap: HeightMap, window: Sequence[float], *,
                   margin: int = 1) -> tuple[int, int, int, int]:
    """Row/column slice bounds ``(i0, i1, j0, j1)`` of the pixels covering ``window``."""
    try:
        x0, y0, x1, y1 = (float(w) for w in window)
    except (TypeError, ValueError):
        raise InputError(f"window must be [x0, y0, x1, y1] in mm, got {window!r}") from None
    if not (x1 > x0 and y1 > y0):
        raise InputError(f"window must have x1 > x0 and y1 > y0, got {window!r}")
    ny, nx = heightmap.shape
    p = heightmap.pixel
    ox, oy = heightmap.origin
    j0 = max(0, int(math.floor((x0 - ox) / p)) - margin)
    j1 = min(nx, int(math.ceil((x1 - ox) / p)) + 1 + margin)
    i0 = max(0, int(math.floor((y0 - oy) / p)) - margin)
    i1 = min(ny, int(math.ceil((y1 - oy) / p)) + 1 + margin)
    if j1 - j0 < 2 or i1 - i0 < 2:
        x_lo, x_hi, y_lo, y_hi = heightmap.extent
        raise InputError(f"window {list(window)} mm does not overlap the height map "
                         f"(x {x_lo:g}..{x_hi:g}, y {y_lo:g}..{y_hi:g} mm)")
    return i0, i1, j0, j1


def heightmap_to_trimesh(heightmap: HeightMap, **kwargs: Any) -> Any:
    """:func:`heightmap_mesh` as a :class:`trimesh.Trimesh` (metadata carries the
    vertical exaggeration and provenance)."""
    return heightmap_mesh(heightmap, **kwargs).to_trimesh()


def export_mesh(mesh: GridMesh, path: str | Path) -> Path:
    """Write a mesh (``GridMesh`` or ``trimesh.Trimesh``) as PLY, OBJ, GLB or STL (chosen by
    the extension), atomically.

    PLY, OBJ and STL keep the project's frame: millimetres, +Z up.  GLB follows glTF 2.0:
    metres, +Y up (a vertex ``(x, y, z)`` mm is written ``(x, z, -y) / 1000``; see
    :func:`gltf_from_project`), so glTF viewers and Blender's importer show the part
    lying flat at its true size.  The metadata (``vertical_exaggeration`` ...) goes into
    the PLY/OBJ header comment or the GLB ``extras`` of the mesh and of its node (Blender's
    importer turns node extras into the object's custom properties), with ``units = "m"``,
    ``up_axis = "+Y"`` and ``source_units = "mm"``."""
    path = Path(path)
    ext = path.suffix.lower()
    if ext not in MESH_FORMATS:
        raise InputError(f"mesh file extension must be one of {sorted(MESH_FORMATS)}, got {ext!r}")
    tm = mesh.to_trimesh() if isinstance(mesh, GridMesh) else mesh
    fmt = MESH_FORMATS[ext]
    meta_text = json.dumps(tm.metadata, sort_keys=True, default=str)
    if fmt == "ply":
        data = cast(bytes, tm.export(file_type="ply", encoding="binary"))
        # add the metadata as a header comment line after "format ..."
        head, sep, rest = data.partition(b"end_header\n")
        lines = head.split(b"\n")
        lines.insert(2, b"comment render_inspect " + meta_text.encode())
        data = b"\n".join(lines) + sep + rest
    elif fmt == "obj":
        text = cast(str, tm.export(file_type="obj",
                                   include_normals=tm.metadata.get("skirt") is False))
        data = ("# render_inspect " + meta_text + "\n" + text).encode()
    elif fmt == "glb":
        smooth = isinstance(mesh, GridMesh) and mesh.normals is not None and \
            not mesh.metadata.get("skirt")
        data = _glb_bytes(tm, mesh.normals if smooth else None)
    else:
        data = cast(bytes, tm.export(file_type="stl"))
    if isinstance(data, str):
        data = data.encode()
    return atomic_write_bytes(path, data)


#: Project frame (mm, +Z up) -> glTF frame (m, +Y up): a rotation by -90 deg about x
#: (determinant +1, so triangles keep their winding) and mm -> m.
GLTF_ROTATION = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def gltf_from_project(points: np.ndarray) -> np.ndarray:
    """(n, 3) points in the project's frame (mm, +Z up) -> glTF's (m, +Y up):
    ``(x, y, z) -> (x, z, -y) / 1000``."""
    return np.asarray(points, dtype=np.float64) @ GLTF_ROTATION.T * MM_TO_M


def _glb_bytes(tm, normals=None) -> bytes:
    import trimesh

    kw = {}
    if normals is not None:
        kw["vertex_normals"] = np.asarray(normals, dtype=np.float64) @ GLTF_ROTATION.T
    out = trimesh.Trimesh(vertices=gltf_from_project(tm.vertices), faces=tm.faces,
                          process=False, **kw)
    extras = json.loads(json.dumps(tm.metadata, default=str))
    extras.update(units="m", up_axis="+Y", source_units="mm", source_up_axis="+Z")
    out.metadata.update(extras)

    def add_node_extras(tree):
        for node in tree.get("nodes", []):
            node["extras"] = dict(extras)

    return cast(bytes, out.export(file_type="glb", tree_postprocessor=add_node_extras))
