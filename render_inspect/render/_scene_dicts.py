"""Mitsuba scene pieces built from plain arrays and numbers (loaded only at the edge).

Conventions: world units are mm, +z is up (the part's height axis), images are returned
with row 0 at the smallest y (the height-map convention), column 0 at the smallest x.
"""

from __future__ import annotations

import numpy as np

from ._variant import import_mitsuba, single_thread

__all__ = ["mitsuba_mesh", "ortho_sensor", "perspective_sensor", "load_scene_dict",
           "render_aov_grid"]


def mitsuba_mesh(gm, *, name: str = "part", bsdf: dict | None = None):
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


def perspective_sensor(*, origin, target, up, fov_deg: float, nx: int, ny: int, spp: int) -> dict:
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


def load_scene_dict(d: dict):
    """``mi.load_dict`` with one Dr.Jit thread, so the BVH (and the image) is repeatable."""
    mi, _, _ = import_mitsuba()
    with single_thread():
        return mi.load_dict(d)


def render_aov_grid(gm, *, x0: float, y0: float, width_mm: float, nx: int, ny: int,
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
    mi, _, _ = import_mitsuba()
    scene = load_scene_dict({
        "type": "scene",
        "integrator": {"type": "aov", "aovs": "pp:position,nn:sh_normal,gn:geo_normal"},
        "sensor": ortho_sensor(x0=x0, y0=y0, width_mm=width_mm, nx=nx, ny=ny, z_top=z_top),
        "part": mitsuba_mesh(gm),
    })
    img = np.array(mi.render(scene, seed=0), dtype=np.float32)
    img = img[::-1]  # film row 0 is the top (largest y)
    return (np.ascontiguousarray(img[..., 0:3]), np.ascontiguousarray(img[..., 3:6]),
            np.ascontiguousarray(img[..., 6:9]))
