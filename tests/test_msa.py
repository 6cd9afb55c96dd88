"""Microstructure arrays: separation, lenslet centres (sub-pixel sphere-centre fit),
dislocations, per-lenslet and base form errors, and seed 002's chain with registration."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from render_inspect.design import LensletArray
from render_inspect.errors import InputError
from render_inspect.machining import HeightMap
from render_inspect.metrology import (
    LENSLET_KEYS,
    RIGID_KEYS,
    base_form_error,
    characterise_msa,
    lenslet_table,
    rigid_resample,
    separate_msa,
)
from render_inspect.scene import MetrologyConfig

PIXEL = 0.01


def _array(**kw):
    args = dict(rows=3, cols=3, pitch_x=1.0, pitch_y=1.0, aperture_radius=0.4, lens_radius=2.0)
    args.update(kw)
    return LensletArray(**args)


class Displaced:
    """The design with lenslet (row, col) moved by ``shifts[(row, col)]`` (mm) on an unmoved
    base, plus an optional form-error ripple on some lenslets: the forward model."""

    def __init__(self, design, shifts, ripple=None):
        self.d, self.shifts, self.ripple = design, shifts, ripple or {}
        self.c = design.centers()

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        z = np.asarray(self.d.height(x, y), float).copy()
        for r, c, cx, cy in self.c:
            near = np.hypot(x - cx, y - cy) < 0.5 * min(self.d.pitch_x, self.d.pitch_y)
            dx, dy = self.shifts.get((r, c), (0.0, 0.0))
            if dx or dy:
                z[near] = self.d.height(x[near] - dx, y[near] - dy)
            if (r, c) in self.ripple:
                a, lam = self.ripple[(r, c)]
                inside = near & (np.hypot(x - cx - dx, y - cy - dy) < self.d.aperture_radius)
                z[inside] += a * np.sin(2 * np.pi * (x[inside] - cx) / lam) * np.sin(
                    2 * np.pi * (y[inside] - cy) / lam)
        return z


def _grid(design, pad=0.0):
    x0, y0, x1, y1 = design.bounds
    x = np.arange(x0 - pad, x1 + pad + 1e-9, PIXEL)
    y = np.arange(y0 - pad, y1 + pad + 1e-9, PIXEL)
    return x, y, (float(x[0]), float(y[0]))


SHIFTS = {(1, 0): (-3e-3, 0.0), (1, 2): (3e-3, 0.0), (0, 1): (0.0, -2e-3), (2, 1): (0.0, 2e-3),
          (0, 0): (1.3e-3, -0.7e-3)}


def test_lenslet_table_recovers_displacements_subpixel():
    la = _array()
    x, y, origin = _grid(la)
    z = Displaced(la, SHIFTS).height(x[None, :], y[:, None])
    z = z + np.random.default_rng(3).normal(0, 5e-6, z.shape)  # 5 nm noise
    table = lenslet_table((z, PIXEL, origin), la)
    assert len(table) == 9
    for e in table:
        assert set(LENSLET_KEYS) <= set(e)
        dx, dy = SHIFTS.get((e["row"], e["col"]), (0.0, 0.0))
        assert abs(e["dx_um"] - dx * 1e3) < 0.3 and abs(e["dy_um"] - dy * 1e3) < 0.3, e
        assert_allclose(e["x_mm"] - e["x_design_mm"], e["dx_um"] * 1e-3, atol=1e-12)
        assert e["Sq_um"] < 0.01  # only the noise is left


def test_lenslet_form_error_bump_recovered_in_sq():
    la = _array()
    x, y, origin = _grid(la)
    amp = 0.4e-3  # ripple amplitude 0.4 um: Sq over the aperture ~ amp / 2
    z = Displaced(la, {(1, 1): (2e-3, 0.0)}, ripple={(1, 1): (amp, 0.1)}).height(x[None, :], y[:, None])
    hm = HeightMap(np.asarray(la.height(x[None, :], y[:, None])), z, PIXEL, origin)
    table = {(e["row"], e["col"]): e for e in lenslet_table(hm, la)}
    assert_allclose(table[(1, 1)]["Sq_um"], amp / 2 * 1e3, rtol=0.1)
    assert abs(table[(1, 1)]["dx_um"] - 2.0) < 0.3
    assert table[(0, 0)]["Sq_um"] < 1e-3
    # the design channel of the HeightMap has no form error and no dislocation
    for e in lenslet_table(hm, la, which="design"):
        assert abs(e["dx_um"]) < 1e-3 and e["Sq_um"] < 1e-4


def test_separation_masks_and_base_form_error():
    la = _array()
    x, y, origin = _grid(la)
    shape = (y.size, x.size)
    msa, base, label = separate_msa(shape, la.centers(), pixel=PIXEL, origin=origin,
                                    aperture_radius=0.4)
    xx, yy = np.meshgrid(x, y)
    d = np.hypot(xx - 0.0, yy - 0.0)  # centre lenslet (1, 1)
    assert msa[d < 0.37].all() and not msa[(d > 0.39) & (d < 0.42)].any()
    assert not base[(d > 0.37) & (d < 0.419)].any() and base[(d > 0.43) & (d < 0.49)].all()
    assert set(np.unique(label[d < 0.37])) == {4}
    # a base waviness of known Sq
    wav = 1e-4 * np.sin(2 * np.pi * xx / 0.77)
    z = np.asarray(la.height(xx, yy)) + wav
    b = base_form_error(z, la, pixel=PIXEL, origin=origin)
    assert_allclose(b["Sq_um"], np.std(wav[base]) * 1e3, rtol=1e-9)
    quad = LensletArray(rows=2, cols=2, pitch_x=0.4, pitch_y=0.4, lens_radius=1.0, cells="quad")
    qx, qy, qo = _grid(quad)
    assert base_form_error(np.asarray(quad.height(qx[None, :], qy[:, None])), quad,
                           pixel=PIXEL, origin=qo) is None


def test_characterise_msa_with_misalignment_outliers_and_displacements():
    la = _array()
    x, y, origin = _grid(la, pad=-0.2)  # the measurement sees slightly less than the array
    true = dict(zip(RIGID_KEYS, (6e-3, -4e-3, 2e-3, 3e-4, -2e-4, 1e-3)))
    z = rigid_resample(Displaced(la, {k: v for k, v in SHIFTS.items() if k != (0, 0)}), true,
                       x[None, :], y[:, None])
    rng = np.random.default_rng(7)
    z = z + rng.normal(0, 3e-6, z.shape)
    spikes = rng.choice(z.size, 20, replace=False)
    z.flat[spikes] += 5e-3
    res = characterise_msa(z, la, pixel=PIXEL, origin=origin)
    reg = res["registration"]
    for k, tol in zip(RIGID_KEYS, (3e-4, 3e-4, 1e-4, 5e-5, 5e-5, 1e-4)):
        assert abs(reg[k] - true[k]) < tol, (k, reg[k], true[k])
    assert res["outliers"] >= 15
    # displacements in the registered frame: the pattern is symmetric (no net shift or
    # rotation), so the registered frame is the design frame moved by ``true``
    assert len(res["lenslets"]) == 9
    for e in res["lenslets"]:
        dx, dy = SHIFTS.get((e["row"], e["col"]), (0.0, 0.0)) if (e["row"], e["col"]) != (0, 0) else (0, 0)
        assert abs(e["dx_um"] - dx * 1e3) < 0.3 and abs(e["dy_um"] - dy * 1e3) < 0.3, e
    assert res["base"]["Sq_um"] < 0.02
    assert_allclose(res["summary"]["max_dislocation_um"], 3.0, atol=0.3)


def test_msa_bad_input():
    la = _array()
    x, y, origin = _grid(la)
    z = np.asarray(la.height(x[None, :], y[:, None]))
    with pytest.raises(InputError, match="pixel"):
        lenslet_table(z, la)
    with pytest.raises(InputError, match="centers"):
        lenslet_table((z, PIXEL, origin), object(), aperture_radius=0.4)
    with pytest.raises(InputError, match="inner"):
        separate_msa(z.shape, la.centers(), pixel=PIXEL, origin=origin, aperture_radius=0.4,
                     inner=1.2)
    zc = z.copy()
    zc[: z.shape[0] // 2] = np.nan  # half the array not measured: those lenslets are skipped
    with pytest.warns(UserWarning, match="left out"):
        t = lenslet_table((zc, PIXEL, origin), la)
    assert {e["row"] for e in t} == {2}


def test_lenslets_on_a_curved_base_no_bias_from_the_base():
    # toric base R 40 / 60 mm under lenslets of R 2 mm: shifting the whole local design
    # would bias a 30 um dislocation by ~30 um x 2 / 40 = 1.5 um; only the lenslet moves
    from render_inspect.design import Toric
    from render_inspect.design._compound import Compound

    la = _array()
    base = Toric(40.0, 60.0)
    design = Compound(base, la)
    shifts = {(1, 2): (30e-3, 0.0), (2, 1): (0.0, -20e-3), (1, 0): (-30e-3, 0.0),
              (0, 1): (0.0, 20e-3)}
    x, y, origin = _grid(la)
    xx, yy = np.meshgrid(x, y)
    z = base.height(xx, yy) + Displaced(la, shifts).height(xx, yy)
    table = lenslet_table((z, PIXEL, origin), design)
    assert len(table) == 9
    for e in table:
        dx, dy = shifts.get((e["row"], e["col"]), (0.0, 0.0))
        assert abs(e["dx_um"] - dx * 1e3) < 0.3 and abs(e["dy_um"] - dy * 1e3) < 0.3, e
    # and after a registration (seed 002's chain): symmetric pattern, so no net move
    true = dict(zip(RIGID_KEYS, (4e-3, 3e-3, 1e-3, 2e-4, 1e-4, -5e-4)))

    class Measured:
        def height(self, u, v):
            return base.height(u, v) + Displaced(la, shifts).height(u, v)

    x2, y2, origin2 = _grid(la, pad=-0.15)
    zm = rigid_resample(Measured(), true, x2[None, :], y2[:, None])
    res = characterise_msa(zm, design, pixel=PIXEL, origin=origin2, metrology=MetrologyConfig())
    for e in res["lenslets"]:
        dx, dy = shifts.get((e["row"], e["col"]), (0.0, 0.0))
        assert abs(e["dx_um"] - dx * 1e3) < 0.3 and abs(e["dy_um"] - dy * 1e3) < 0.3, e
