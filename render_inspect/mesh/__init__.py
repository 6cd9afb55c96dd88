"""Meshes of height maps: a vertical exaggeration stated in the metadata, optional
skirt and base, PLY/OBJ/GLB/STL export (GLB in glTF's metres, +Y up).

>>> gm = heightmap_mesh(hm, channel="machined", exaggeration=200.0)
>>> gm.metadata["vertical_exaggeration"]
200.0
>>> export_mesh(gm, "part.ply")

Meshes are built directly from arrays (float32 vertices, uint32 faces), so a 4000 x 4000
map costs about 1.2 GB; renders crop a window or decimate where detail cannot be seen.
"""

from ._disc import disc_mesh
from ._grid import (
                    DEFAULT_MEMORY_BUDGET_BYTES,
                    MESH_FORMATS,
                    GridMesh,
                    decimation_stride,
                    export_mesh,
                    gltf_from_project,
                    grid_mesh,
                    heightmap_mesh,
                    heightmap_to_trimesh,
                    window_indices,
)

__all__ = ["GridMesh", "grid_mesh", "disc_mesh", "heightmap_mesh", "heightmap_to_trimesh", "export_mesh",
           "gltf_from_project", "decimation_stride", "window_indices", "MESH_FORMATS", "DEFAULT_MEMORY_BUDGET_BYTES"]
