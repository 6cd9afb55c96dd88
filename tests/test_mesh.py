"""Height map -> mesh: known grids in, exact vertices / faces / volumes out."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from render_inspect.errors import InputError, MemoryBudgetError
from render_inspect.machining import HeightMap
from render_inspect.mesh import (
    decimation_stride,
    export_mesh,
    gltf_from_project,
    grid_mesh,
    heightmap_mesh,
    heightmap_to_trimesh,
    window_indices,
)


def _hm(ny=6, nx=9, pixel=0.01, origin=(-0.04, 0.02), seed=0):
    rng = np.random.default_rng(seed)
    design = 1e-3 * rng.normal(size=(ny, nx))
    return HeightMap(design, design + 1e-6 * rng.normal(size=(ny, nx)), pixel, origin)


def test_vertices_sit_on_the_grid_with_stated_exaggeration():
    hm = _hm()
    gm = heightmap_mesh(hm, channel="machined", exaggeration=50.0)
    ny, nx = hm.shape
    assert gm.n_vertices == ny * nx
    assert gm.n_faces == 2 * (ny - 1) * (nx - 1)
    assert gm.vertices.dtype == np.float32 and gm.faces.dtype == np.uint32
    v = gm.vertices.reshape(ny, nx, 3)
    np.testing.assert_allclose(v[0, :, 0], hm.x, atol=1e-7)
    np.testing.assert_allclose(v[:, 0, 1], hm.y, atol=1e-7)
    off = gm.metadata["z_offset_mm"]
    assert off == pytest.approx(np.mean(hm.machined))
    np.testing.assert_allclose(v[..., 2], 50.0 * (hm.machined - off), rtol=1e-6, atol=1e-9)
    assert gm.metadata["vertical_exaggeration"] == 50.0
    tm = gm.to_trimesh()
    assert tm.metadata["vertical_exaggeration"] == 50.0
    # all faces point up (counter-clockwise seen from +z)
    assert (tm.face_normals[:, 2] > 0).all()


def test_vertex_normals_of_a_tilted_plane():
    x = np.arange(7) * 0.1
    z = np.broadcast_to(0.2 * x[None, :] - 0.1 * np.arange(5)[:, None] * 0.1, (5, 7))
    gm = grid_mesh(z, pixel=0.1, exaggeration=1.0)
    expect = np.array([-0.2, 0.1, 1.0]) / np.sqrt(1.05)
    np.testing.assert_allclose(gm.normals, np.broadcast_to(expect, gm.normals.shape), atol=1e-6)


def test_nan_cells_are_left_out():
    hm = _hm(5, 5)
    m = hm.machined.copy()
    m[2, 2] = np.nan
    gm = grid_mesh(m, pixel=0.01)
    # the four cells around the NaN vertex (8 triangles) are dropped
    assert gm.n_faces == 2 * 16 - 8
    assert np.isfinite(gm.vertices).all()


def test_skirt_makes_a_closed_solid_of_known_volume():
    z = np.full((4, 6), 0.3)
    gm = grid_mesh(z, pixel=0.5, exaggeration=2.0, z_offset=0.0, skirt=True, base_depth=0.4)
    tm = gm.to_trimesh()
    assert tm.is_watertight and tm.is_winding_consistent
    # top at 0.6 (exaggerated), base at 0.6 - 0.4: a 2.5 x 1.5 x 0.4 box
    assert tm.volume == pytest.approx(2.5 * 1.5 * 0.4, rel=1e-6)
    assert gm.metadata["base_z_mm"] == pytest.approx(0.2)


def test_decimation_and_window():
    hm = _hm(41, 61, pixel=0.01, origin=(0.0, 0.0))
    assert decimation_stride((41, 61), 20) == 3
    gm = heightmap_mesh(hm, max_cells=20, normals=False)
    ny, nx = gm.metadata["grid_shape"]
    assert max(ny, nx) - 1 <= 21 and gm.metadata["stride"] == 3
    # the last row / column are kept, so the extent is unchanged
    assert gm.vertices[:, 0].max() == pytest.approx(hm.x[-1], abs=1e-6)
    i0, i1, j0, j1 = window_indices(hm, (0.1, 0.1, 0.2, 0.15), margin=0)
    assert (i0, i1, j0, j1) == (10, 16, 10, 21)
    gw = heightmap_mesh(hm, window=(0.1, 0.1, 0.2, 0.15), margin=0)
    assert gw.metadata["grid_shape"] == [6, 11]
    assert gw.vertices[0, 0] == pytest.approx(0.1, abs=1e-7)


@pytest.mark.parametrize("ext", [".ply", ".obj", ".glb", ".stl"])
def test_export_round_trip(tmp_path, ext):
    gm = heightmap_mesh(_hm(), exaggeration=10.0)
    path = export_mesh(gm, tmp_path / f"part{ext}")
    loaded = trimesh.load(path, force="mesh", process=False)
    assert len(loaded.faces) == gm.n_faces
    if ext == ".glb":  # glTF: metres, +Y up: (x, y, z) mm -> (x, z, -y) / 1000
        np.testing.assert_allclose(loaded.vertices, gltf_from_project(gm.vertices), atol=1e-9)
        assert loaded.metadata["vertical_exaggeration"] == 10.0
        assert loaded.metadata["units"] == "m" and loaded.metadata["up_axis"] == "+Y"
        return
    # STL stores three corners per face (no shared vertices): compare the sets of heights
    np.testing.assert_allclose(np.unique(np.round(loaded.vertices[:, 2], 6)),
                               np.unique(np.round(gm.vertices[:, 2], 6)), atol=1e-6)
    if ext == ".ply":
        head = path.read_bytes()[:2000].split(b"end_header")[0]
        line = [ln for ln in head.split(b"\n") if ln.startswith(b"comment render_inspect ")][0]
        meta = json.loads(line[len(b"comment render_inspect "):])
        assert meta["vertical_exaggeration"] == 10.0


def test_trimesh_factory_carries_metadata():
    tm = heightmap_to_trimesh(_hm(), channel="design", exaggeration=3.0)
    assert isinstance(tm, trimesh.Trimesh)
    assert tm.metadata["channel"] == "design" and tm.metadata["vertical_exaggeration"] == 3.0


def test_bad_input_is_named():
    hm = _hm()
    with pytest.raises(InputError, match="exaggeration"):
        heightmap_mesh(hm, exaggeration=0.0)
    with pytest.raises(InputError, match="channel"):
        heightmap_mesh(hm, channel="height")
    with pytest.raises(InputError, match="pixel"):
        grid_mesh(np.zeros((3, 3)), pixel=-1.0)
    with pytest.raises(InputError, match="stride"):
        grid_mesh(np.zeros((3, 3)), pixel=1.0, stride=0)
    with pytest.raises(InputError, match="window"):
        heightmap_mesh(hm, window=(5.0, 5.0, 6.0, 6.0))
    with pytest.raises(InputError, match="extension"):
        export_mesh(heightmap_mesh(hm), "part.xyz")
    with pytest.raises(MemoryBudgetError, match="stride"):
        grid_mesh(np.zeros((100, 100)), pixel=1.0, memory_budget=1000)


def test_disc_mesh_is_a_round_solid_sampled_from_the_map():
    """A turned disc: its face on polar rings through the map's heights (a tilted plane
    comes back exactly), its rim on the radius, a 45 degree chamfer, a vertical side wall,
    the face's normals up and one vertex at the centre (no seam at the axis)."""
    from render_inspect.mesh import disc_mesh

    R, c, wall, ex = 2.0, 0.1, 0.5, 10.0
    x = np.linspace(-R, R, 81)
    X, Y = np.meshgrid(x, x)
    z = 1e-3 * X + 2e-3 * Y
    z[X ** 2 + Y ** 2 > R * R] = np.nan
    gm = disc_mesh(z, pixel=x[1] - x[0], origin=(-R, -R), center=(0.0, 0.0), radius=R,
                   exaggeration=ex, z_offset=0.0, rings=16, sectors=64, chamfer=c, wall=wall)
    v, n = gm.vertices.astype(float), gm.normals.astype(float)
    face = slice(0, 1 + 16 * 64)
    r = np.hypot(v[face, 0], v[face, 1])
    np.testing.assert_allclose(v[face, 2], ex * (1e-3 * v[face, 0] + 2e-3 * v[face, 1]), atol=1e-5)
    assert r.max() == pytest.approx(R - c, rel=1e-6) and r[0] == 0.0
    assert np.all(n[face, 2] > 0.9)
    rim = np.hypot(v[:, 0], v[:, 1])
    assert rim.max() == pytest.approx(R, rel=1e-6)
    assert v[:, 2].min() < v[face, 2].min() - wall + 1e-6
    tm = gm.to_trimesh()
    assert tm.is_winding_consistent
    # the outward faces point away from the axis or up; the bottom down
    fn, fc = tm.face_normals, tm.triangles_center
    radial = (fn[:, 0] * fc[:, 0] + fn[:, 1] * fc[:, 1])
    side = np.hypot(fc[:, 0], fc[:, 1]) > R - c + 1e-6
    assert np.all(radial[side & (np.abs(fn[:, 2]) < 0.99)] > 0)
    assert gm.metadata["shape"] == "disc" and gm.metadata["chamfer_mm"] == c
