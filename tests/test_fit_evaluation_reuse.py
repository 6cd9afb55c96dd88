"""What a fit's evaluations share within a process, and that sharing it changes no number:
the ray tracer's program (compiled once, not once per mesh) and the design (built once,
the part's highest point found once)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from render_inspect.mesh import grid_mesh
from render_inspect.pipeline import _fit_model
from render_inspect.pipeline._fit_model import KEPT_DESIGNS, design_surface
from render_inspect.pipeline._simulate import simulate
from render_inspect.scene import scene_from_dict

#: a turned sinusoidal grid of 0.1 x 0.1 mm at 2 um (2,601 samples)
SCENE = {"name": "shared", "design": {"type": "sinusoidal_grid", "amplitude_x": 0.001,
                                      "amplitude_y": 0.001, "wavelength_x": 0.5,
                                      "wavelength_y": 0.5},
         "tool": {"nose_radius": 0.5},
         "process": {"kind": "sts", "spindle_rpm": 50, "feed_mm_per_min": 1,
                     "workpiece_radius": 0.5, "points_per_rev": 360},
         "simulation": {"region": [0.2, -0.05, 0.3, 0.05], "pixel": 0.002}}


def _scene(**process):
    d = copy.deepcopy(SCENE)
    d["process"].update(process)
    return scene_from_dict(d, "(test)")


def _mesh(z_offset: float):
    n, q = 61, 0.001
    c = np.arange(n) * q
    X, Y = np.meshgrid(c, c)
    z = 2e-4 * np.sin(2 * np.pi * X / 0.037) * np.cos(2 * np.pi * Y / 0.023) + z_offset
    return grid_mesh(z, pixel=q, z_offset=0.0, normals=True)


def _trace_with_constants(gm, grids, *, z_top, shift):
    """The tracing as written before: the start height and the shift written into the
    program as constants."""
    from render_inspect.render import load_scene_dict
    from render_inspect.render._scene_dicts import mitsuba_mesh
    from render_inspect.render._variant import import_mitsuba

    mi, dr, _ = import_mitsuba()
    dx, dy = shift
    scene = load_scene_dict({"type": "scene", "part": mitsuba_mesh(gm)})
    out = []
    for g in grids:
        nx, ny = int(g["nx"]), int(g["ny"])
        cell = float(g["width_mm"]) / nx
        xs = (float(g["x0"]) + dx + (np.arange(nx) + 0.5) * cell).astype(np.float32)
        ys = (float(g["y0"]) + dy + (np.arange(ny) + 0.5) * cell).astype(np.float32)
        o = mi.Point3f(mi.Float(np.tile(xs, ny)), mi.Float(np.repeat(ys, nx)), float(z_top))
        si = scene.ray_intersect(mi.Ray3f(o, mi.Vector3f(0.0, 0.0, -1.0)),
                                 ray_flags=mi.RayFlags.All, coherent=True)
        hit = si.is_valid() & (si.n.z > 1e-6)
        z = si.p.z + (si.n.x * dx + si.n.y * dy) / dr.select(hit, si.n.z, 1.0)
        z = dr.select(hit, z, dr.nan)
        comps = [dr.select(hit, c, 0.0) for c in (si.sh_frame.n.x, si.sh_frame.n.y,
                                                   si.sh_frame.n.z)]
        dr.eval(z, *comps)
        n_out = np.stack([np.asarray(c, dtype=np.float32).reshape(ny, nx) for c in comps], -1)
        out.append((np.array(z, dtype=np.float32).reshape(ny, nx), n_out))
    return out


@pytest.mark.mitsuba
def test_the_traced_program_is_compiled_once_and_traces_the_same_heights():
    """Meshes at other heights (another start height for the rays each) are traced by the
    program compiled for the first: every kernel of the later traces comes from the
    in-memory cache.  The heights and normals are those of the program with the numbers
    written in as constants, bit for bit."""
    from render_inspect.render import trace_grids
    from render_inspect.render._variant import import_mitsuba

    mi, dr, variant = import_mitsuba()
    if not variant.startswith("llvm"):
        pytest.skip(f"Mitsuba's LLVM variant is not available here (libLLVM 19 missing: "
                    f"{variant} in use); the traced program is compiled only there")
    grids = [{"x0": 0.005, "y0": 0.004, "width_mm": 0.05, "nx": 75, "ny": 80},
             {"x0": 0.01, "y0": 0.01, "width_mm": 0.04, "nx": 20, "ny": 20}]
    shift = (1.23e-5, 2.71e-5)
    offsets = [0.0, 0.013, 0.0271, 0.0419, 0.0583, 0.0697]
    for k, off in enumerate(offsets):
        gm = _mesh(off)
        z_top = float(gm.vertices[:, 2].max()) + 1.0
        dr.kernel_history_clear()
        with dr.scoped_set_flag(dr.JitFlag.KernelHistory):
            got = trace_grids(gm, grids, z_top=z_top, shift=shift, full_normals=True)
            hist = dr.kernel_history([dr.KernelType.JIT])
        hashes = [h["hash"] for h in hist]
        if k == 0:
            first = hashes
        else:  # the same programs for every mesh (whatever addresses NumPy's arrays got)
            assert hashes == first
        if k >= 3:  # (the first traces may differ in what they register once)
            assert hist and all(h["cache_hit"] for h in hist), \
                [(h["hash"], h["cache_hit"]) for h in hist]
        ref = _trace_with_constants(gm, grids, z_top=z_top, shift=shift)
        for (z, n), (zr, nr) in zip(got, ref):
            assert np.isfinite(z).all()
            assert np.array_equal(z, zr) and np.array_equal(n, nr)
        # (and the heights are the mesh's: the second grid's centres lie on its vertices)
        expect = np.asarray(gm.vertices[:, 2]).reshape(61, 61)[11:50:2, 11:50:2]
        np.testing.assert_allclose(got[1][0], expect, atol=5e-8)


def test_a_design_file_that_changes_makes_another_key(tmp_path):
    """A design section's files are part of its key: rewritten, the design is built again."""
    p = tmp_path / "design.npy"
    p.write_bytes(b"one")
    d = {"type": "heightmap", "path": str(p), "channel": "design", "more": [str(tmp_path)]}
    first = _fit_model._file_stamps(d)
    assert len(first) == 1 and first[0][0] == str(p)  # (the folder is not a file)
    p.write_bytes(b"three")
    assert _fit_model._file_stamps(d) != first


def test_evaluations_share_the_design_and_predict_the_same_surface(monkeypatch):
    """Scenes that differ in a process key share one design object (its highest point over
    the part found once, for the check of the program's links); the cut is the one a
    design of its own gives, bit for bit; another design gets its own, and only the last
    few are kept."""
    monkeypatch.setattr(_fit_model, "_DESIGNS", {})
    a, b = _scene(), _scene(feed_mm_per_min=1.1)
    s = design_surface(a)
    assert design_surface(b) is s
    shared = simulate(b, surface=s)
    assert s.__dict__.get("_max_height_cache"), "the part's highest point is kept on it"
    own = simulate(b)
    assert own.heightmap.machined.size == 51 * 51
    assert np.array_equal(shared.heightmap.machined, own.heightmap.machined, equal_nan=True)
    assert np.array_equal(shared.heightmap.design, own.heightmap.design, equal_nan=True)
    assert shared.metrics["residual"] == own.metrics["residual"]
    others = []
    for k in range(KEPT_DESIGNS + 1):
        d = copy.deepcopy(SCENE)
        d["design"]["amplitude_x"] = 0.001 * (2 + k)
        others.append(design_surface(scene_from_dict(d, "(test)")))
    assert all(o is not s for o in others) and len(set(map(id, others))) == len(others)
    assert len(_fit_model._DESIGNS) == KEPT_DESIGNS
    assert design_surface(a) is not s  # (the first was let go)
    assert math.isclose(design_surface(a).height(0.25, 0.0), s.height(0.25, 0.0))
